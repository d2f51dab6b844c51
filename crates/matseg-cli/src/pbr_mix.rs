//! `matseg pbr-mix`: new PBR materials by mixing existing ones (pipeline.md
//! §5; `matseg_pipeline::material_mixes`).

use crate::common::{init_threads, BarProgress};
use anyhow::Result;
use matseg_pipeline::material_mixes::make_mixes;
use std::path::PathBuf;

/// Arguments of `matseg pbr-mix`.
#[derive(clap::Args)]
pub struct Args {
    /// A folder of material folders (ours, ambientCG, MatSeg or MatSynth naming).
    materials: PathBuf,
    /// Output folder: one folder per mix; a rerun adds the missing ones
    /// (docs/outputs.md).
    #[arg(long)]
    out: PathBuf,
    /// Number of mixes.
    #[arg(short = 'n', long = "count", default_value_t = 10)]
    n: u64,
    /// Seed: mix i depends only on (seed, i) and the materials.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Worker threads (default: all cores).
    #[arg(long)]
    threads: Option<usize>,
}

/// Runs `matseg pbr-mix`.
pub fn run(args: Args) -> Result<()> {
    init_threads(args.threads)?;
    let r = make_mixes(
        &args.materials,
        &args.out,
        args.n,
        args.seed,
        &BarProgress::default(),
    )?;
    println!(
        "{}: {} mixes of {} materials written ({} already there)",
        args.out.display(),
        r.written,
        r.materials,
        r.already
    );
    Ok(())
}
