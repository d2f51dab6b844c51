//! `cargo bench -p matseg-query --bench clicks`: what a click costs after
//! the photo's descriptor pass, as the web app and `matseg segment` answer
//! it. A 1152x864 photo (1 MP) described as the shipped model describes it
//! (408 values a cell: its 128-value descriptor, the encoder's and the
//! colour parts, on the stride-4 grid of its 700 px pass, 176x132 cells),
//! eight materials in blobs with noisy descriptors; ten clicks,
//! alternately positive and negative, each answered with the selection's
//! soft map and mask at the photo's size. Prints, as medians over 5
//! repeats: the photo's preparation (its materials, the classifier's
//! factorised Gram matrix, its edges and colours), which the web app
//! makes when it describes a photo; each click on a prepared photo; and,
//! on a photo not prepared, the first click (which then finds the photo's
//! materials and edges), the second (which makes the classifier's Gram
//! matrix) and the others.

use image::RgbImage;
use matseg_query::coarse::CoarseDescriptors;
use matseg_query::descriptor::DescriptorMap;
use matseg_query::select::{Click, PhotoPrep, Selector};
use rand::{Rng, SeedableRng};
use std::sync::Arc;
use std::time::Instant;

const WIDTH: usize = 1152;
const HEIGHT: usize = 864;
const GRID: (usize, usize) = (176, 132);
const DIM: usize = 408;
const MATERIALS: usize = 8;

/// The material at photo pixel `(x, y)`: blobs from a few sines.
fn material(x: f32, y: f32) -> usize {
    let v = (x / 97.0).sin() + (y / 71.0).cos() + ((x + y) / 153.0).sin();
    (((v + 3.0) / 6.0 * MATERIALS as f32) as usize).min(MATERIALS - 1)
}

/// Milliseconds to add `click` and answer the selection at the photo's size.
fn timed(selector: &mut Selector<'_>, click: Click) -> f64 {
    let started = Instant::now();
    selector.add(click).expect("inside");
    let selection = selector.selection().expect("a positive click");
    let ms = started.elapsed().as_secs_f64() * 1e3;
    assert_eq!(selection.mask.len(), WIDTH * HEIGHT);
    ms
}

fn main() {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(0);
    let centres: Vec<Vec<f32>> = (0..MATERIALS)
        .map(|_| (0..DIM).map(|_| rng.random_range(-1.0..1.0)).collect())
        .collect();
    let (gw, gh) = GRID;
    let mut data = Vec::with_capacity(gw * gh * DIM);
    for cy in 0..gh {
        for cx in 0..gw {
            let m = material(
                (cx as f32 + 0.5) * WIDTH as f32 / gw as f32,
                (cy as f32 + 0.5) * HEIGHT as f32 / gh as f32,
            );
            let v: Vec<f32> = centres[m]
                .iter()
                .map(|c| c + rng.random_range(-0.4..0.4))
                .collect();
            let norm = v.iter().map(|a| a * a).sum::<f32>().sqrt();
            data.extend(v.iter().map(|a| a / norm));
        }
    }
    let map = CoarseDescriptors {
        grid: DescriptorMap {
            width: gw,
            height: gh,
            dim: DIM,
            data,
        },
        width: WIDTH,
        height: HEIGHT,
    };
    let photo = RgbImage::from_fn(WIDTH as u32, HEIGHT as u32, |x, y| {
        let m = material(x as f32, y as f32) as u8;
        image::Rgb([30 * m, 255 - 25 * m, 90])
    });
    let clicks: Vec<Click> = (0..10)
        .map(|i| {
            let (x, y) = (
                rng.random_range(0.0..WIDTH as f32),
                rng.random_range(0.0..HEIGHT as f32),
            );
            if i % 2 == 0 {
                Click::positive(x, y)
            } else {
                Click::negative(x, y)
            }
        })
        .collect();
    let (mut preparing, mut prepared) = (Vec::new(), Vec::new());
    let (mut first, mut second, mut next) = (Vec::new(), Vec::new(), Vec::new());
    for _ in 0..5 {
        // The photo prepared as the web app prepares it, then clicked.
        let started = Instant::now();
        let prep = PhotoPrep::default();
        prep.prepare(&map, Some(&photo));
        preparing.push(started.elapsed().as_secs_f64() * 1e3);
        let mut selector =
            Selector::with_prep(&map, Some(&photo), 5.0, Arc::new(prep)).expect("a radius");
        for &click in &clicks {
            prepared.push(timed(&mut selector, click));
        }
        // A photo not prepared: its parts are made as the first and
        // second clicks need them.
        let mut selector = Selector::new(&map, Some(&photo), 5.0).expect("a radius");
        for (i, &click) in clicks.iter().enumerate() {
            let ms = timed(&mut selector, click);
            match i {
                0 => first.push(ms),
                1 => second.push(ms),
                _ => next.push(ms),
            }
        }
    }
    let median = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    println!(
        "{WIDTH}x{HEIGHT} photo, {gw}x{gh}x{DIM} descriptors, {} threads, medians: preparing the photo {:.1} ms, then {:.1} ms a click (slowest {:.1} ms); unprepared, first click {:.1} ms, second {:.1} ms, each next {:.1} ms",
        rayon::current_num_threads(),
        median(&mut preparing),
        median(&mut prepared),
        prepared.iter().copied().fold(0.0, f64::max),
        median(&mut first),
        median(&mut second),
        median(&mut next),
    );
}
