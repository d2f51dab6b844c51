//! `matseg bench-set make` and `masks`: a point benchmark and a mask
//! benchmark from generated scenes, so the evaluations run end to end
//! without external data; `matseg bench-set draw`: any point benchmark's
//! annotations drawn on its photos (`matseg_pipeline::point_bench`).

use crate::common::LibraryArgs;
use anyhow::Result;
use clap::Subcommand;
use matseg_image::outputs::StagedOutput;
use matseg_pipeline::point_bench::{
    draw_point_benchmark, make_mask_benchmark, make_point_benchmark, mask_benchmark_from_dataset,
};
use matseg_pipeline::sources::DEFAULT_CACHE_MB;
use std::path::PathBuf;

/// `matseg bench-set` subcommands.
#[derive(Subcommand)]
pub enum Command {
    /// Write a point benchmark (MatSeg layout) made from generated 2D scenes.
    Make(MakeArgs),
    /// Write a mask benchmark (NAME.jpg, NAME.maskK.png; for `eval masks`
    /// and `eval clicks`) made from generated 2D scenes, or from the
    /// samples of a generated dataset (`--from`, e.g. video frames).
    Masks(MasksArgs),
    /// Draw each image's points on it (NAME.png: rings in one colour per
    /// material, labelled with its id), to check an annotation by eye.
    Draw(DrawArgs),
}

/// Arguments of `matseg bench-set draw`.
#[derive(clap::Args)]
pub struct DrawArgs {
    /// Benchmark folder (images/, data/NAME/data.json).
    bench: PathBuf,
    /// Output folder for the NAME.png overlays; written whole, replacing
    /// only an earlier `bench-set draw` output (docs/outputs.md).
    #[arg(long)]
    out: PathBuf,
    /// Magnify photos whose longer side is below this many pixels twofold.
    #[arg(long, default_value_t = 450)]
    magnify_below: u32,
}

/// Arguments of `matseg bench-set make`.
#[derive(clap::Args)]
pub struct MakeArgs {
    /// Output folder (images/, data/); written whole, replacing only an
    /// earlier `bench-set make` output (docs/outputs.md).
    #[arg(long)]
    out: PathBuf,
    /// Number of scenes to generate (scenes with fewer than two pointed
    /// materials are left out).
    #[arg(short = 'n', long = "scenes", default_value_t = 20)]
    n: u64,
    /// Seed: scene i depends only on (seed, i).
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Points per material.
    #[arg(long, default_value_t = 5)]
    points: usize,
    #[command(flatten)]
    libraries: LibraryArgs,
}

/// Arguments of `matseg bench-set masks`.
#[derive(clap::Args)]
pub struct MasksArgs {
    /// Output folder (NAME.jpg, NAME.mask0.png, ...); written whole,
    /// replacing only an earlier `bench-set masks` output
    /// (docs/outputs.md).
    #[arg(long)]
    out: PathBuf,
    /// Number of scenes to generate.
    #[arg(short = 'n', long = "scenes", default_value_t = 20)]
    n: u64,
    /// Seed: scene i depends only on (seed, i).
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Instead of generating scenes, take every sample of this dataset
    /// (`matseg generate` output: folders or shards) with its masks and
    /// region of interest.
    #[arg(long, conflicts_with_all = ["n", "seed"])]
    from: Option<PathBuf>,
    #[command(flatten)]
    libraries: LibraryArgs,
}

/// Runs `matseg bench-set`.
pub fn run(command: Command) -> Result<()> {
    match command {
        Command::Make(args) => make(args),
        Command::Draw(args) => draw(args),
        Command::Masks(args) => masks(args),
    }
}

fn masks(args: MasksArgs) -> Result<()> {
    if let Some(data) = &args.from {
        let staged = StagedOutput::begin(&args.out, "bench-set masks", &[data])?;
        let written = mask_benchmark_from_dataset(data, staged.dir())?;
        staged.finish()?;
        println!(
            "{}: mask benchmark of {written} samples of {}",
            args.out.display(),
            data.display()
        );
        return Ok(());
    }
    let libraries = args.libraries.load(DEFAULT_CACHE_MB)?;
    let staged = StagedOutput::begin(&args.out, "bench-set masks", &libraries.roots())?;
    let written = make_mask_benchmark(staged.dir(), args.n, args.seed, &libraries)?;
    staged.finish()?;
    println!("{}: mask benchmark of {written} scenes", args.out.display());
    Ok(())
}

fn draw(args: DrawArgs) -> Result<()> {
    let staged = StagedOutput::begin(&args.out, "bench-set draw", &[&args.bench])?;
    let (overlays, points) = draw_point_benchmark(&args.bench, staged.dir(), args.magnify_below)?;
    staged.finish()?;
    println!(
        "{}: {overlays} overlays, {points} points",
        args.out.display()
    );
    Ok(())
}

fn make(args: MakeArgs) -> Result<()> {
    let libraries = args.libraries.load(DEFAULT_CACHE_MB)?;
    let staged = StagedOutput::begin(&args.out, "bench-set make", &libraries.roots())?;
    let (written, left_out) =
        make_point_benchmark(staged.dir(), args.n, args.seed, args.points, &libraries)?;
    staged.finish()?;
    println!(
        "{}: point benchmark of {written} scenes ({left_out} with fewer than two pointed materials left out)",
        args.out.display()
    );
    Ok(())
}
