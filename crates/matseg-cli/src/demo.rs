//! `matseg demo`: the pipeline on the bundled assets, with an HTML report
//! (`matseg_pipeline::demo`).

use crate::common::{init_threads, BarProgress};
use anyhow::Result;
use matseg_pipeline::demo::{run as run_demo, DemoOptions};
use std::path::PathBuf;

/// Arguments of `matseg demo`.
#[derive(clap::Args)]
pub struct Args {
    /// Output folder for the samples and `index.html`; a rerun continues
    /// it (docs/outputs.md).
    #[arg(long, default_value = "demo-out")]
    out: PathBuf,
    /// Number of 2D samples.
    #[arg(short = 'n', long = "samples", value_name = "N", default_value_t = 36)]
    n: u64,
    /// Number of 3D samples (0: no 3D page).
    #[arg(long, default_value_t = 6)]
    samples_3d: u64,
    /// Side of the 3D samples, in pixels.
    #[arg(long, default_value_t = 256)]
    size_3d: u32,
    /// Seed.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Worker threads (default: all cores).
    #[arg(long)]
    threads: Option<usize>,
    /// Steps of the demo's training demonstration (0: none; the net page
    /// still shows the shipped model). A build without the net has no net
    /// page and takes only 0.
    #[arg(long, default_value_t = DEFAULT_TRAIN_STEPS)]
    train_steps: u64,
}

/// Training steps of the demo's net page by default (none without the net).
#[cfg(feature = "net")]
const DEFAULT_TRAIN_STEPS: u64 = 150;
/// Training steps of the demo's net page by default (none without the net).
#[cfg(not(feature = "net"))]
const DEFAULT_TRAIN_STEPS: u64 = 0;

/// Runs `matseg demo`: generates samples from the bundled assets and writes the HTML report.
pub fn run(args: Args) -> Result<()> {
    init_threads(args.threads)?;
    let options = DemoOptions {
        out: args.out,
        samples_2d: args.n,
        samples_3d: args.samples_3d,
        size_3d: args.size_3d,
        seed: args.seed,
        train_steps: args.train_steps,
    };
    let report = run_demo(&options, &BarProgress::default())?;
    #[cfg(feature = "net")]
    if let Some(training) = &report.training {
        if let Some(loaded) = &training.initial_weights {
            eprintln!("{loaded}");
        }
        crate::training::print_trained(
            &training.dir,
            training.step,
            &training.model_file,
            &training.summary,
            "cpu",
        );
    }
    eprintln!(
        "{}: demo report with {} samples",
        report.index.display(),
        report.samples
    );
    Ok(())
}
