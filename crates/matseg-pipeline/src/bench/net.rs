//! The net's speed on one batch size: inference forward time and training
//! step time (forward, MatSeg loss, backward, AdamW), and the process's
//! peak memory. `scripts/bench-net-pytorch.py` times the same net and step
//! in PyTorch.

use super::clock::{median, peak_rss_mib};
use crate::error::PipelineError;
use matseg_image::device::ComputeDevice;
use matseg_net::batch::{Batch, TrainingSample};
use matseg_net::data::BatchPlan;
use matseg_net::torch_device;
use matseg_net::train::{RunConfig, TrainOptions, Trainer};
use matseg_net::{NetConfig, PRESETS};
use rand::{Rng, SeedableRng};
use std::time::Instant;
use tch::Device;

/// What to measure.
#[derive(Clone, Debug)]
pub struct NetBench {
    /// Encoder preset (one of [`PRESETS`]).
    pub encoder: String,
    /// Side of the square images, in pixels (a multiple of 32).
    pub side: usize,
    /// Images per batch.
    pub batch: usize,
    /// Timed repetitions of each measurement (the median is reported).
    pub repeats: usize,
    /// Untimed repetitions first.
    pub warmup: usize,
    /// The device.
    pub device: ComputeDevice,
}

/// Median milliseconds of a forward pass and of a training step.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NetReport {
    /// Inference forward pass, ms.
    pub forward_ms: f64,
    /// Training step, ms.
    pub train_step_ms: f64,
    /// libtorch's CPU threads.
    pub threads: i32,
    /// The process's peak resident memory, in MiB.
    pub peak_rss_mib: Option<f64>,
}

/// Materials per synthetic image.
const MATERIALS: usize = 3;

impl NetBench {
    /// Times the net on a synthetic batch.
    pub fn run(&self) -> Result<NetReport, PipelineError> {
        let net = NetConfig::preset(&self.encoder).ok_or_else(|| {
            PipelineError::setting(
                "encoder",
                Some(&self.encoder),
                format!("expected one of {}", PRESETS.join(", ")),
            )
        })?;
        if self.side == 0 || !self.side.is_multiple_of(32) || self.batch == 0 || self.repeats == 0 {
            return Err(PipelineError::Settings(
                "the side must be a positive multiple of 32, the batch and the repeats positive"
                    .into(),
            ));
        }
        let device = torch_device(self.device);
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
                features: None,
            },
            device,
        );
        let samples = synthetic_batch(self.batch, self.side);
        let images = Batch::new(&samples, device).images;
        let forward = time(self.warmup, self.repeats, device, || {
            let _descriptors = tch::no_grad(|| trainer.net.forward_t(&images, false));
        });
        let step = time(self.warmup, self.repeats, device, || {
            trainer.train_step(&samples);
        });
        Ok(NetReport {
            forward_ms: median(forward),
            train_step_ms: median(step),
            threads: tch::get_num_threads(),
            peak_rss_mib: peak_rss_mib(),
        })
    }
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
