//! `matseg segment`: where else in this photo is the material under these
//! points? Similarity maps from a trained net (pipeline.md §8, inference), and a hard
//! segmentation when several points are given, or with no points by
//! clustering the descriptors (`--auto K`).

use crate::net_args::parse_device;
use anyhow::{bail, Context, Result};
use image::RgbImage;
use matseg_eval::{cluster_descriptors, ClusterOptions};
use matseg_image::coarse::CoarseDescriptors;
use matseg_image::io::{encode_png_gray, encode_png_rgb, read_rgb, write_atomic};
use matseg_net::infer::TrainedNet;
use matseg_net::TEMPERATURE;
use matseg_scene::PALETTE;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Radius of a query point's disc unless `--radius` says otherwise, in pixels.
pub const DEFAULT_RADIUS: f32 = 5.0;

/// Arguments of `matseg segment`.
#[derive(clap::Args)]
pub struct Args {
    /// The photo.
    image: PathBuf,
    /// The model: `default` (the shipped one), a run folder from `matseg
    /// train`, or its weights file (model.safetensors, best.safetensors).
    #[arg(long, default_value = "default")]
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
    #[arg(long, default_value_t = DEFAULT_RADIUS)]
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

/// Runs `matseg segment`.
pub fn run(args: Args) -> Result<()> {
    let photo = read_rgb(&args.image)?;
    let (w, h) = (photo.width() as f32, photo.height() as f32);
    if args.points.len() > 255 {
        bail!("--point: at most 255 points (labels.png is 8-bit)");
    }
    for &(x, y) in &args.points {
        if !(0.0..w).contains(&x) || !(0.0..h).contains(&y) {
            bail!(
                "--point {x},{y}: outside {} ({w}x{h})",
                args.image.display()
            );
        }
    }
    let net = TrainedNet::load(&args.model, parse_device(&args.device)?)?;
    let started = Instant::now();
    let map = net.describe_coarse(
        photo.as_raw(),
        photo.width() as usize,
        photo.height() as usize,
    );
    let described = started.elapsed().as_secs_f64();
    if let Some(k) = args.auto {
        let options = ClusterOptions {
            seed: args.seed,
            ..ClusterOptions::new(k as usize)
        };
        let clusters = write_clusters(&photo, &map, &options, &args.out)?;
        println!(
            "{}: segmentation.png and labels.png, {clusters} clusters",
            args.out.display()
        );
        return Ok(());
    }
    let queried = write_point_maps(&photo, &map, &args.points, args.radius, &args.out)?;
    println!(
        "{}: {} similarity map(s){}",
        args.out.display(),
        args.points.len(),
        if args.points.len() > 1 {
            " and segmentation.png, labels.png"
        } else {
            ""
        }
    );
    eprintln!(
        "descriptors: {:.3} s ({}x{} photo, {}x{} grid); similarity maps: {:.1} ms a point",
        described,
        photo.width(),
        photo.height(),
        map.grid.width,
        map.grid.height,
        1e3 * queried / args.points.len().max(1) as f64
    );
    Ok(())
}

/// Writes into `out`, for each point (inside `photo`, in pixels),
/// `similarity_I.png` (cosine in [0, 1] as grey) and `overlay_I.png`, and
/// for several points their nearest-point segmentation. Returns the
/// seconds spent computing the points' descriptors and similarity maps
/// (not drawing or writing them).
pub fn write_point_maps(
    photo: &RgbImage,
    map: &CoarseDescriptors,
    points: &[(f32, f32)],
    radius: f32,
    out: &Path,
) -> Result<f64> {
    create_folder(out)?;
    let (w, h) = photo.dimensions();
    let mut queries = Vec::new();
    let mut queried = 0.0;
    for (i, &(x, y)) in points.iter().enumerate() {
        let started = Instant::now();
        let query = map.point_descriptor(x, y, radius);
        let similarity = map.similarity_map(&query);
        queried += started.elapsed().as_secs_f64();
        // Cosine in [0, 1] to grey levels (negative similarity is black).
        let grey: Vec<u8> = similarity
            .iter()
            .map(|s| (s.clamp(0.0, 1.0) * 255.0).round() as u8)
            .collect();
        write_file(
            out,
            &format!("similarity_{i}.png"),
            encode_png_gray(w, h, &grey),
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
        mark(&mut overlay, x, y, radius);
        write_file(out, &format!("overlay_{i}.png"), encode_png_rgb(&overlay))?;
        queries.push(query);
    }
    if queries.len() > 1 {
        write_segmentation(photo, &map.nearest_query(&queries), out)?;
    }
    Ok(queried)
}

/// Writes into `out` the segmentation of `photo` by k-means on its
/// descriptor grid (each pixel then takes its nearest centre); returns the
/// number of clusters.
pub fn write_clusters(
    photo: &RgbImage,
    map: &CoarseDescriptors,
    options: &ClusterOptions,
    out: &Path,
) -> Result<usize> {
    create_folder(out)?;
    let clustering = cluster_descriptors(&map.grid, options);
    write_segmentation(photo, &map.nearest_query(&clustering.centres), out)?;
    Ok(clustering.centres.len())
}

/// How red a pixel of similarity `s` is painted in an overlay: the
/// training softmax's weight of the point's material relative to a perfect
/// match, `exp((s - 1) / T)`, so the map reads as the net was taught to
/// read it (cosine 1: full red; 0.8: 37%; 0.5: 8%).
fn overlay_strength(s: f32) -> f32 {
    (((s - 1.0) as f64 / TEMPERATURE).exp() as f32).clamp(0.0, 1.0)
}

/// Writes `segmentation.png` (each label's palette colour blended over the
/// photo) and `labels.png` (8-bit grey, pixel value = label).
fn write_segmentation(photo: &RgbImage, labels: &[u32], out: &Path) -> Result<()> {
    let mut segmentation = photo.clone();
    for (p, &label) in segmentation.pixels_mut().zip(labels) {
        let c = PALETTE[label as usize % PALETTE.len()];
        for (v, &colour) in p.0.iter_mut().zip(&c) {
            *v = ((*v as u16 + 2 * colour as u16) / 3) as u8;
        }
    }
    write_file(out, "segmentation.png", encode_png_rgb(&segmentation))?;
    let grey: Vec<u8> = labels.iter().map(|&l| l as u8).collect();
    write_file(
        out,
        "labels.png",
        encode_png_gray(photo.width(), photo.height(), &grey),
    )
}

fn create_folder(out: &Path) -> Result<()> {
    std::fs::create_dir_all(out).with_context(|| format!("{}: cannot create", out.display()))
}

/// Writes `out/name` atomically.
fn write_file(out: &Path, name: &str, bytes: Vec<u8>) -> Result<()> {
    let path = out.join(name);
    write_atomic(&path, &bytes).with_context(|| format!("{}: cannot write", path.display()))
}

/// Draws the query disc's outline in white.
fn mark(img: &mut RgbImage, x: f32, y: f32, r: f32) {
    let r = r.max(3.0);
    for k in 0..64 {
        let t = k as f32 / 64.0 * std::f32::consts::TAU;
        let (px, py) = ((x + r * t.cos()).round(), (y + r * t.sin()).round());
        if px >= 0.0 && py >= 0.0 && (px as u32) < img.width() && (py as u32) < img.height() {
            img.put_pixel(px as u32, py as u32, image::Rgb([255, 255, 255]));
        }
    }
}
