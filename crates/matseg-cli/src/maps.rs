//! `matseg maps`: the soft maps of one photo, for inspection or reuse
//! (`matseg_pipeline::soft_maps`).

use anyhow::Result;
use matseg_image::outputs::StagedOutput;
use matseg_pipeline::soft_maps::PhotoMaps;
use std::path::PathBuf;

/// Arguments of `matseg maps`.
#[derive(clap::Args)]
pub struct Args {
    /// The photo to cut maps from.
    photo: PathBuf,
    /// Output folder; written whole, replacing only an earlier maps output
    /// (docs/outputs.md).
    #[arg(long)]
    out: PathBuf,
    /// Number of maps.
    #[arg(short = 'n', long = "maps", value_name = "K", default_value_t = 4)]
    n: usize,
    /// Seed.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Force a hard (one-hot) combination; default: drawn as for a scene.
    #[arg(long)]
    hard: bool,
    /// The maps are at most this many pixels on their longer side.
    #[arg(long, default_value_t = 1024)]
    max_side: u32,
    /// TOML recipe overriding map probabilities.
    #[arg(long)]
    config: Option<PathBuf>,
}

/// Runs `matseg maps`: draws the maps of one photo and writes them.
pub fn run(args: Args) -> Result<()> {
    let recipe = crate::common::load_recipe(args.config.as_deref(), None)?;
    let maps = PhotoMaps {
        maps: args.n,
        seed: args.seed,
        hard: args.hard,
        max_side: args.max_side,
    };
    let mut inputs = vec![args.photo.as_path()];
    inputs.extend(args.config.as_deref());
    let staged = StagedOutput::begin(&args.out, "maps", &inputs)?;
    let s = maps.write(&args.photo, &recipe, staged.dir())?;
    staged.finish()?;
    eprintln!(
        "{}: {} maps of {}x{} ({}) written",
        args.out.display(),
        args.n,
        s.width,
        s.height,
        if s.hard { "hard" } else { "soft" }
    );
    Ok(())
}
