//! Invariants of generated 2D scenes over many seeds.

mod common;

use matseg_extract::random_placement;
use matseg_scene::{generate_2d, quantise_weights, Sources};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

#[test]
fn annotations_are_exact_on_many_seeds() {
    let (photos, textures) = common::libraries();
    let sources = Sources {
        photos: &photos,
        textures: &textures,
    };
    let recipe = common::small_recipe();
    let (mut hard_seen, mut soft_seen, mut background_pixels) = (0, 0, 0);
    for seed in 0..80u64 {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let scene = generate_2d(&mut rng, &recipe, sources).unwrap();
        let rec = &scene.record;
        let (w, h) = (rec.width, rec.height);
        assert!((64..=160).contains(&w) && (64..=160).contains(&h));
        assert_eq!(scene.image.dimensions(), (w as u32, h as u32));
        let k = scene.weights.len();
        assert!((1..=10).contains(&k));
        assert_eq!(rec.maps.len(), k);
        assert_eq!(rec.materials.len(), k);

        let q = quantise_weights(&scene.weights, &scene.background);
        assert_eq!(q.masks.len(), k);
        for i in 0..w * h {
            let masks: u32 = q.masks.iter().map(|m| m[i] as u32).sum();
            assert_eq!(masks + q.background[i] as u32, 255, "seed {seed} pixel {i}");
            assert_eq!(q.roi[i] as u32, masks);
            let roi = 255.0 * (1.0 - scene.background.data[i]);
            assert!((q.roi[i] as f32 - roi).abs() <= 1.0 + 1e-3);
            if rec.hard {
                assert!(
                    q.masks.iter().all(|m| m[i] == 0 || m[i] == 255),
                    "hard scene not one-hot"
                );
            }
        }
        if rec.hard {
            hard_seen += 1;
        } else {
            soft_seen += 1;
        }

        // Where no material lies, the image is exactly the background photo.
        let photo = photos.get(rec.background.photo).unwrap();
        let bg = photo.pyramid.sample_planes(&rec.background.placement, w, h);
        let mut checked = 0;
        for i in 0..w * h {
            if scene.background.data[i] == 1.0 {
                let (x, y) = ((i % w) as u32, (i / w) as u32);
                let want = bg.each_ref().map(|plane| plane[i]);
                assert_eq!(scene.image.get_pixel(x, y).0, want);
                checked += 1;
            }
        }
        background_pixels += checked;
    }
    assert!(
        hard_seen > 20 && soft_seen > 20,
        "hard {hard_seen}, soft {soft_seen}"
    );
    assert!(
        background_pixels > 80 * 64 * 64 / 4,
        "background compared on {background_pixels} pixels"
    );
}

#[test]
fn background_placement_fits_short_side_or_shrinks() {
    let (photos, _) = common::libraries();
    for seed in 0..20u64 {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let photo = photos.get(seed as usize % photos.len()).unwrap();
        let p = random_placement(&mut rng, &photo, 300, 200, 0.5, true);
        assert!(p.resized_w >= 300 && p.resized_h >= 200);
        assert!(p.x0 + 300 <= p.resized_w && p.y0 + 200 <= p.resized_h);
        // Aspect ratio is kept (to rounding).
        let (pw, ph) = (photo.pyramid.width() as f64, photo.pyramid.height() as f64);
        let ratio = p.resized_w as f64 / p.resized_h as f64;
        assert!((ratio - pw / ph).abs() < 0.02 * pw / ph + 2.0 / p.resized_h as f64);
    }
}
