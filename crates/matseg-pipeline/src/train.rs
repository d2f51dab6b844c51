//! Training the material-descriptor net (pipeline.md §8): a run is
//! started from a [`TrainConfig`] ([`start`]) or continued from its folder
//! ([`resume`]), then trained with [`TrainingRun::train`], which reports
//! each step to a callback. The run folder (`run.json`, checkpoints, the
//! metrics log) makes a resumed run continue exactly where it stopped.

use crate::error::PipelineError;
use crate::files::create_folder;
use crate::nets::point_score;
use crate::sources::Libraries;
use crate::weights::{imagenet_weights, read_weights};
use matseg_data::Dataset;
use matseg_eval::load_point_benchmark;
use matseg_image::outputs::{Layout, SharedFolder, Sign};
use matseg_net::colour::COLOUR_PART;
use matseg_net::data::{BatchPlan, DatasetSource, GeneratorSource, MixedSource, SampleSource};
use matseg_net::features::{encoder_digest, CacheManifest, FeatureCache};
use matseg_net::infer::{resolve_model, run_files, NetModel, TrainedNet, DEFAULT_MODEL};
use matseg_net::loader::default_workers;
use matseg_net::train::{
    self, CachedFeatures, LrScale, Mix, NetScore, RunConfig, StepMetrics, TrainOptions, Trainer,
    TrainingData, Validation,
};
use matseg_net::{load_named, load_net_adding, EncoderConfig, NetConfig, NetError, PRESETS};
use matseg_scene::Recipe2d;
use matseg_weights::Arch;
use std::path::{Path, PathBuf};
use std::time::Instant;

pub use crate::train_summary::TrainSummary;
use matseg_image::device::ComputeDevice;
use matseg_net::torch_device;

/// Where a new run's training samples come from.
#[derive(Clone, Debug, PartialEq)]
pub enum TrainData {
    /// Scenes from the 2D generator, made as they are needed (no disk).
    Online,
    /// A stored dataset: MatSeg folders or WebDataset shards.
    Dataset(PathBuf),
    /// A feature cache made by [`crate::features::make_features`]: the
    /// encoder stays frozen (it made the cache), the rest of the net trains
    /// on the cached taps with the loss on the stride-4 grid.
    Features(PathBuf),
}

/// A stored dataset mixed into the training data.
#[derive(Clone, Debug, PartialEq)]
pub struct MixIn {
    /// The dataset (e.g. 3D renders).
    pub data: PathBuf,
    /// The share of samples taken from it, in 0..=1.
    pub fraction: f64,
}

impl MixIn {
    /// Checks the share (`mix fraction`, in 0..=1).
    pub fn validate(&self) -> Result<(), PipelineError> {
        MixedSource::check_fraction(self.fraction)
            .map_err(|e| PipelineError::setting("mix fraction", Some(self.fraction), e.to_string()))
    }
}

/// Everything a new run is made from; [`TrainConfig::new`] gives the
/// defaults of `matseg train`.
#[derive(Clone, Debug, PartialEq)]
pub struct TrainConfig {
    /// The run folder (must not hold a run yet).
    pub out: PathBuf,
    /// The training samples.
    pub data: TrainData,
    /// A second dataset mixed in.
    pub mix: Option<MixIn>,
    /// The encoder preset: one of [`PRESETS`].
    pub encoder: String,
    /// The encoder's own stride-4, 8 and 16 features join the descriptor.
    pub encoder_features: bool,
    /// Each stride-4 cell's mean colour joins the descriptor.
    pub colour_features: bool,
    /// Initial weights: `imagenet` (the registry's MobileNetV2 encoder),
    /// `scratch`, `default` (the shipped model), an encoder's safetensors
    /// file with its standard names, a whole net's weights of the same
    /// shape or a run folder to continue from, or [`TrainConfig::CACHE_INIT`].
    pub init: String,
    /// Steps (batches) in all.
    pub steps: u64,
    /// Peak learning rate; `None`: [`train::LR_PRETRAINED`] from trained
    /// weights, [`train::LR_SCRATCH`] from scratch.
    pub lr: Option<f64>,
    /// Warm-up steps.
    pub warmup: u64,
    /// The learning rate falls linearly towards 0 over the last this many
    /// steps (0: constant after the warm-up).
    pub decay: u64,
    /// Learning-rate factors of groups of variables.
    pub lr_scales: Vec<LrScale>,
    /// Batch sizes and augmentation.
    pub plan: BatchPlan,
    /// Steps between checkpoints and validations.
    pub checkpoint_every: u64,
    /// Held-out generated batches per validation (0: none).
    pub validation_batches: u64,
    /// Seed of the batch stream and of the generator.
    pub seed: u64,
    /// Longer sides photos are described at, at inference (empty: at their
    /// own size; several: their descriptors averaged, the first sets the
    /// grid).
    pub inference_sides: Vec<u32>,
}

impl TrainConfig {
    /// Default steps of a run.
    pub const STEPS: u64 = 10_000;
    /// Default steps between checkpoints.
    pub const CHECKPOINT_EVERY: u64 = 500;
    /// Default held-out batches per validation.
    pub const VALIDATION_BATCHES: u64 = 4;
    /// Default share of a mixed-in dataset.
    pub const MIX_FRACTION: f64 = 0.3;
    /// Default encoder preset.
    pub const ENCODER: &'static str = "mobilenet-v2";
    /// Default initial weights.
    pub const INIT: &'static str = "imagenet";
    /// Initial weights of a run on a feature cache: the model the cache's
    /// encoder came from (the default of [`TrainData::Features`] runs).
    pub const CACHE_INIT: &'static str = "cache";
    /// Weight decay of every run.
    pub const WEIGHT_DECAY: f64 = 4e-5;

    /// A run into `out` from `data` with `matseg train`'s defaults.
    pub fn new(out: impl Into<PathBuf>, data: TrainData) -> Self {
        Self {
            out: out.into(),
            mix: None,
            encoder: Self::ENCODER.to_string(),
            encoder_features: false,
            colour_features: false,
            init: match data {
                TrainData::Features(_) => Self::CACHE_INIT,
                _ => Self::INIT,
            }
            .to_string(),
            steps: Self::STEPS,
            lr: None,
            warmup: train::WARMUP_STEPS,
            decay: 0,
            lr_scales: Vec::new(),
            plan: BatchPlan::SPEC,
            checkpoint_every: Self::CHECKPOINT_EVERY,
            validation_batches: Self::VALIDATION_BATCHES,
            seed: 0,
            inference_sides: Vec::new(),
            data,
        }
    }

    /// The `run.json` this configuration makes, checked.
    fn run_config(&self) -> Result<RunConfig, PipelineError> {
        let net = NetConfig {
            encoder_features: self.encoder_features,
            colour_features: self.colour_features,
            ..NetConfig::preset(&self.encoder).ok_or_else(|| {
                PipelineError::setting(
                    "encoder",
                    Some(&self.encoder),
                    format!("expected one of {}", PRESETS.join(", ")),
                )
            })?
        };
        let pretrained = self.init != "scratch";
        let features = match &self.data {
            TrainData::Features(dir) => Some(CachedFeatures {
                cache: dir.display().to_string(),
                manifest: CacheManifest::read(dir)?,
            }),
            _ => None,
        };
        let mut plan = self.plan;
        let mut lr_scales = self.lr_scales.clone();
        if let Some(cached) = &features {
            if self.mix.is_some() {
                return Err(PipelineError::Settings(
                    "a run on a feature cache takes its data from the cache: mix datasets in \
                     when making the cache"
                        .into(),
                ));
            }
            // The batches are the cache's samples; the plan keeps their
            // size (for the held-out batches too) and how many make one.
            let m = &cached.manifest;
            plan.min_side = m.width.min(m.height);
            plan.max_side = m.width.max(m.height);
            // The encoder made the cache: it stays as it is.
            lr_scales.push(LrScale {
                prefix: ENCODER_PREFIX.into(),
                scale: 0.0,
            });
        }
        let options = TrainOptions {
            steps: self.steps,
            lr: self.lr.unwrap_or(if pretrained {
                train::LR_PRETRAINED
            } else {
                train::LR_SCRATCH
            }),
            warmup: self.warmup,
            decay: self.decay,
            weight_decay: Self::WEIGHT_DECAY,
            plan,
            seed: self.seed,
            checkpoint_every: self.checkpoint_every,
            validation_batches: self.validation_batches,
            lr_scales,
        };
        options
            .plan
            .validate()
            .map_err(|e| PipelineError::Settings(e.0))?;
        if let Some(mix) = &self.mix {
            mix.validate()?;
        }
        Ok(RunConfig {
            net,
            options,
            init: self.init.clone(),
            data: match (&self.data, &features) {
                (_, Some(cached)) => cached.manifest.data.clone(),
                (TrainData::Dataset(path), None) => path.display().to_string(),
                _ => ONLINE.to_string(),
            },
            mix: self.mix.as_ref().map(|m| Mix {
                data: m.data.display().to_string(),
                fraction: m.fraction,
            }),
            inference_side: self.inference_sides.first().copied(),
            extra_inference_sides: self.inference_sides.iter().skip(1).copied().collect(),
            features,
        })
    }
}

/// What `run.json` records as the data of an online run.
pub(crate) const ONLINE: &str = "online";

/// The start of the encoder's variable names.
const ENCODER_PREFIX: &str = "encoder.";

/// Validation scenes come from the generator under this seed offset, apart
/// from the online training scenes.
pub const VALIDATION_GENERATOR_SEED: u64 = 0x5eed;

/// A run being trained: its folder and its net, optimiser and step.
pub struct TrainingRun {
    trainer: Trainer,
    dir: PathBuf,
    initial_weights: Option<String>,
}

/// Starts a new run: checks `config`, makes the net on `device`, loads its
/// initial weights (fetching the ImageNet ones once when needed), and
/// writes the run folder's `run.json`.
pub fn start(config: &TrainConfig, device: ComputeDevice) -> Result<TrainingRun, PipelineError> {
    let dir = matseg_image::outputs::output_folder(&config.out)?;
    if dir.join(train::RUN_FILE).exists() {
        return Err(PipelineError::file(
            dir.display(),
            "already holds a run; resume it (matseg train --resume), or choose another folder",
        ));
    }
    // The run folder: new, or holding only what a run writes (a start
    // that failed), never overlapping what the run reads.
    let mut inputs: Vec<&Path> = config.mix.iter().map(|m| m.data.as_path()).collect();
    match &config.data {
        TrainData::Dataset(path) | TrainData::Features(path) => inputs.push(path),
        TrainData::Online => {}
    }
    let layout = Layout {
        command: "train",
        sign: Sign::Entries,
        owns: &is_run_entry,
    };
    SharedFolder::check(&dir, &layout, &inputs)?;
    // The datasets are checked before anything is loaded or written.
    let datasets = match &config.data {
        TrainData::Dataset(path) => vec![path],
        _ => Vec::new(),
    };
    for path in datasets
        .into_iter()
        .chain(config.mix.iter().map(|m| &m.data))
    {
        dataset_source(&path.display().to_string())?;
    }
    let trainer = Trainer::new(config.run_config()?, torch_device(device));
    for group in &config.lr_scales {
        if !trainer
            .vs
            .variables()
            .keys()
            .any(|n| n.starts_with(&group.prefix))
        {
            return Err(PipelineError::setting(
                "lr scale",
                Some(format!("{}={}", group.prefix, group.scale)),
                format!(
                    "no variable of the {} net starts with {:?}",
                    config.encoder, group.prefix
                ),
            ));
        }
    }
    let init = match (&trainer.config.features, config.init.as_str()) {
        (Some(cached), TrainConfig::CACHE_INIT) => cached.manifest.model.clone(),
        (None, TrainConfig::CACHE_INIT) => {
            return Err(PipelineError::setting(
                "init",
                Some(TrainConfig::CACHE_INIT),
                "names a feature cache's model, for runs on a feature cache",
            ))
        }
        (_, init) => init.to_string(),
    };
    let initial_weights = load_initial_weights(&trainer, &init)?;
    if let Some(cached) = &trainer.config.features {
        check_cache_encoder(&trainer, cached, &init)?;
    }
    create_folder(&dir)?;
    train::write_run_config(&dir, &trainer.config)?;
    Ok(TrainingRun {
        trainer,
        dir,
        initial_weights,
    })
}

/// Whether `path`, an entry of a run folder, is one a training run writes
/// (its settings, weights, checkpoint, metrics and plot, or one of them
/// being written).
fn is_run_entry(path: &Path) -> bool {
    let name = path.file_name().unwrap_or_default().to_string_lossy();
    let file = name.split(".tmp").next().unwrap_or_default();
    [
        train::RUN_FILE,
        train::MODEL_FILE,
        train::BEST_MODEL_FILE,
        train::CHECKPOINT_FILE,
        train::METRICS_FILE,
        train::PLOT_FILE,
    ]
    .contains(&file)
        && path.is_file()
}

/// Refuses a run whose net's encoder is not the one that made its cache.
fn check_cache_encoder(
    trainer: &Trainer,
    cached: &CachedFeatures,
    init: &str,
) -> Result<(), PipelineError> {
    let m = &cached.manifest;
    if trainer.config.net.encoder != m.encoder {
        return Err(PipelineError::file(
            format!("{}/{}", cached.cache, matseg_net::features::MANIFEST_FILE),
            format!(
                "made by another encoder ({:?}) than this run's ({:?})",
                m.encoder, trainer.config.net.encoder
            ),
        ));
    }
    if encoder_digest(&trainer.vs) != m.encoder_digest {
        return Err(PipelineError::file(
            format!("{}/{}", cached.cache, matseg_net::features::MANIFEST_FILE),
            format!(
                "made by the encoder of {}, whose weights differ from those of {init}:                  start from the cache's model (--init {})",
                m.model,
                TrainConfig::CACHE_INIT
            ),
        ));
    }
    Ok(())
}

/// Continues the run in `dir` from its last checkpoint, on `device`.
pub fn resume(dir: &Path, device: ComputeDevice) -> Result<TrainingRun, PipelineError> {
    Ok(TrainingRun {
        trainer: Trainer::resume(dir, torch_device(device))?,
        dir: dir.to_path_buf(),
        initial_weights: None,
    })
}

/// What a call of [`TrainingRun::train`] reads besides the run itself.
pub struct TrainInputs<'a> {
    /// The photo and texture libraries of the online generator and of the
    /// held-out validation scenes.
    pub libraries: &'a Libraries,
    /// A point benchmark (MatSeg layout) to score the net on at each
    /// checkpoint (`val_points` in the metrics log).
    pub val_points: Option<&'a Path>,
    /// Longer side of the benchmark's photos, in pixels (0: as they are).
    pub val_max_side: u32,
    /// Threads preparing batches ahead (`None`: one on the CPU, all cores
    /// but two on a GPU); the batches do not depend on it.
    pub loader_threads: Option<usize>,
}

impl<'a> TrainInputs<'a> {
    /// Inputs drawing online and validation scenes from `libraries`,
    /// with no point benchmark and the default loader threads.
    pub fn new(libraries: &'a Libraries) -> Self {
        Self {
            libraries,
            val_points: None,
            val_max_side: 0,
            loader_threads: None,
        }
    }
}

impl TrainingRun {
    /// The run folder.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// Steps trained so far.
    pub fn step(&self) -> u64 {
        self.trainer.step
    }

    /// The run's configuration (`run.json`).
    pub fn config(&self) -> &RunConfig {
        &self.trainer.config
    }

    /// The latest weights, for `matseg segment --model` and [`TrainedNet::load`].
    pub fn model_file(&self) -> PathBuf {
        self.dir.join(train::MODEL_FILE)
    }

    /// For a new run, where its initial weights came from (`net: N tensors
    /// from FILE`, `encoder: N tensors from FILE`); `None` from scratch or
    /// when resumed.
    pub fn initial_weights(&self) -> Option<&str> {
        self.initial_weights.as_deref()
    }

    /// Trains until the run's planned steps, checkpointing into the run
    /// folder; `on_step` gets each step's metrics (loss, learning rate,
    /// batch size, validation scores at checkpoints).
    pub fn train(
        &mut self,
        inputs: &TrainInputs,
        mut on_step: impl FnMut(&StepMetrics),
    ) -> Result<TrainSummary, PipelineError> {
        let config = self.trainer.config.clone();
        let device = self.trainer.vs.device();
        let generator = |seed| GeneratorSource {
            sources: inputs.libraries.sources(),
            recipe: Recipe2d::default(),
            seed,
        };
        let cache = match &config.features {
            Some(cached) => Some(open_cache(&self.trainer, cached)?),
            None => None,
        };
        let main: Box<dyn SampleSource + '_> = if config.data == ONLINE || cache.is_some() {
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
        let data = match (&cache, &mixture) {
            (Some(cache), _) => TrainingData::Features(cache),
            (None, Some(mixture)) => TrainingData::Samples(mixture),
            (None, None) => TrainingData::Samples(main.as_ref()),
        };
        let held_out = generator(config.options.seed ^ VALIDATION_GENERATOR_SEED);
        let bench = match inputs.val_points {
            Some(dir) => Some(load_point_benchmark(dir, false)?),
            None => None,
        };
        let score_points = |trainer: &Trainer| -> Result<f64, NetError> {
            let bench = bench.as_ref().expect("only called with a benchmark");
            let net = NetModel::new("net", TrainedNet::snapshot(trainer)?);
            point_score(&net, bench, inputs.val_max_side).map_err(|e| NetError::Validation {
                message: e.to_string(),
            })
        };
        let validation = Validation {
            samples: Some(&held_out),
            points: bench.is_some().then_some(&score_points as NetScore),
        };
        let loader_threads = inputs
            .loader_threads
            .unwrap_or_else(|| default_workers(device.is_cuda()));
        if device.is_cuda() {
            // On a GPU the trainer's CPU work is converting each batch: one
            // libtorch thread, so that its thread pool does not fight the
            // loader threads for the cores (which made steps 10x slower).
            tch::set_num_threads(1);
        }
        let (first_step, started) = (self.trainer.step, Instant::now());
        let (mut images, mut pixels, mut waited) = (0, 0, 0.0);
        train::run(
            &mut self.trainer,
            data,
            validation,
            &self.dir,
            loader_threads,
            |m| {
                images += m.images;
                pixels += m.images * m.width * m.height;
                waited += m.data_seconds;
                on_step(m);
            },
        )?;
        Ok(TrainSummary {
            steps: self.trainer.step - first_step,
            images,
            pixels,
            seconds: started.elapsed().as_secs_f64(),
            waited,
            loader_threads,
        })
    }
}

/// Opens a run's feature cache, checking that it is the one the run
/// started on and that the net's encoder still made it.
fn open_cache(trainer: &Trainer, cached: &CachedFeatures) -> Result<FeatureCache, PipelineError> {
    let cache = FeatureCache::open(Path::new(&cached.cache))?;
    if let Some(what) = cache.manifest.difference(&cached.manifest) {
        return Err(PipelineError::file(
            format!("{}/{}", cached.cache, matseg_net::features::MANIFEST_FILE),
            format!("is not the cache this run started on ({what} differs)"),
        ));
    }
    check_cache_encoder(trainer, cached, "the run")?;
    Ok(cache)
}

/// Loads the initial weights `init` names into a new run's net; says what
/// it loaded.
fn load_initial_weights(trainer: &Trainer, init: &str) -> Result<Option<String>, PipelineError> {
    let path = match init {
        "scratch" => return Ok(None),
        "imagenet" => {
            if trainer.config.net.encoder != EncoderConfig::MobilenetV2 {
                return Err(PipelineError::setting(
                    "init",
                    Some("imagenet"),
                    "the registry has ImageNet weights for mobilenet-v2 only; give a safetensors file for ConvNeXt, or start from scratch",
                ));
            }
            imagenet_weights(Arch::MobilenetV2, None)?.path
        }
        model => run_files(&resolve_model(Path::new(model))?).1,
    };
    let label = match init {
        DEFAULT_MODEL => DEFAULT_MODEL.to_string(),
        _ => path.display().to_string(),
    };
    let (tensors, _) = read_weights(&path)?;
    // A whole net's weights (a run's model.safetensors or best.safetensors)
    // carry the net's own names; an encoder's, the encoder's standard ones.
    let whole_net = tensors.iter().any(|t| t.name.starts_with("encoder."));
    Ok(Some(if whole_net {
        let (copied, fresh) = load_net_adding(&trainer.vs, &tensors, COLOUR_PART, &label)?;
        let fresh = match fresh {
            0 => String::new(),
            n => format!(" ({n} of a new colour part start fresh)"),
        };
        format!("net: {copied} tensors from {label}{fresh}")
    } else {
        let copied = load_named(&trainer.vs, "encoder", &tensors, &label)?;
        format!("encoder: {copied} tensors from {label}")
    }))
}

/// The dataset `run.json`'s `data` names.
pub(crate) fn dataset_source(data: &str) -> Result<DatasetSource, PipelineError> {
    let dataset = Dataset::open(Path::new(data))?;
    if dataset.is_empty() {
        return Err(PipelineError::file(data, "no complete samples"));
    }
    Ok(DatasetSource(dataset))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_config_makes_its_run_json_with_the_learning_rate_of_its_start() {
        let config = TrainConfig::new("run", TrainData::Online);
        let run = config.run_config().unwrap();
        assert_eq!(run.data, "online");
        assert_eq!(run.options.lr, train::LR_PRETRAINED);
        assert_eq!(run.options.weight_decay, TrainConfig::WEIGHT_DECAY);
        let scratch = TrainConfig {
            init: "scratch".into(),
            data: TrainData::Dataset("data".into()),
            inference_sides: vec![320, 256],
            ..config
        };
        let run = scratch.run_config().unwrap();
        assert_eq!(run.options.lr, train::LR_SCRATCH);
        assert_eq!(run.data, "data");
        assert_eq!(
            (run.inference_side, run.extra_inference_sides),
            (Some(320), vec![256])
        );
    }

    #[test]
    fn bad_settings_name_the_setting() {
        let base = TrainConfig::new("run", TrainData::Online);
        let encoder = TrainConfig {
            encoder: "resnet".into(),
            ..base.clone()
        };
        let e = encoder.run_config().unwrap_err().to_string();
        assert!(
            e.starts_with("encoder resnet: expected one of mobilenet-v2"),
            "{e}"
        );
        let mix = TrainConfig {
            mix: Some(MixIn {
                data: "renders".into(),
                fraction: 1.5,
            }),
            ..base.clone()
        };
        assert_eq!(
            mix.run_config().unwrap_err().to_string(),
            "mix fraction 1.5: expected 0..1"
        );
        let plan = TrainConfig {
            plan: BatchPlan {
                min_side: 100,
                ..BatchPlan::SPEC
            },
            ..base
        };
        assert!(plan
            .run_config()
            .unwrap_err()
            .to_string()
            .contains("multiples of 32"));
    }

    #[test]
    fn a_folder_holding_a_run_is_not_started_again() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join(train::RUN_FILE), "{}").unwrap();
        let config = TrainConfig::new(dir.path(), TrainData::Online);
        let e = start(&config, ComputeDevice::Cpu).err().expect("refused");
        assert!(e.to_string().contains("already holds a run"), "{e}");
    }
}
