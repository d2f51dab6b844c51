//! `matseg bench`: generator throughput at the paper's scene-size
//! distribution (`matseg_pipeline::bench::generator`), printed as a table.

use crate::common::load_libraries;
use anyhow::Result;
use matseg_image::LicenceFilter;
use matseg_pipeline::bench::generator::GeneratorBench;
use matseg_pipeline::sources::{Defaults, DEFAULT_CACHE_MB};
use std::path::PathBuf;

/// Arguments of `matseg bench`.
#[derive(clap::Args)]
pub struct Args {
    /// Scenes per measurement. A scene's cost varies by about two thirds
    /// of the mean from one scene to the next (size, K, which photos are
    /// upscaled), so a row of n scenes is within about 67%/sqrt(n) of the
    /// distribution's mean: 2% for the default, 10% for 40 scenes.
    #[arg(long, default_value_t = 1000)]
    scenes: u64,
    /// Threads for the parallel measurement (default: all cores).
    #[arg(long)]
    threads: Option<usize>,
    /// Seed of the scenes.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Folders of natural photos to measure with; default: bundled assets.
    #[arg(long, num_args = 1..)]
    sources: Vec<PathBuf>,
    /// Folders of textures to measure with; default: bundled assets.
    #[arg(long, num_args = 1..)]
    textures: Vec<PathBuf>,
    /// Memory bound for decoded source photos, in MiB.
    #[arg(long, default_value_t = DEFAULT_CACHE_MB)]
    cache_mb: usize,
    /// Where the end-to-end rows write (and then delete) their datasets;
    /// default: the system's temporary folder. The disk's cost is part of
    /// those rows.
    #[arg(long)]
    dir: Option<PathBuf>,
    /// Measure only generation in memory, one thread (no soft-maps row,
    /// encoding or disk): a run to profile, see
    /// scripts/bench-unchanged-share.sh.
    #[arg(long)]
    in_memory_only: bool,
}

/// Runs `matseg bench`: measures each row and prints the table.
pub fn run(args: Args) -> Result<()> {
    anyhow::ensure!(args.scenes >= 1, "--scenes must be at least 1");
    let libraries = load_libraries(
        &args.sources,
        &args.textures,
        args.cache_mb,
        Defaults::Bundled,
        &LicenceFilter::default(),
    )?;
    let bench = GeneratorBench {
        scenes: args.scenes,
        threads: args
            .threads
            .unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get())),
        seed: args.seed,
        dir: args.dir.unwrap_or_else(std::env::temp_dir),
        in_memory_only: args.in_memory_only,
    };
    print!("{}", bench.run(&libraries)?.text());
    Ok(())
}
