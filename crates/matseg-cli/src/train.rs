//! `matseg train`: trains the material-descriptor net (pipeline.md §8) from a
//! dataset or straight from the 2D generator, into a run folder that
//! `--resume` continues exactly.

use crate::common::{load_libraries, LicenceArgs};
use crate::net_args::{parse_device, preset};
use crate::weights::{fetched, ArchArg};
use anyhow::{bail, Context, Result};
use indicatif::{ProgressBar, ProgressStyle};
use matseg_data::Dataset;
use matseg_eval::{evaluate_points, load_point_benchmark};
use matseg_net::colour::COLOUR_PART;
use matseg_net::data::{BatchPlan, DatasetSource, GeneratorSource, MixedSource, SampleSource};
use matseg_net::infer::{NetModel, TrainedNet};
use matseg_net::loader::default_workers;
use matseg_net::train::{
    self, LrScale, Mix, NetScore, RunConfig, TrainOptions, Trainer, Validation,
};
use matseg_net::{load_named, load_net_adding, EncoderConfig, NetConfig};
use matseg_pipeline::sources::Defaults;
use matseg_scene::Recipe2d;
use matseg_weights::read_safetensors;
use std::path::{Path, PathBuf};
use std::time::Instant;
use tch::Device;

/// Arguments of `matseg train`.
#[derive(clap::Args)]
pub struct Args {
    /// Train from this dataset (MatSeg folders or WebDataset shards).
    #[arg(long, conflicts_with = "online")]
    data: Option<PathBuf>,
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
    #[arg(long, default_value_t = 0.3, requires = "mix_data")]
    mix_fraction: f64,
    /// Photo folders for --online; default: the fetched corpus, else bundled assets.
    #[arg(long, num_args = 1..)]
    sources: Vec<PathBuf>,
    /// Texture folders for --online; default: the fetched corpus, else bundled assets.
    #[arg(long, num_args = 1..)]
    textures: Vec<PathBuf>,
    #[command(flatten)]
    licences: LicenceArgs,
    /// Encoder: mobilenet-v2, convnext-tiny or convnext-base.
    #[arg(long, default_value = "mobilenet-v2")]
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
    /// registry), scratch, a safetensors file with the encoder's standard
    /// names, or a whole net's weights of the same shape (a run's
    /// model.safetensors or best.safetensors) to continue from.
    #[arg(long, default_value = "imagenet")]
    init: String,
    /// cpu or cuda.
    #[arg(long, default_value = "cpu")]
    device: String,
    /// Steps (batches) in all.
    #[arg(long, default_value_t = 10_000)]
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
    #[arg(long, default_value_t = 500)]
    checkpoint_every: u64,
    /// Held-out generated batches per validation (0: none).
    #[arg(long, default_value_t = 4)]
    validation_batches: u64,
    /// A point benchmark (MatSeg format) to score the net on at each
    /// checkpoint: triplet accuracy (All, by material) in the metrics log
    /// as `val_points`.
    #[arg(long, value_name = "BENCH_DIR")]
    val_points: Option<PathBuf>,
    /// Longer side of the --val-points images, in pixels (0: as they are).
    #[arg(long, default_value_t = 700)]
    val_max_side: u32,
    /// Threads preparing batches ahead (default: 1 on the CPU, all cores
    /// but two with --device cuda); the batches do not depend on it.
    #[arg(long)]
    loader_threads: Option<usize>,
    /// Seed of the batch stream and of the generator.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// The run folder.
    #[arg(long, required_unless_present = "resume")]
    out: Option<PathBuf>,
    /// Continue the run in this folder from its last checkpoint.
    #[arg(long, conflicts_with_all = ["out", "encoder", "init", "lr_scales", "encoder_features", "colour_features", "mix_data", "inference_side"])]
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
    let (mut trainer, dir) = match &args.resume {
        Some(dir) => (Trainer::resume(dir, device)?, dir.clone()),
        None => start(&args, device)?,
    };
    let config = trainer.config.clone();
    // One scan of the libraries serves the online source and validation.
    let libraries = load_libraries(
        &args.sources,
        &args.textures,
        1024,
        Defaults::CorpusOrBundled,
        &args.licences.filter()?,
    )?;
    let generator = |seed| GeneratorSource {
        sources: libraries.sources(),
        recipe: Recipe2d::default(),
        seed,
    };
    let main: Box<dyn SampleSource + '_> = if config.data == ONLINE {
        Box::new(generator(config.options.seed))
    } else {
        Box::new(dataset_source(&config.data)?)
    };
    let mixed_in = match &config.mix {
        Some(mix) => Some((dataset_source(&mix.data)?, mix.fraction)),
        None => None,
    };
    let mixture = mixed_in.as_ref().map(|(other, fraction)| MixedSource {
        main: main.as_ref(),
        other,
        fraction: *fraction,
    });
    let source: &dyn SampleSource = match &mixture {
        Some(mixture) => mixture,
        None => main.as_ref(),
    };
    let held_out = generator(config.options.seed ^ VALIDATION_GENERATOR_SEED);
    let bench = match &args.val_points {
        Some(dir) => Some(load_point_benchmark(dir, false)?),
        None => None,
    };
    let score_points = |trainer: &Trainer| -> Result<f64, String> {
        let bench = bench.as_ref().expect("only called with a benchmark");
        let net = TrainedNet::snapshot(trainer).map_err(|e| e.to_string())?;
        let report = evaluate_points(&NetModel::new("net", net), bench, args.val_max_side)
            .map_err(|e| e.to_string())?;
        report
            .all_by_material
            .ok_or_else(|| "--val-points: the benchmark has no triplets".to_string())
    };
    let validation = Validation {
        samples: Some(&held_out),
        points: bench.is_some().then_some(&score_points as NetScore),
    };
    let bar = ProgressBar::new(config.options.steps).with_style(
        ProgressStyle::with_template("{bar:40} {pos}/{len} steps {per_sec} ETA {eta} {msg}")
            .expect("template"),
    );
    bar.set_position(trainer.step);
    let mut recent: Vec<f64> = Vec::new();
    let loader_threads = args
        .loader_threads
        .unwrap_or_else(|| default_workers(device.is_cuda()));
    if device.is_cuda() {
        // On a GPU the trainer's CPU work is converting each batch: one
        // libtorch thread, so that its thread pool does not fight the
        // loader threads for the cores (which made steps 10x slower).
        tch::set_num_threads(1);
    }
    let (first_step, started) = (trainer.step, Instant::now());
    let (mut images, mut pixels, mut waited) = (0usize, 0usize, 0.0);
    train::run(
        &mut trainer,
        source,
        validation,
        &dir,
        loader_threads,
        |m| {
            images += m.images;
            pixels += m.images * m.width * m.height;
            waited += m.data_seconds;
            if let Some(l) = m.loss {
                recent.push(l);
            }
            let tail = &recent[recent.len().saturating_sub(20)..];
            let mean = tail.iter().sum::<f64>() / tail.len().max(1) as f64;
            let val = m
                .validation
                .map(|v| format!(" val {v:.4}"))
                .unwrap_or_default();
            let points = m
                .val_points
                .map(|v| format!(" points {v:.4}"))
                .unwrap_or_default();
            bar.set_message(format!("loss {mean:.4}{val}{points}"));
            bar.inc(1);
        },
    )?;
    bar.finish();
    let seconds = started.elapsed().as_secs_f64();
    println!(
        "{}: {} steps; model {}",
        dir.display(),
        trainer.step,
        dir.join(train::MODEL_FILE).display()
    );
    println!(
        "{} steps in {seconds:.1} s on {}: {:.1} images/s, {:.2} Mpixel/s (checkpoints and validation included); \
         {waited:.1} s waiting for batches from {loader_threads} loader thread(s)",
        trainer.step - first_step,
        args.device,
        images as f64 / seconds,
        pixels as f64 / seconds / 1e6
    );
    Ok(())
}

/// A new run: its folder, config and initial weights.
fn start(args: &Args, device: Device) -> Result<(Trainer, PathBuf)> {
    let dir = args
        .out
        .clone()
        .expect("clap requires --out without --resume");
    if dir.join(train::RUN_FILE).exists() {
        bail!(
            "{}: already holds a run; continue it with --resume {0}, or choose another --out",
            dir.display()
        );
    }
    let net = NetConfig {
        encoder_features: args.encoder_features,
        colour_features: args.colour_features,
        ..preset(&args.encoder)?
    };
    let data = match (&args.data, args.online) {
        (Some(path), false) => path.display().to_string(),
        (None, true) => ONLINE.to_string(),
        _ => bail!("give --data DIR or --online"),
    };
    let pretrained = args.init != "scratch";
    let options = TrainOptions {
        steps: args.steps,
        lr: args.lr.unwrap_or(if pretrained {
            train::LR_PRETRAINED
        } else {
            train::LR_SCRATCH
        }),
        warmup: args.warmup,
        decay: args.decay,
        weight_decay: 4e-5,
        plan: BatchPlan {
            min_side: args.min_side,
            max_side: args.max_side,
            pixels: args.batch_pixels,
            ..BatchPlan::SPEC
        },
        seed: args.seed,
        checkpoint_every: args.checkpoint_every,
        validation_batches: args.validation_batches,
        lr_scales: args.lr_scales.clone(),
    };
    options.plan.validate().map_err(anyhow::Error::msg)?;
    if !(0.0..=1.0).contains(&args.mix_fraction) {
        bail!("--mix-fraction {}: expected 0..1", args.mix_fraction);
    }
    let config = RunConfig {
        net,
        options,
        init: args.init.clone(),
        data,
        mix: args.mix_data.as_ref().map(|dir| Mix {
            data: dir.display().to_string(),
            fraction: args.mix_fraction,
        }),
        inference_side: args.inference_side.first().copied(),
        extra_inference_sides: args.inference_side.iter().skip(1).copied().collect(),
    };
    let trainer = Trainer::new(config, device);
    for group in &args.lr_scales {
        if !trainer
            .vs
            .variables()
            .keys()
            .any(|n| n.starts_with(&group.prefix))
        {
            bail!(
                "--lr-scale {}={}: no variable of the {} net starts with {:?}",
                group.prefix,
                group.scale,
                args.encoder,
                group.prefix
            );
        }
    }
    init_encoder(&trainer, &args.init)?;
    std::fs::create_dir_all(&dir).with_context(|| format!("{}: cannot create", dir.display()))?;
    train::write_run_config(&dir, &trainer.config)?;
    Ok((trainer, dir))
}

/// What `run.json` records as the data of an online run.
const ONLINE: &str = "online";

/// Loads the encoder's initial weights.
fn init_encoder(trainer: &Trainer, init: &str) -> Result<()> {
    let path = match init {
        "scratch" => return Ok(()),
        "imagenet" => {
            if trainer.config.net.encoder != EncoderConfig::MobilenetV2 {
                bail!("--init imagenet: the registry has ImageNet weights for mobilenet-v2 only; give a safetensors file for ConvNeXt, or --init scratch");
            }
            fetched(ArchArg::MobilenetV2, None)?.0
        }
        file => PathBuf::from(file),
    };
    let label = path.display().to_string();
    let bytes = std::fs::read(&path).with_context(|| format!("{label}: cannot read"))?;
    let tensors = read_safetensors(&bytes, &label)?;
    // A whole net's weights (a run's model.safetensors or best.safetensors)
    // carry the net's own names; an encoder's, the encoder's standard ones.
    let whole_net = tensors.iter().any(|t| t.name.starts_with("encoder."));
    if whole_net {
        let (copied, fresh) = load_net_adding(&trainer.vs, &tensors, COLOUR_PART, &label)?;
        let fresh = match fresh {
            0 => String::new(),
            n => format!(" ({n} of a new colour part start fresh)"),
        };
        eprintln!("net: {copied} tensors from {label}{fresh}");
    } else {
        let copied = load_named(&trainer.vs, "encoder", &tensors, &label)?;
        eprintln!("encoder: {copied} tensors from {label}");
    }
    Ok(())
}

/// Validation scenes come from the generator under this seed offset, apart
/// from the online training scenes.
const VALIDATION_GENERATOR_SEED: u64 = 0x5eed;

/// The dataset `run.json`'s `data` names.
fn dataset_source(data: &str) -> Result<DatasetSource> {
    let dataset = Dataset::open(Path::new(data))?;
    if dataset.is_empty() {
        bail!("{data}: no complete samples");
    }
    Ok(DatasetSource(dataset))
}
