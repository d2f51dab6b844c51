//! `matseg segment`: where else in this photo is the material under these
//! points, and not the material under the `--not` clicks? Similarity maps
//! and masks from a trained net (pipeline.md §8, inference), a hard
//! segmentation when several materials are clicked, or with no points by
//! clustering the descriptors (`--auto K`).

use crate::net_args::parse_device;
use crate::query_args::{parse_grouped_point, parse_point, parse_radius};
use anyhow::Result;
use matseg_image::io::read_rgb;
use matseg_image::outputs::StagedOutput;
use matseg_pipeline::segment::{
    describe, load_model, write_clusters, write_point_maps, DEFAULT_RADIUS,
};
use matseg_pipeline::select::MaterialClicks;
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
    /// `GROUP:X,Y` gives several points of one material (those of one
    /// group number).
    #[arg(long = "point", value_parser = parse_grouped_point, allow_hyphen_values = true)]
    points: Vec<(Option<u32>, (f32, f32))>,
    /// A negative click `X,Y`: its material is excluded from every
    /// material's selection; repeat for several.
    #[arg(long = "not", value_parser = parse_point, allow_hyphen_values = true, conflicts_with = "auto")]
    not: Vec<(f32, f32)>,
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
    /// Output folder; written whole, replacing only an earlier segment
    /// output (docs/outputs.md).
    #[arg(long)]
    out: PathBuf,
}

/// Runs `matseg segment`.
pub fn run(args: Args) -> Result<()> {
    let photo = read_rgb(&args.image)?;
    let clicks = MaterialClicks::group(&args.points, args.not.clone());
    if args.auto.is_none() {
        clicks.check(&photo, &args.image.display().to_string())?;
    }
    let staged = StagedOutput::begin(&args.out, "segment", &[&args.image])?;
    let net = load_model(&args.model, parse_device(&args.device)?)?;
    let started = Instant::now();
    let map = describe(&net, &photo);
    let described = started.elapsed().as_secs_f64();
    if let Some(k) = args.auto {
        let options = ClusterOptions {
            seed: args.seed,
            ..ClusterOptions::new(k as usize)
        };
        let clusters = write_clusters(&photo, &map, &options, staged.dir())?;
        staged.finish()?;
        println!(
            "{}: segmentation.png and labels.png, {clusters} clusters",
            args.out.display()
        );
        return Ok(());
    }
    let model = args.model.display().to_string();
    let queried = write_point_maps(&photo, &map, &clicks, args.radius, &model, staged.dir())?;
    staged.finish()?;
    let materials = clicks.materials.len();
    println!(
        "{}: {materials} similarity map(s) and mask(s){}",
        args.out.display(),
        if materials > 1 {
            ", segmentation.png, labels.png"
        } else {
            ""
        }
    );
    eprintln!(
        "descriptors: {:.3} s ({}x{} photo, {}x{} grid); selections: {:.1} ms a material",
        described,
        photo.width(),
        photo.height(),
        map.grid.width,
        map.grid.height,
        1e3 * queried / materials.max(1) as f64
    );
    Ok(())
}
