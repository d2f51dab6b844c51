//! `matseg bench-net`: the net's speed on one batch size: inference forward
//! time and training step time (forward, MatSeg loss, backward, AdamW), and
//! the process's peak memory. `scripts/bench-net-pytorch.py` times the same
//! net and step in PyTorch for the ratio in BENCHMARKS.md.

use crate::cpu_time::{median, peak_rss_mib};
use crate::net_args::{parse_device, preset};
use anyhow::{bail, Result};
use matseg_net::batch::{Batch, TrainingSample};
use matseg_net::data::BatchPlan;
use matseg_net::train::{RunConfig, TrainOptions, Trainer};
use rand::{Rng, SeedableRng};
use std::time::Instant;
use tch::Device;

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
    /// cpu or cuda.
    #[arg(long, default_value = "cpu")]
    device: String,
    /// Print JSON instead of a table row.
    #[arg(long)]
    json: bool,
}

/// Materials per synthetic image.
const MATERIALS: usize = 3;

/// Runs `matseg bench-net`.
pub fn run(args: Args) -> Result<()> {
    let net = preset(&args.encoder)?;
    if args.side == 0 || !args.side.is_multiple_of(32) || args.batch == 0 || args.repeats == 0 {
        bail!("--side must be a positive multiple of 32, --batch and --repeats positive");
    }
    let device = parse_device(&args.device)?;
    tch::manual_seed(0);
    let mut trainer = Trainer::new(
        RunConfig {
            net,
            options: TrainOptions {
                steps: u64::MAX,
                lr: 1e-4,
                warmup: 1,
                decay: 0,
                weight_decay: 4e-5,
                plan: BatchPlan::SPEC,
                seed: 0,
                checkpoint_every: u64::MAX,
                validation_batches: 0,
                lr_scales: Vec::new(),
            },
            init: "scratch".into(),
            data: "synthetic".into(),
            mix: None,
            inference_side: None,
            extra_inference_sides: Vec::new(),
        },
        device,
    );
    let samples = synthetic_batch(args.batch, args.side);
    let images = Batch::new(&samples, device).images;
    let forward = time(args.warmup, args.repeats, device, || {
        let _descriptors = tch::no_grad(|| trainer.net.forward_t(&images, false));
    });
    let step = time(args.warmup, args.repeats, device, || {
        trainer.train_step(&samples);
    });
    let peak = peak_rss_mib();
    let (f, s) = (median(forward), median(step));
    if args.json {
        let out = serde_json::json!({
            "encoder": args.encoder,
            "side": args.side,
            "batch": args.batch,
            "device": args.device,
            "threads": tch::get_num_threads(),
            "forward_ms": f,
            "train_step_ms": s,
            "peak_rss_mib": peak,
        });
        println!("{out}");
    } else {
        println!(
            "| {} | {}² x {} | {} | {:.0} | {:.0} | {} |",
            args.encoder,
            args.side,
            args.batch,
            args.device,
            f,
            s,
            peak.map_or("-".into(), |m| format!("{m:.0}"))
        );
    }
    Ok(())
}

/// `batch` square images of noise, each with three soft horizontal bands
/// of material (linear ramps between them) and a full ROI.
fn synthetic_batch(batch: usize, side: usize) -> Vec<TrainingSample> {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
    (0..batch)
        .map(|_| {
            let rgb = (0..side * side * 3).map(|_| rng.random::<u8>()).collect();
            let weights = (0..MATERIALS)
                .map(|m| {
                    (0..side * side)
                        .map(|i| {
                            let band = (i / side) as f32 / side as f32 * MATERIALS as f32 - 0.5;
                            (1.0 - (band - m as f32).abs()).clamp(0.0, 1.0)
                        })
                        .collect()
                })
                .collect();
            TrainingSample {
                rgb,
                width: side,
                height: side,
                weights,
                roi: vec![1.0; side * side],
            }
        })
        .collect()
}

/// Milliseconds of `repeats` timed calls of `f` after `warmup` untimed
/// ones (CUDA work is waited for).
fn time(warmup: usize, repeats: usize, device: Device, mut f: impl FnMut()) -> Vec<f64> {
    let sync = || {
        if let Device::Cuda(i) = device {
            tch::Cuda::synchronize(i as i64);
        }
    };
    for _ in 0..warmup {
        f();
    }
    sync();
    (0..repeats)
        .map(|_| {
            let start = Instant::now();
            f();
            sync();
            start.elapsed().as_secs_f64() * 1e3
        })
        .collect()
}
