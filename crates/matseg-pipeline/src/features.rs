//! Feature caches (`matseg features`): training samples run once through a
//! model's encoder and stored with their targets on the stride-4 grid, for
//! runs that train the rest of the net on them for several epochs
//! (`matseg train --features`, [`crate::train::TrainData::Features`]).
//! What a cache holds and why: `matseg_net::features`.

use crate::error::PipelineError;
use crate::progress::Progress;
use crate::sources::Libraries;
use crate::train::{dataset_source, MixIn, TrainData, ONLINE};
use crate::weights::{imagenet_weights, read_weights};
use matseg_data::generate::sources_fingerprint;
use matseg_data::wds::shard_path;
use matseg_image::device::ComputeDevice;
use matseg_net::data::{cached_view, GeneratorSource, MixedSource, SampleSource, Zoom};
use matseg_net::features::{
    encode_samples, encoder_digest, CacheManifest, CacheWriter, CACHE_FORMAT, CACHE_VERSION,
};
use matseg_net::infer::{resolve_model, TrainedNet};
use matseg_net::loader::BatchLoader;
use matseg_net::torch_device;
use matseg_net::train::Mix;
use matseg_net::{load_named, MaterialNet, NetConfig};
use matseg_scene::Recipe2d;
use matseg_weights::Arch;
use std::path::{Path, PathBuf};
use std::time::Instant;
use tch::nn;

/// Everything a cache is made from; [`FeaturesConfig::new`] gives the
/// defaults of `matseg features`.
#[derive(Clone, Debug, PartialEq)]
pub struct FeaturesConfig {
    /// The cache's folder (a cache made with the same settings there is
    /// continued, one made with others refused).
    pub out: PathBuf,
    /// Where the scenes come from: the 2D generator or a stored dataset.
    pub data: TrainData,
    /// A stored dataset mixed in.
    pub mix: Option<MixIn>,
    /// The encoder's weights: `default` (the shipped model), `imagenet`
    /// (the registry's MobileNetV2), a run folder or a whole net's weights
    /// file beside its `run.json`.
    pub model: String,
    /// Samples in the cache.
    pub samples: u64,
    /// Sample width in pixels (a multiple of 32).
    pub width: usize,
    /// Sample height in pixels (a multiple of 32).
    pub height: usize,
    /// Samples per shard.
    pub shard_size: u64,
    /// Seed of the scenes and of their fitting and augmentation.
    pub seed: u64,
    /// How scenes are scaled before their windows are cut out.
    pub zoom: Zoom,
    /// The share of samples augmented.
    pub p_augment: f64,
}

impl FeaturesConfig {
    /// Default samples in a cache.
    pub const SAMPLES: u64 = 2000;
    /// Default sample side.
    pub const SIDE: usize = 256;
    /// Default samples per shard.
    pub const SHARD_SIZE: u64 = 256;
    /// Default encoder weights.
    pub const MODEL: &'static str = "default";

    /// A cache in `out` of scenes from `data`, with `matseg features`'s
    /// defaults.
    pub fn new(out: impl Into<PathBuf>, data: TrainData) -> Self {
        Self {
            out: out.into(),
            data,
            mix: None,
            model: Self::MODEL.to_string(),
            samples: Self::SAMPLES,
            width: Self::SIDE,
            height: Self::SIDE,
            shard_size: Self::SHARD_SIZE,
            seed: 0,
            zoom: Zoom::Cover,
            p_augment: matseg_net::data::BatchPlan::SPEC.p_augment,
        }
    }

    /// Checks the settings that need no file.
    fn check(&self) -> Result<(), PipelineError> {
        if [self.width, self.height]
            .iter()
            .any(|&side| side < 32 || !side.is_multiple_of(32))
        {
            return Err(PipelineError::Settings(format!(
                "sample sides {}x{}: expected multiples of 32, at least 32",
                self.width, self.height
            )));
        }
        if self.samples == 0 {
            return Err(PipelineError::setting(
                "samples",
                Some(0),
                "expected at least 1",
            ));
        }
        if self.shard_size == 0 {
            return Err(PipelineError::setting(
                "shard size",
                Some(0),
                "expected at least 1",
            ));
        }
        if !(0.0..=1.0).contains(&self.p_augment) {
            return Err(PipelineError::setting(
                "augment",
                Some(self.p_augment),
                "expected 0..1",
            ));
        }
        if let Some(mix) = &self.mix {
            mix.validate()?;
        }
        Ok(())
    }
}

/// What one call of [`make_features`] did.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FeaturesReport {
    /// Samples made now.
    pub made: u64,
    /// Samples found in complete shards and kept.
    pub kept: u64,
    /// Bytes of the cache's shards.
    pub bytes: u64,
    /// Wall seconds.
    pub seconds: f64,
}

/// Samples encoded together (one encoder pass).
const ENCODE_BATCH: u64 = 8;

/// A net whose encoder makes a cache's taps: the encoder of `model`
/// ([`FeaturesConfig::model`]), and how it is named in the manifest.
pub fn encoder_net(
    model: &str,
    device: ComputeDevice,
) -> Result<(nn::VarStore, MaterialNet, String), PipelineError> {
    if model == "imagenet" {
        let vs = nn::VarStore::new(torch_device(device));
        let config = NetConfig::preset("mobilenet-v2").expect("a preset");
        let net = MaterialNet::new(&vs.root(), config);
        let path = imagenet_weights(Arch::MobilenetV2, None)?.path;
        let (tensors, _) = read_weights(&path)?;
        load_named(&vs, "encoder", &tensors, &path.display().to_string())?;
        return Ok((vs, net, model.to_string()));
    }
    let trained = TrainedNet::load(Path::new(model), device)?;
    let mut vs = nn::VarStore::new(torch_device(device));
    let net = MaterialNet::new(&vs.root(), trained.net().config);
    vs.copy(trained.vs())
        .map_err(|source| matseg_net::NetError::Torch {
            file: model.to_string(),
            source,
        })?;
    let name = match model {
        matseg_net::infer::DEFAULT_MODEL => model.to_string(),
        _ => std::fs::canonicalize(resolve_model(Path::new(model))?)
            .map_or_else(|_| model.to_string(), |p| p.display().to_string()),
    };
    Ok((vs, net, name))
}

/// Makes (or finishes) the cache `config` describes on `device`, drawing
/// online scenes from `libraries` in `loader_threads` background threads
/// (the cache is the same whatever their number); shards already
/// complete are kept.
pub fn make_features(
    config: &FeaturesConfig,
    libraries: &Libraries,
    device: ComputeDevice,
    loader_threads: usize,
    progress: &dyn Progress,
) -> Result<FeaturesReport, PipelineError> {
    config.check()?;
    let started = Instant::now();
    let (vs, net, model) = encoder_net(&config.model, device)?;
    let generator = GeneratorSource {
        sources: libraries.sources(),
        recipe: Recipe2d::default(),
        seed: config.seed,
    };
    let (main, data): (Box<dyn SampleSource + '_>, String) =
        match &config.data {
            TrainData::Online => (Box::new(generator), ONLINE.to_string()),
            TrainData::Dataset(dir) => (
                Box::new(dataset_source(&dir.display().to_string())?),
                dir.display().to_string(),
            ),
            TrainData::Features(dir) => return Err(PipelineError::file(
                dir.display(),
                "a feature cache is made from scenes (online or a dataset), not from another cache",
            )),
        };
    let mixed_in = match &config.mix {
        Some(mix) => Some((
            dataset_source(&mix.data.display().to_string())?,
            mix.fraction,
        )),
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
    let net_config = net.config;
    let manifest = CacheManifest {
        format: CACHE_FORMAT.into(),
        version: CACHE_VERSION,
        encoder: net_config.encoder,
        encoder_digest: encoder_digest(&vs),
        model,
        width: config.width,
        height: config.height,
        taps: net.tap_channels(),
        samples: config.samples,
        shard_size: config.shard_size,
        sources_fingerprint: match config.data {
            TrainData::Online => sources_fingerprint(libraries.sources()),
            _ => String::new(),
        },
        data,
        mix: config.mix.as_ref().map(|m| Mix {
            data: m.data.display().to_string(),
            fraction: m.fraction,
        }),
        seed: config.seed,
        zoom: config.zoom,
        p_augment: config.p_augment,
    };
    let writer = CacheWriter::create(&config.out, manifest)?;
    let missing = writer.missing_shards();
    // The encoder passes' chunks of samples, shard by shard.
    let chunks: Vec<(u64, u64)> = missing
        .iter()
        .flat_map(|&shard| {
            let range = writer.shard_samples(shard);
            (range.start..range.end)
                .step_by(ENCODE_BATCH as usize)
                .map(move |first| (first, (first + ENCODE_BATCH).min(range.end)))
        })
        .collect();
    let made: u64 = chunks.iter().map(|(a, b)| b - a).sum();
    progress.start(made, "samples");
    let size = (config.width, config.height);
    let make = |chunk: u64| {
        let (first, end) = chunks[chunk as usize];
        (first..end)
            .map(|i| cached_view(source, i, size, config.zoom, config.p_augment, config.seed))
            .collect::<Result<Vec<_>, _>>()
            .map_err(matseg_net::NetError::from)
    };
    std::thread::scope(|scope| -> Result<(), PipelineError> {
        let loader = BatchLoader::spawn(scope, &make, (0, chunks.len() as u64), loader_threads);
        let mut next_chunk = 0u64;
        for &shard in &missing {
            let range = writer.shard_samples(shard);
            let chunks_here = (range.end - range.start).div_ceil(ENCODE_BATCH);
            let encoded = (0..chunks_here).flat_map(|_| {
                let chunk = next_chunk;
                next_chunk += 1;
                let batch = loader.batch(chunk);
                let samples = batch.map(|fitted| encode_samples(&net, &fitted, vs.device()));
                progress.advance_by(chunks[chunk as usize].1 - chunks[chunk as usize].0);
                match samples {
                    Ok(samples) => samples.into_iter().map(Ok).collect::<Vec<_>>(),
                    Err(e) => vec![Err(e)],
                }
            });
            writer.write_shard(shard, encoded)?;
        }
        Ok(())
    })?;
    progress.finish();
    let bytes = (0..writer.manifest().shards())
        .filter_map(|s| std::fs::metadata(shard_path(&config.out, s)).ok())
        .map(|m| m.len())
        .sum();
    Ok(FeaturesReport {
        made,
        kept: config.samples - made,
        bytes,
        seconds: started.elapsed().as_secs_f64(),
    })
}
