//! `matseg bench-net`: the net's forward and training-step time on one
//! batch size (`matseg_pipeline::bench::net`), as a table row or JSON.
//! `scripts/bench-net-pytorch.py` times the same net and step in PyTorch
//! for the ratio in BENCHMARKS.md.

use crate::net_args::parse_device;
use anyhow::{bail, Result};
use matseg_pipeline::bench::net::NetBench;

/// Arguments of `matseg bench-net`.
#[derive(clap::Args)]
pub struct Args {
    /// Encoder: mobilenet-v2, convnext-tiny or convnext-base.
    #[arg(long, default_value = "mobilenet-v2")]
    encoder: String,
    /// Side of the square images, in pixels (multiple of 32).
    #[arg(long, default_value_t = 256)]
    side: usize,
    /// Images per batch.
    #[arg(long, default_value_t = 4)]
    batch: usize,
    /// Timed repetitions of each measurement (the median is reported).
    #[arg(long, default_value_t = 5)]
    repeats: usize,
    /// Untimed repetitions first.
    #[arg(long, default_value_t = 1)]
    warmup: usize,
    /// cpu, cuda or cuda:N.
    #[arg(long, default_value = "cpu")]
    device: String,
    /// Print JSON instead of a table row.
    #[arg(long)]
    json: bool,
}

/// Runs `matseg bench-net`.
pub fn run(args: Args) -> Result<()> {
    if args.side == 0 || !args.side.is_multiple_of(32) || args.batch == 0 || args.repeats == 0 {
        bail!("--side must be a positive multiple of 32, --batch and --repeats positive");
    }
    let bench = NetBench {
        encoder: args.encoder.clone(),
        side: args.side,
        batch: args.batch,
        repeats: args.repeats,
        warmup: args.warmup,
        device: parse_device(&args.device)?,
    };
    let r = bench.run()?;
    if args.json {
        let out = serde_json::json!({
            "encoder": args.encoder,
            "side": args.side,
            "batch": args.batch,
            "device": args.device,
            "threads": r.threads,
            "forward_ms": r.forward_ms,
            "train_step_ms": r.train_step_ms,
            "peak_rss_mib": r.peak_rss_mib,
        });
        println!("{out}");
    } else {
        println!(
            "| {} | {}² x {} | {} | {:.0} | {:.0} | {} |",
            args.encoder,
            args.side,
            args.batch,
            args.device,
            r.forward_ms,
            r.train_step_ms,
            r.peak_rss_mib.map_or("-".into(), |m| format!("{m:.0}"))
        );
    }
    Ok(())
}
