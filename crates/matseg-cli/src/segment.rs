//! `matseg segment`: where else in this photo is the material under these
//! points? Similarity maps from a trained net (SPEC 8, inference), and a hard
//! segmentation when several points are given, or with no points by
//! clustering the descriptors (`--auto K`).

use crate::train::parse_device;
use anyhow::{bail, Context, Result};
use matseg_eval::descriptor::Comparison;
use matseg_eval::{cluster_descriptors, ClusterOptions};
use matseg_image::io::{encode_png_gray, encode_png_rgb, read_rgb, write_atomic};
use matseg_net::infer::TrainedNet;
use matseg_net::TEMPERATURE;
use std::path::PathBuf;

/// Arguments of `matseg segment`.
#[derive(clap::Args)]
pub struct Args {
    /// The photo.
    image: PathBuf,
    /// A run folder from `matseg train`, or its model.safetensors.
    #[arg(long)]
    model: PathBuf,
    /// A query point `X,Y` in image pixels; repeat for several materials.
    #[arg(long = "point", required_unless_present = "auto", value_parser = parse_point)]
    points: Vec<(f32, f32)>,
    /// No points: split the photo into K materials by clustering the
    /// descriptors (spherical k-means).
    #[arg(long, value_name = "K", conflicts_with = "points", value_parser = clap::value_parser!(u32).range(2..=255))]
    auto: Option<u32>,
    /// Seed of the clustering (--auto).
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Radius of each point's disc in pixels.
    #[arg(long, default_value_t = 5.0)]
    radius: f32,
    /// cpu or cuda.
    #[arg(long, default_value = "cpu")]
    device: String,
    /// Output folder.
    #[arg(long)]
    out: PathBuf,
}

fn parse_point(s: &str) -> Result<(f32, f32), String> {
    let (x, y) = s
        .split_once(',')
        .ok_or_else(|| format!("{s}: expected X,Y"))?;
    let number = |v: &str| {
        v.trim()
            .parse::<f32>()
            .map_err(|_| format!("{s}: expected X,Y numbers"))
    };
    Ok((number(x)?, number(y)?))
}

/// Distinct colours for the segmentation's labels.
const PALETTE: [[u8; 3]; 8] = [
    [230, 25, 75],
    [60, 180, 75],
    [255, 225, 25],
    [0, 130, 200],
    [245, 130, 48],
    [145, 30, 180],
    [70, 240, 240],
    [240, 50, 230],
];

/// Runs `matseg segment`.
pub fn run(args: Args) -> Result<()> {
    let photo = read_rgb(&args.image)?;
    let (w, h) = (photo.width() as usize, photo.height() as usize);
    if args.points.len() > 255 {
        bail!("--point: at most 255 points (labels.png is 8-bit)");
    }
    for &(x, y) in &args.points {
        if !(0.0..w as f32).contains(&x) || !(0.0..h as f32).contains(&y) {
            bail!(
                "--point {x},{y}: outside {} ({w}x{h})",
                args.image.display()
            );
        }
    }
    let net = TrainedNet::load(&args.model, parse_device(&args.device)?)?;
    let map = net.descriptor_map(&photo);
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("{}: cannot create", args.out.display()))?;
    let write = |name: &str, bytes: Vec<u8>| {
        let path = args.out.join(name);
        write_atomic(&path, &bytes).with_context(|| format!("{}: cannot write", path.display()))
    };
    if let Some(k) = args.auto {
        let options = ClusterOptions {
            seed: args.seed,
            ..ClusterOptions::new(k as usize)
        };
        let clustering = cluster_descriptors(&map, &options);
        write_segmentation(&photo, &clustering.labels, &write)?;
        println!(
            "{}: segmentation.png and labels.png, {} clusters",
            args.out.display(),
            clustering.centres.len()
        );
        return Ok(());
    }
    let mut maps = Vec::new();
    for (i, &(x, y)) in args.points.iter().enumerate() {
        let query = map.point_descriptor(x, y, args.radius, Comparison::Cosine);
        let similarity = map.similarity_map(&query, Comparison::Cosine);
        // Cosine in [0, 1] to grey levels (negative similarity is black).
        let grey: Vec<u8> = similarity
            .iter()
            .map(|s| (s.clamp(0.0, 1.0) * 255.0).round() as u8)
            .collect();
        write(
            &format!("similarity_{i}.png"),
            encode_png_gray(w as u32, h as u32, &grey),
        )?;
        let mut overlay = photo.clone();
        for (p, s) in overlay.pixels_mut().zip(&similarity) {
            let a = overlay_strength(*s);
            p.0 = [
                (p.0[0] as f32 * (1.0 - a) + 255.0 * a) as u8,
                (p.0[1] as f32 * (1.0 - a)) as u8,
                (p.0[2] as f32 * (1.0 - a)) as u8,
            ];
        }
        mark(&mut overlay, x, y, args.radius);
        write(&format!("overlay_{i}.png"), encode_png_rgb(&overlay))?;
        maps.push(similarity);
    }
    if maps.len() > 1 {
        let labels: Vec<u32> = (0..w * h)
            .map(|j| {
                (0..maps.len())
                    .max_by(|&a, &b| maps[a][j].total_cmp(&maps[b][j]))
                    .expect("points") as u32
            })
            .collect();
        write_segmentation(&photo, &labels, &write)?;
    }
    println!(
        "{}: {} similarity map(s){}",
        args.out.display(),
        maps.len(),
        if maps.len() > 1 {
            " and segmentation.png, labels.png"
        } else {
            ""
        }
    );
    Ok(())
}

/// How red a pixel of similarity `s` is painted in an overlay: the
/// training softmax's weight of the point's material relative to a perfect
/// match, `exp((s - 1) / T)`, so the map reads as the net was taught to
/// read it (cosine 1: full red; 0.8: 37%; 0.5: 8%).
fn overlay_strength(s: f32) -> f32 {
    (((s - 1.0) as f64 / TEMPERATURE).exp() as f32).clamp(0.0, 1.0)
}

/// Writes `segmentation.png` (each label's colour blended over the photo)
/// and `labels.png` (8-bit grey, pixel value = label).
fn write_segmentation(
    photo: &image::RgbImage,
    labels: &[u32],
    write: &dyn Fn(&str, Vec<u8>) -> Result<()>,
) -> Result<()> {
    let mut segmentation = photo.clone();
    for (p, &label) in segmentation.pixels_mut().zip(labels) {
        let c = PALETTE[label as usize % PALETTE.len()];
        for (v, &colour) in p.0.iter_mut().zip(&c) {
            *v = ((*v as u16 + 2 * colour as u16) / 3) as u8;
        }
    }
    write("segmentation.png", encode_png_rgb(&segmentation))?;
    let grey: Vec<u8> = labels.iter().map(|&l| l as u8).collect();
    write(
        "labels.png",
        encode_png_gray(photo.width(), photo.height(), &grey),
    )
}

/// Draws the query disc's outline in white.
fn mark(img: &mut image::RgbImage, x: f32, y: f32, r: f32) {
    let r = r.max(3.0);
    for k in 0..64 {
        let t = k as f32 / 64.0 * std::f32::consts::TAU;
        let (px, py) = ((x + r * t.cos()).round(), (y + r * t.sin()).round());
        if px >= 0.0 && py >= 0.0 && (px as u32) < img.width() && (py as u32) < img.height() {
            img.put_pixel(px as u32, py as u32, image::Rgb([255, 255, 255]));
        }
    }
}
