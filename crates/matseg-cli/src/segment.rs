//! `matseg segment`: where else in this photo is the material under these
//! points? Similarity maps from a trained net (SPEC 8, inference), and a hard
//! segmentation when several points are given.

use crate::train::parse_device;
use anyhow::{bail, Context, Result};
use matseg_eval::descriptor::{Comparison, DescriptorMap};
use matseg_image::io::{encode_png_gray, encode_png_rgb, read_rgb, write_atomic};
use matseg_net::infer::TrainedNet;
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
    #[arg(long = "point", required = true, value_parser = parse_point)]
    points: Vec<(f32, f32)>,
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
    for &(x, y) in &args.points {
        if !(0.0..w as f32).contains(&x) || !(0.0..h as f32).contains(&y) {
            bail!(
                "--point {x},{y}: outside {} ({w}x{h})",
                args.image.display()
            );
        }
    }
    let net = TrainedNet::load(&args.model, parse_device(&args.device)?)?;
    let descriptors = net.describe(photo.as_raw(), w, h);
    let dim = descriptors.size()[0] as usize;
    let data = Vec::<f32>::try_from(descriptors.permute([1, 2, 0]).contiguous().flatten(0, -1))
        .context("descriptor map")?;
    let map = DescriptorMap {
        width: w,
        height: h,
        dim,
        data,
    };
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("{}: cannot create", args.out.display()))?;
    let write = |name: &str, bytes: Vec<u8>| {
        let path = args.out.join(name);
        write_atomic(&path, &bytes).with_context(|| format!("{}: cannot write", path.display()))
    };
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
            let a = s.clamp(0.0, 1.0);
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
        let mut segmentation = photo.clone();
        for (j, p) in segmentation.pixels_mut().enumerate() {
            let best = (0..maps.len())
                .max_by(|&a, &b| maps[a][j].total_cmp(&maps[b][j]))
                .expect("points");
            let c = PALETTE[best % PALETTE.len()];
            for (v, &colour) in p.0.iter_mut().zip(&c) {
                *v = ((*v as u16 + 2 * colour as u16) / 3) as u8;
            }
        }
        write("segmentation.png", encode_png_rgb(&segmentation))?;
    }
    println!(
        "{}: {} similarity map(s){}",
        args.out.display(),
        maps.len(),
        if maps.len() > 1 {
            " and segmentation.png"
        } else {
            ""
        }
    );
    Ok(())
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
