//! `matseg pbr`: PBR materials from a texture library (pipeline.md §5).

use crate::common::{init_threads, BarProgress};
use anyhow::Result;
use matseg_pipeline::materials::make_library;
use std::path::PathBuf;

/// Arguments of `matseg pbr`.
#[derive(clap::Args)]
pub struct Args {
    /// Texture images or folders of them (e.g. a `matseg textures` library).
    #[arg(required = true, num_args = 1..)]
    textures: Vec<PathBuf>,
    /// Output folder: one folder per material; a rerun adds the missing
    /// ones (docs/outputs.md).
    #[arg(long)]
    out: PathBuf,
    /// Materials per texture.
    #[arg(short = 'n', long = "per-texture", default_value_t = 1)]
    per_texture: u64,
    /// Seed: material j of texture i depends only on (seed, i, j).
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Make every map tileable (edges match when the material is repeated).
    #[arg(long)]
    seamless: bool,
    /// Worker threads (default: all cores).
    #[arg(long)]
    threads: Option<usize>,
}

/// Runs `matseg pbr`.
pub fn run(args: Args) -> Result<()> {
    init_threads(args.threads)?;
    let made = make_library(
        &args.textures,
        &args.out,
        args.per_texture,
        args.seed,
        args.seamless,
        &BarProgress::default(),
    )?;
    let per_mp = |s: f64| {
        if made.megapixels > 0.0 {
            s / made.megapixels
        } else {
            0.0
        }
    };
    println!(
        "{}: {} materials written ({} already there, {} failed); per megapixel of material: {:.3} s making the maps, {:.3} s encoding and writing them",
        args.out.display(),
        made.written,
        made.existing,
        made.failed,
        per_mp(made.make_seconds),
        per_mp(made.write_seconds),
    );
    Ok(())
}
