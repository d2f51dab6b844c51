//! `matseg train`: trains the material-descriptor net (pipeline.md §8) from a
//! dataset or straight from the 2D generator, into a run folder that
//! `--resume` continues exactly.

use crate::common::LibraryArgs;
use crate::net_args::parse_device;
use crate::training::train_with_bar;
use anyhow::{bail, Result};
use matseg_net::data::BatchPlan;
use matseg_net::train::{self, LrScale};
use matseg_pipeline::train::{resume, start, MixIn, TrainConfig, TrainData, TrainInputs};
use std::path::PathBuf;

/// Arguments of `matseg train`.
#[derive(clap::Args)]
pub struct Args {
    /// Train from this dataset (MatSeg folders or WebDataset shards).
    #[arg(long, conflicts_with_all = ["online", "features"])]
    data: Option<PathBuf>,
    /// Train on this feature cache (`matseg features`): the encoder stays
    /// frozen and the rest of the net trains on its cached taps, with the
    /// loss on the stride-4 grid, epoch after epoch.
    #[arg(long, value_name = "CACHE", conflicts_with_all = ["online", "mix_data"])]
    features: Option<PathBuf>,
    /// Train straight from the 2D generator (bundled assets unless
    /// --sources/--textures), with no disk in between.
    #[arg(long)]
    online: bool,
    /// A stored dataset (e.g. `matseg generate --kind 3d` renders) mixed
    /// into the training data, --mix-fraction of the samples.
    #[arg(long, value_name = "DIR")]
    mix_data: Option<PathBuf>,
    /// At inference (validation, eval, segment), describe photos at this
    /// longer side at most; stored in run.json as inference_side. Several
    /// sides (`320,256`) average the descriptors of each (the first sets
    /// the grid).
    #[arg(long, value_name = "PIXELS", value_delimiter = ',')]
    inference_side: Vec<u32>,
    /// The share of samples taken from --mix-data.
    #[arg(long, default_value_t = TrainConfig::MIX_FRACTION, requires = "mix_data")]
    mix_fraction: f64,
    #[command(flatten)]
    libraries: LibraryArgs,
    /// Encoder: mobilenet-v2, convnext-tiny or convnext-base.
    #[arg(long, default_value = TrainConfig::ENCODER)]
    encoder: String,
    /// Let the encoder's own features at strides 4, 8 and 16 join the
    /// learned descriptor (with learned weights): from the ImageNet
    /// encoder, the net starts out from the `imagenet` baseline's features.
    #[arg(long)]
    encoder_features: bool,
    /// Let each stride-4 cell's mean colour join the descriptor as a
    /// learned Gaussian kernel of L*a*b* distance (random Fourier
    /// features) with a learned weight. With --init from a run trained
    /// without it, the colour part starts fresh.
    #[arg(long)]
    colour_features: bool,
    /// Initial weights: imagenet (the MobileNetV2 encoder's, from the
    /// registry), scratch, default (the shipped model), a safetensors file
    /// with the encoder's standard names, or a whole net's weights of the
    /// same shape (a run's model.safetensors or best.safetensors, or its
    /// folder) to continue from; with --features, the cache's model unless
    /// given (which must be the same encoder). Default: imagenet.
    #[arg(long)]
    init: Option<String>,
    /// cpu, cuda or cuda:N.
    #[arg(long, default_value = "cpu")]
    device: String,
    /// Steps (batches) in all.
    #[arg(long, default_value_t = TrainConfig::STEPS)]
    steps: u64,
    /// Peak learning rate (default: 1e-5 from ImageNet weights, 1e-4 from
    /// scratch).
    #[arg(long)]
    lr: Option<f64>,
    /// Warm-up steps.
    #[arg(long, default_value_t = train::WARMUP_STEPS)]
    warmup: u64,
    /// Let the learning rate fall linearly towards 0 over the last this
    /// many steps (0: constant after the warm-up).
    #[arg(long, default_value_t = 0)]
    decay: u64,
    /// `PREFIX=SCALE`: multiply the learning rate of the variables whose
    /// names start with PREFIX by SCALE (0 freezes them); repeatable, a
    /// later one wins where both apply. E.g. `encoder.=0.1` (an ImageNet
    /// encoder learning ten times slower than the head) or
    /// `encoder.features.0.=0`.
    #[arg(long = "lr-scale", value_name = "PREFIX=SCALE", value_parser = parse_lr_scale)]
    lr_scales: Vec<LrScale>,
    /// Smallest batch side (multiple of 32).
    #[arg(long, default_value_t = BatchPlan::SPEC.min_side)]
    min_side: usize,
    /// Largest batch side (multiple of 32).
    #[arg(long, default_value_t = BatchPlan::SPEC.max_side)]
    max_side: usize,
    /// Pixels per batch to aim at.
    #[arg(long, default_value_t = BatchPlan::SPEC.pixels)]
    batch_pixels: usize,
    /// Steps between checkpoints and validations.
    #[arg(long, default_value_t = TrainConfig::CHECKPOINT_EVERY)]
    checkpoint_every: u64,
    /// Held-out generated batches per validation (0: none).
    #[arg(long, default_value_t = TrainConfig::VALIDATION_BATCHES)]
    validation_batches: u64,
    /// A point benchmark (MatSeg format) to score the net on at each
    /// checkpoint: triplet accuracy (All, by material) in the metrics log
    /// as `val_points`.
    #[arg(long, value_name = "BENCH_DIR")]
    val_points: Option<PathBuf>,
    /// Longer side of the --val-points images, in pixels (0: as they are).
    #[arg(long, default_value_t = matseg_eval::evaluate::DEFAULT_MAX_SIDE)]
    val_max_side: u32,
    /// Threads preparing batches ahead (default: 1 on the CPU, all cores
    /// but two with --device cuda); the batches do not depend on it.
    #[arg(long)]
    loader_threads: Option<usize>,
    /// Seed of the batch stream and of the generator.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// The run folder: a new or empty one (docs/outputs.md).
    #[arg(long, required_unless_present = "resume")]
    out: Option<PathBuf>,
    /// Continue the run in this folder from its last checkpoint.
    #[arg(long, conflicts_with_all = ["out", "encoder", "init", "lr_scales", "encoder_features", "colour_features", "mix_data", "inference_side", "features"])]
    resume: Option<PathBuf>,
}

fn parse_lr_scale(s: &str) -> Result<LrScale, String> {
    let (prefix, scale) = s
        .split_once('=')
        .ok_or_else(|| format!("{s}: expected PREFIX=SCALE"))?;
    let scale: f64 = scale
        .parse()
        .ok()
        .filter(|v: &f64| v.is_finite() && *v >= 0.0)
        .ok_or_else(|| format!("{s}: SCALE must be a number >= 0"))?;
    Ok(LrScale {
        prefix: prefix.to_string(),
        scale,
    })
}

/// Runs `matseg train`.
pub fn run(args: Args) -> Result<()> {
    let device = parse_device(&args.device)?;
    let mut run = match &args.resume {
        Some(dir) => resume(dir, device)?,
        None => start(&config(&args)?, device)?,
    };
    if let Some(loaded) = run.initial_weights() {
        eprintln!("{loaded}");
    }
    // One scan of the libraries serves the online source and validation.
    let libraries = args.libraries.load(1024)?;
    let inputs = TrainInputs {
        libraries: &libraries,
        val_points: args.val_points.as_deref(),
        val_max_side: args.val_max_side,
        loader_threads: args.loader_threads,
    };
    train_with_bar(&mut run, &inputs, &args.device)
}

/// The new run's configuration the arguments describe.
fn config(args: &Args) -> Result<TrainConfig> {
    let out = args
        .out
        .clone()
        .expect("clap requires --out without --resume");
    let data = match (&args.data, &args.features, args.online) {
        (Some(path), None, false) => TrainData::Dataset(path.clone()),
        (None, Some(cache), false) => TrainData::Features(cache.clone()),
        (None, None, true) => TrainData::Online,
        _ => bail!("give --data DIR, --features CACHE or --online"),
    };
    let defaults = TrainConfig::new(out, data);
    Ok(TrainConfig {
        mix: args.mix_data.as_ref().map(|dir| MixIn {
            data: dir.clone(),
            fraction: args.mix_fraction,
        }),
        encoder: args.encoder.clone(),
        encoder_features: args.encoder_features,
        colour_features: args.colour_features,
        init: args.init.clone().unwrap_or(defaults.init.clone()),
        steps: args.steps,
        lr: args.lr,
        warmup: args.warmup,
        decay: args.decay,
        lr_scales: args.lr_scales.clone(),
        plan: BatchPlan {
            min_side: args.min_side,
            max_side: args.max_side,
            pixels: args.batch_pixels,
            ..BatchPlan::SPEC
        },
        checkpoint_every: args.checkpoint_every,
        validation_batches: args.validation_batches,
        seed: args.seed,
        inference_sides: args.inference_side.clone(),
        ..defaults
    })
}
