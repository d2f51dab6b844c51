//! `matseg segment`: where else in this photo is the material under these
//! points? Similarity maps from a trained net (pipeline.md §8, inference), and a hard
//! segmentation when several points are given, or with no points by
//! clustering the descriptors (`--auto K`).

use crate::net_args::parse_device;
use crate::query_args::{parse_point, parse_radius};
use anyhow::Result;
use matseg_image::io::read_rgb;
use matseg_pipeline::segment::{
    check_points, describe, write_clusters, write_point_maps, Model, DEFAULT_RADIUS,
};
use matseg_query::ClusterOptions;
use std::path::PathBuf;
use std::time::Instant;

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
    #[arg(long = "point", required_unless_present = "auto", value_parser = parse_point, allow_hyphen_values = true)]
    points: Vec<(f32, f32)>,
    /// No points: split the photo into K materials by clustering the
    /// descriptors (spherical k-means).
    #[arg(long, value_name = "K", conflicts_with = "points", value_parser = clap::value_parser!(u32).range(2..=255))]
    auto: Option<u32>,
    /// Seed of the clustering (--auto).
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Radius of each point's disc in pixels.
    #[arg(long, default_value_t = DEFAULT_RADIUS, value_parser = parse_radius, allow_negative_numbers = true)]
    radius: f32,
    /// cpu, cuda or cuda:N.
    #[arg(long, default_value = "cpu")]
    device: String,
    /// Output folder.
    #[arg(long)]
    out: PathBuf,
}

/// Runs `matseg segment`.
pub fn run(args: Args) -> Result<()> {
    let photo = read_rgb(&args.image)?;
    check_points(&photo, &args.points, &args.image.display().to_string())?;
    let net = Model::load(&args.model, parse_device(&args.device)?)?;
    let started = Instant::now();
    let map = describe(&net, &photo);
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
