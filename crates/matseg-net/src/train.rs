//! The training loop: batches from a [`SampleSource`] or a feature cache
//! ([`crate::features`]) prepared in background threads, the MatSeg loss,
//! AdamW with linear warm-up, a metrics log, periodic validation on
//! held-out generated batches, and checkpoints that resume exactly.
//!
//! A run folder holds `run.json` (the net's shape and the options),
//! `model.safetensors` (the weights, for inference), `best.safetensors`
//! (with a point benchmark to validate on: the weights of the checkpoint
//! that scored best on it), `checkpoint.safetensors`
//! (weights, optimizer state and the next step: all a resume needs, written
//! atomically), `metrics.jsonl` (one line per step) and `loss.png`.

use crate::batch::{Batch, TrainingSample};
use crate::blocks::l2_normalise;
use crate::checkpoint_keys;
use crate::data::{batch_samples, BatchPlan, SampleSource};
use crate::features::{epoch_indices, CacheManifest, CachedBatch, CachedSample, FeatureCache};
use crate::loader::BatchLoader;
use crate::loss::matseg_loss;
use crate::net::{MaterialNet, NetConfig};
use crate::optim::{AdamW, AdamWConfig};
use crate::plot::plot_losses;
use crate::weights::load_tensors;
use crate::NetError;
use matseg_image::outputs::temporary_path;
use serde::{Deserialize, Serialize};
use std::io::Write;
use std::path::Path;
use std::time::Instant;
use tch::{nn, Device, Tensor};

/// The run's settings, stored in `run.json`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TrainOptions {
    /// Steps (batches) in all.
    pub steps: u64,
    /// Peak learning rate.
    pub lr: f64,
    /// Steps of linear warm-up to `lr`.
    pub warmup: u64,
    /// Over the last this many steps the learning rate falls linearly
    /// towards 0 (0: constant after the warm-up).
    #[serde(default)]
    pub decay: u64,
    /// Decoupled weight decay.
    pub weight_decay: f64,
    /// Batch sizes and augmentation.
    pub plan: BatchPlan,
    /// Seed of the batch stream.
    pub seed: u64,
    /// Steps between checkpoints (and validations).
    pub checkpoint_every: u64,
    /// Held-out batches per validation (0: none).
    pub validation_batches: u64,
    /// Learning-rate factors of groups of variables, applied in order (a
    /// later one wins where both apply); e.g. `encoder.` at 0.1 for an
    /// ImageNet encoder that learns ten times slower than the head.
    #[serde(default)]
    pub lr_scales: Vec<LrScale>,
}

impl TrainOptions {
    /// Learning rate at `step`: linear warm-up, then constant, then (with
    /// `decay`) a linear fall over the last `decay` steps.
    pub fn lr_at(&self, step: u64) -> f64 {
        let warm = ((step + 1) as f64 / self.warmup.max(1) as f64).min(1.0);
        let left = self.steps.saturating_sub(step) as f64;
        let cool = if self.decay == 0 {
            1.0
        } else {
            (left / self.decay as f64).min(1.0)
        };
        self.lr * warm * cool
    }
}

/// The learning rate of the variables whose names start with `prefix`
/// (`encoder.`, `encoder.features.1.`...) multiplied by `scale` (0
/// freezes them).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct LrScale {
    /// Start of the variables' names.
    pub prefix: String,
    /// Factor of their learning rate.
    pub scale: f64,
}

/// Learning rate for an ImageNet-initialised encoder (pipeline.md §8).
pub const LR_PRETRAINED: f64 = 1e-5;
/// Learning rate from scratch: a randomly initialised net needs larger
/// steps; 1e-4 with warm-up trains our ConvNeXt and MobileNetV2 nets stably.
pub const LR_SCRATCH: f64 = 1e-4;
/// Default warm-up steps.
pub const WARMUP_STEPS: u64 = 100;
/// Validation batches are drawn from this seed offset, disjoint from training.
pub const VALIDATION_SEED: u64 = 0x7661_6c69_6461_7465;

/// What `run.json` holds.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RunConfig {
    /// The net's shape.
    pub net: NetConfig,
    /// Training settings.
    pub options: TrainOptions,
    /// Where the initial weights came from (`scratch`, `imagenet`, a path).
    pub init: String,
    /// Where the data came from.
    pub data: String,
    /// A second source mixed into `data`, if any.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mix: Option<Mix>,
    /// At inference, photos whose longer side exceeds this many pixels are
    /// described at that size (the descriptors resized back to the photo):
    /// a net trained on crops of a few hundred pixels sees materials at
    /// the scale it learned them, and large photos cost less. `None`: at
    /// their own size.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub inference_side: Option<u32>,
    /// Further longer sides photos are described at, at inference: the
    /// unit descriptors of every size are resized onto the main size's
    /// grid and averaged (a multi-scale descriptor, one forward pass each).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub extra_inference_sides: Vec<u32>,
    /// The feature cache a run on cached features trains on (then `data`
    /// says where the cache's scenes came from).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub features: Option<CachedFeatures>,
}

/// The feature cache of a run on cached features: its folder and its
/// manifest as the run started on it (a resumed run must find the same).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CachedFeatures {
    /// The cache's folder.
    pub cache: String,
    /// Its `cache.json`.
    pub manifest: CacheManifest,
}

/// A stored dataset mixed into the training data (see
/// [`crate::data::MixedSource`]).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Mix {
    /// The dataset's folder.
    pub data: String,
    /// The share of samples taken from it.
    pub fraction: f64,
}

/// One line of `metrics.jsonl`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct StepMetrics {
    /// Step index (0-based).
    pub step: u64,
    /// Training loss, or `None` for a batch with fewer than two materials.
    pub loss: Option<f64>,
    /// Learning rate used.
    pub lr: f64,
    /// Images in the batch.
    pub images: usize,
    /// Batch image width.
    pub width: usize,
    /// Batch image height.
    pub height: usize,
    /// Wall seconds of the step: waiting for its batch, then the forward,
    /// loss, backward and update (validation and checkpoints not counted).
    #[serde(default)]
    pub seconds: f64,
    /// Of `seconds`, those spent waiting for the batch (when the loader
    /// threads fall behind the net).
    #[serde(default)]
    pub data_seconds: f64,
    /// Mean validation loss, on validation steps.
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub validation: Option<f64>,
    /// The point-benchmark score, on validation steps when there is one.
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub val_points: Option<f64>,
}

/// A score of the net as it is now, higher is better (e.g. triplet
/// accuracy on a point benchmark); errors are one-line messages.
pub type NetScore<'a> = &'a dyn Fn(&Trainer) -> Result<f64, NetError>;

/// What a run validates on at each checkpoint.
#[derive(Clone, Copy)]
pub struct Validation<'a> {
    /// Held-out samples: `validation_batches` batches of them, scored by
    /// the mean MatSeg loss.
    pub samples: Option<&'a dyn SampleSource>,
    /// A point benchmark's score.
    pub points: Option<NetScore<'a>>,
}

/// A net being trained, with its optimizer and the next step.
pub struct Trainer {
    /// The variables (the net's parameters and BatchNorm statistics).
    pub vs: nn::VarStore,
    /// The net.
    pub net: MaterialNet,
    optimizer: AdamW,
    /// The next step to take.
    pub step: u64,
    /// The run's settings.
    pub config: RunConfig,
}

fn torch_error(file: &Path) -> impl Fn(tch::TchError) -> NetError + '_ {
    move |source| NetError::Torch {
        file: file.display().to_string(),
        source,
    }
}

impl Trainer {
    /// A fresh trainer (weights as initialised by the caller afterwards
    /// through [`Trainer::vs`]).
    pub fn new(config: RunConfig, device: Device) -> Self {
        let vs = nn::VarStore::new(device);
        let net = MaterialNet::new(&vs.root(), config.net);
        let mut optimizer = AdamW::new(
            &vs,
            AdamWConfig {
                weight_decay: config.options.weight_decay,
                ..Default::default()
            },
        );
        for group in &config.options.lr_scales {
            optimizer.scale_lr(&group.prefix, group.scale);
        }
        Self {
            vs,
            net,
            optimizer,
            step: 0,
            config,
        }
    }

    /// Resumes the run in `dir` from its last checkpoint.
    pub fn resume(dir: &Path, device: Device) -> Result<Self, NetError> {
        let config = read_run_config(dir)?;
        let mut trainer = Self::new(config, device);
        let path = dir.join(CHECKPOINT_FILE);
        let saved = Tensor::read_safetensors(&path).map_err(torch_error(&path))?;
        let bad = |message: String| NetError::File {
            file: path.display().to_string(),
            message,
        };
        let mut model = Vec::new();
        let mut optim = Vec::new();
        let mut next_batch = None;
        for (name, t) in saved {
            if let Some(n) = name.strip_prefix(checkpoint_keys::MODEL) {
                model.push((n.to_string(), t));
            } else if let Some(n) = name.strip_prefix(checkpoint_keys::OPTIMIZER) {
                optim.push((n.to_string(), t));
            } else if name == checkpoint_keys::NEXT_STEP {
                trainer.step = t.int64_value(&[0]) as u64;
            } else if name == checkpoint_keys::NEXT_BATCH {
                next_batch = Some(t.int64_value(&[0]) as u64);
            }
        }
        // `python -m matseg.train` under torchrun trains several batches a
        // step; its runs say where the batch stream stopped.
        if let Some(batch) = next_batch.filter(|&b| b != trainer.step) {
            return Err(bad(format!(
                "the next batch is {batch}, not the next step {}: a run trained by several \
                 processes resumes with python -m matseg.train --resume",
                trainer.step
            )));
        }
        load_tensors(&trainer.vs, &model).map_err(|e| bad(e.to_string()))?;
        trainer
            .optimizer
            .load_state(&optim)
            .map_err(|e| bad(e.to_string()))?;
        Ok(trainer)
    }

    /// Learning rate at `step` ([`TrainOptions::lr_at`]).
    pub fn lr(&self, step: u64) -> f64 {
        self.config.options.lr_at(step)
    }

    /// One step on `samples`; the loss, or `None` for a skipped batch.
    pub fn train_step(&mut self, samples: &[TrainingSample]) -> Option<f64> {
        let batch = Batch::new(samples, self.vs.device());
        let descriptors = self.net.forward_t(&batch.images, true);
        self.update(matseg_loss(&descriptors, &batch.targets))
    }

    /// One step on cached samples: the net after its encoder, on the
    /// cached taps, with the loss on the stride-4 grid; the loss, or
    /// `None` for a skipped batch.
    pub fn train_step_cached(&mut self, samples: &[CachedSample]) -> Option<f64> {
        let batch = CachedBatch::new(samples, self.vs.device());
        let grid = self
            .net
            .coarse_from_taps(&batch.taps, Some(&batch.lab), true);
        self.update(matseg_loss(&l2_normalise(&grid, 1), &batch.targets))
    }

    /// One step on a prepared batch of either kind.
    pub fn step_on(&mut self, batch: &StepBatch) -> Option<f64> {
        match batch {
            StepBatch::Samples(samples) => self.train_step(samples),
            StepBatch::Features(samples) => self.train_step_cached(samples),
        }
    }

    /// Takes the step's update on `loss` (none for a skipped batch) and
    /// moves to the next step.
    fn update(&mut self, loss: Option<Tensor>) -> Option<f64> {
        let lr = self.lr(self.step);
        self.step += 1;
        let loss = loss?;
        self.optimizer.step(&loss, lr);
        Some(loss.double_value(&[]))
    }

    /// The loss on `samples` without training (inference-mode BatchNorm).
    pub fn evaluate(&self, samples: &[TrainingSample]) -> Option<f64> {
        let batch = Batch::new(samples, self.vs.device());
        tch::no_grad(|| {
            let descriptors = self.net.forward_t(&batch.images, false);
            matseg_loss(&descriptors, &batch.targets).map(|l| l.double_value(&[]))
        })
    }

    /// The net's variables on the CPU, sorted by name.
    fn weights_on_cpu(&self) -> Vec<(String, Tensor)> {
        let mut named: Vec<(String, Tensor)> = self
            .vs
            .variables()
            .into_iter()
            .map(|(n, t)| (n, t.to_device(Device::Cpu)))
            .collect();
        named.sort_by(|a, b| a.0.cmp(&b.0));
        named
    }

    /// Writes the net's weights alone to `path` (atomically), as
    /// `model.safetensors` holds them.
    pub fn save_weights(&self, path: &Path) -> Result<(), NetError> {
        write_tensors(path, &self.weights_on_cpu())
    }

    /// Writes `model.safetensors` and `checkpoint.safetensors` (atomically);
    /// the variables are copied to the CPU once for both.
    pub fn save(&self, dir: &Path) -> Result<(), NetError> {
        let on_cpu = |(n, t): (String, Tensor)| (n, t.to_device(Device::Cpu));
        let named = self.weights_on_cpu();
        write_tensors(&dir.join(MODEL_FILE), &named)?;
        let mut all: Vec<(String, Tensor)> = named
            .into_iter()
            .map(|(n, t)| (format!("{}{n}", checkpoint_keys::MODEL), t))
            .collect();
        all.extend(
            self.optimizer
                .state()
                .into_iter()
                .map(on_cpu)
                .map(|(n, t)| (format!("{}{n}", checkpoint_keys::OPTIMIZER), t)),
        );
        all.push((
            checkpoint_keys::NEXT_STEP.into(),
            Tensor::from_slice(&[self.step as i64]),
        ));
        write_tensors(&dir.join(CHECKPOINT_FILE), &all)
    }
}

pub use matseg_model::{MODEL_FILE, RUN_FILE};
/// The weights of the checkpoint that scored best on the point benchmark
/// (`--val-points`), written whenever a checkpoint beats the best so far.
pub const BEST_MODEL_FILE: &str = "best.safetensors";
/// Everything a resume needs.
pub const CHECKPOINT_FILE: &str = "checkpoint.safetensors";
/// One JSON line per step.
pub const METRICS_FILE: &str = "metrics.jsonl";
/// The loss curve.
pub const PLOT_FILE: &str = "loss.png";

/// Reads `dir/run.json`.
pub fn read_run_config(dir: &Path) -> Result<RunConfig, NetError> {
    let path = dir.join(RUN_FILE);
    let bad = |message: String| NetError::File {
        file: path.display().to_string(),
        message,
    };
    let text = std::fs::read_to_string(&path).map_err(|e| bad(format!("cannot read: {e}")))?;
    serde_json::from_str(&text).map_err(|e| bad(format!("not a run config: {e}")))
}

/// Writes `dir/run.json` (atomically).
pub fn write_run_config(dir: &Path, config: &RunConfig) -> Result<(), NetError> {
    let path = dir.join(RUN_FILE);
    let text = serde_json::to_string_pretty(config).expect("serialisable");
    write_atomic(&path, text.as_bytes())
}

/// [`matseg_image::outputs::write_atomic`] with the error naming `path`.
pub(crate) fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), NetError> {
    matseg_image::outputs::write_atomic(path, bytes).map_err(|e| NetError::File {
        file: path.display().to_string(),
        message: format!("cannot write: {e}"),
    })
}

/// Writes CPU tensors to `path` through a temporary file.
fn write_tensors(path: &Path, named: &[(String, Tensor)]) -> Result<(), NetError> {
    let tmp = temporary_path(path);
    Tensor::write_safetensors(named, &tmp).map_err(torch_error(path))?;
    std::fs::rename(&tmp, path).map_err(|e| NetError::File {
        file: path.display().to_string(),
        message: format!("cannot write: {e}"),
    })
}

/// What a run trains on.
#[derive(Clone, Copy)]
pub enum TrainingData<'a> {
    /// Training samples, fitted and augmented into batches by the plan.
    Samples(&'a dyn SampleSource),
    /// A feature cache, epoch after epoch ([`epoch_indices`]).
    Features(&'a FeatureCache),
}

/// The batch of one step, as the loader threads prepare it.
pub enum StepBatch {
    /// Same-size training samples.
    Samples(Vec<TrainingSample>),
    /// Samples of a feature cache.
    Features(Vec<CachedSample>),
}

impl TrainingData<'_> {
    /// The batch of `step` under `options` (plan and seed).
    pub fn batch(&self, options: &TrainOptions, step: u64) -> Result<StepBatch, NetError> {
        match self {
            TrainingData::Samples(source) => Ok(StepBatch::Samples(batch_samples(
                *source,
                &options.plan,
                options.seed,
                step,
            )?)),
            TrainingData::Features(cache) => {
                cached_batch(cache, &options.plan, options.seed, step).map(StepBatch::Features)
            }
        }
    }

    /// Image (width, height) in pixels of `batch`, which this data made.
    fn size(&self, batch: &StepBatch) -> (usize, usize) {
        match (self, batch) {
            (_, StepBatch::Samples(s)) => (s[0].width, s[0].height),
            (TrainingData::Features(cache), StepBatch::Features(_)) => {
                (cache.manifest.width, cache.manifest.height)
            }
            (TrainingData::Samples(_), StepBatch::Features(_)) => {
                unreachable!("samples make sample batches")
            }
        }
    }
}

/// The samples of batch `step` from a feature cache: as many as `plan`
/// puts in a batch of the cache's size, in the epochs' order of `seed`
/// ([`epoch_indices`]).
pub fn cached_batch(
    cache: &FeatureCache,
    plan: &BatchPlan,
    seed: u64,
    step: u64,
) -> Result<Vec<CachedSample>, NetError> {
    let m = &cache.manifest;
    let images = plan.images(m.width, m.height);
    epoch_indices(cache.len(), images, seed, step)
        .into_iter()
        .map(|i| cache.get(i))
        .collect()
}

impl StepBatch {
    /// Images in the batch.
    pub fn images(&self) -> usize {
        match self {
            StepBatch::Samples(s) => s.len(),
            StepBatch::Features(s) => s.len(),
        }
    }
}

/// Trains `trainer` on `data` until `options.steps`, writing into `dir`;
/// `progress(step, loss)` is called after every step. Batches are prepared
/// ahead in `loader_threads` background threads (the same batches whatever
/// their number: [`BatchLoader`]).
pub fn run(
    trainer: &mut Trainer,
    data: TrainingData,
    validation: Validation,
    dir: &Path,
    loader_threads: usize,
    mut progress: impl FnMut(&StepMetrics),
) -> Result<(), NetError> {
    let options = trainer.config.options.clone();
    let metrics_path = dir.join(METRICS_FILE);
    let mut history = read_metrics(&metrics_path, trainer.step);
    let mut log = rewrite_metrics(&metrics_path, &history)?;
    let validation_sets: Vec<Vec<TrainingSample>> = match validation.samples {
        Some(v) => (0..options.validation_batches)
            .map(|i| batch_samples(v, &options.plan, options.seed ^ VALIDATION_SEED, i))
            .collect::<Result<_, _>>()?,
        None => Vec::new(),
    };
    let make = |step| data.batch(&options, step);
    std::thread::scope(|scope| -> Result<(), NetError> {
        let loader =
            BatchLoader::spawn(scope, &make, (trainer.step, options.steps), loader_threads);
        while trainer.step < options.steps {
            let step = trainer.step;
            let started = Instant::now();
            let batch = loader.batch(step)?;
            let data_seconds = started.elapsed().as_secs_f64();
            let lr = trainer.lr(step);
            let loss = trainer.step_on(&batch);
            let (width, height) = data.size(&batch);
            let seconds = started.elapsed().as_secs_f64();
            let checkpoint = trainer.step.is_multiple_of(options.checkpoint_every.max(1))
                || trainer.step == options.steps;
            let val_points = match validation.points.filter(|_| checkpoint) {
                Some(score) => Some(score(trainer)?),
                None => None,
            };
            let validation = (checkpoint && !validation_sets.is_empty()).then(|| {
                let losses: Vec<f64> = validation_sets
                    .iter()
                    .filter_map(|b| trainer.evaluate(b))
                    .collect();
                losses.iter().sum::<f64>() / losses.len().max(1) as f64
            });
            let metrics = StepMetrics {
                step,
                loss,
                lr,
                images: batch.images(),
                width,
                height,
                seconds,
                data_seconds,
                validation,
                val_points,
            };
            writeln!(
                log,
                "{}",
                serde_json::to_string(&metrics).expect("serialisable")
            )
            .map_err(|e| NetError::File {
                file: metrics_path.display().to_string(),
                message: format!("cannot write: {e}"),
            })?;
            progress(&metrics);
            let best_so_far = history
                .iter()
                .filter_map(|m| m.val_points)
                .fold(f64::NEG_INFINITY, f64::max);
            history.push(metrics);
            if checkpoint {
                log.flush().ok();
                trainer.save(dir)?;
                if val_points.is_some_and(|v| v > best_so_far) {
                    trainer.save_weights(&dir.join(BEST_MODEL_FILE))?;
                }
                plot_losses(&history, &dir.join(PLOT_FILE))?;
            }
        }
        Ok(())
    })
}

/// The metrics of steps before `next_step` from a run's log (lines that
/// do not parse are left out).
pub fn read_metrics(path: &Path, next_step: u64) -> Vec<StepMetrics> {
    std::fs::read_to_string(path)
        .unwrap_or_default()
        .lines()
        .filter_map(|l| serde_json::from_str::<StepMetrics>(l).ok())
        .filter(|m| m.step < next_step)
        .collect()
}

/// Rewrites the log with `history` (dropping steps after the checkpoint a
/// run resumes from) and opens it for appending.
fn rewrite_metrics(path: &Path, history: &[StepMetrics]) -> Result<std::fs::File, NetError> {
    let text: String = history
        .iter()
        .map(|m| serde_json::to_string(m).expect("serialisable") + "\n")
        .collect();
    write_atomic(path, text.as_bytes())?;
    std::fs::OpenOptions::new()
        .append(true)
        .open(path)
        .map_err(|e| NetError::File {
            file: path.display().to_string(),
            message: format!("cannot open: {e}"),
        })
}
