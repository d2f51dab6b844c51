//! `matseg features`: a feature cache (training samples run once through a
//! model's encoder) for `matseg train --features`.

use crate::common::{BarProgress, LibraryArgs};
use crate::net_args::parse_device;
use anyhow::{bail, Result};
use matseg_image::outputs::check_apart;
use matseg_net::data::Zoom;
use matseg_pipeline::features::{make_features, FeaturesConfig};
use matseg_pipeline::sources::DEFAULT_CACHE_MB;
use matseg_pipeline::train::{MixIn, TrainConfig, TrainData};
use std::path::PathBuf;

/// `--zoom` values.
#[derive(Clone, Copy, clap::ValueEnum)]
enum ZoomArg {
    /// The whole scene shrunk to cover the window.
    Cover,
    /// Any scale up to the scene's own.
    Native,
}

/// Arguments of `matseg features`.
#[derive(clap::Args)]
pub struct Args {
    /// The cache's folder (rerun the same command to finish an interrupted
    /// cache; docs/outputs.md).
    #[arg(long)]
    out: PathBuf,
    /// Scenes from this dataset (MatSeg folders or WebDataset shards).
    #[arg(long, conflicts_with = "online")]
    data: Option<PathBuf>,
    /// Scenes straight from the 2D generator (the fetched corpus, else the
    /// bundled assets, unless --sources/--textures).
    #[arg(long)]
    online: bool,
    /// A stored dataset (e.g. 3D renders) mixed in, --mix-fraction of the samples.
    #[arg(long, value_name = "DIR")]
    mix_data: Option<PathBuf>,
    /// The share of samples taken from --mix-data.
    #[arg(long, default_value_t = TrainConfig::MIX_FRACTION, requires = "mix_data")]
    mix_fraction: f64,
    #[command(flatten)]
    libraries: LibraryArgs,
    /// The encoder's weights: default (the shipped model), imagenet, a run
    /// folder, or a whole net's weights file beside its run.json.
    #[arg(long, default_value = FeaturesConfig::MODEL)]
    model: String,
    /// Samples in the cache.
    #[arg(short = 'n', long = "samples", default_value_t = FeaturesConfig::SAMPLES)]
    samples: u64,
    /// Sample side in pixels (a multiple of 32): scenes are fitted to SIDE x SIDE.
    #[arg(long, default_value_t = FeaturesConfig::SIDE)]
    side: usize,
    /// Samples per tar shard.
    #[arg(long, default_value_t = FeaturesConfig::SHARD_SIZE)]
    shard_size: u64,
    /// Seed of the scenes and of their fitting and augmentation.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// How scenes are scaled before a SIDE x SIDE window is cut out: cover
    /// (the whole scene shrunk to just cover it, up to 1.5 times more, as
    /// matseg train fits batches) or native (any scale from that to the
    /// scene's own).
    #[arg(long, value_enum, default_value = "cover")]
    zoom: ZoomArg,
    /// The share of samples augmented (flips, blur, brightness, greyscale, noise).
    #[arg(long, default_value_t = 0.5)]
    augment: f64,
    /// cpu, cuda or cuda:N.
    #[arg(long, default_value = "cpu")]
    device: String,
    /// Threads making the scenes while the encoder runs (the cache is the
    /// same whatever their number).
    #[arg(long, default_value_t = 2)]
    loader_threads: usize,
    /// Memory for decoded source photos and textures, in MiB.
    #[arg(long, default_value_t = DEFAULT_CACHE_MB)]
    cache_mb: usize,
}

/// Runs `matseg features`.
pub fn run(args: Args) -> Result<()> {
    let device = parse_device(&args.device)?;
    let data = match (&args.data, args.online) {
        (Some(path), false) => TrainData::Dataset(path.clone()),
        (None, true) => TrainData::Online,
        _ => bail!("give --data DIR or --online"),
    };
    let config = FeaturesConfig {
        mix: args.mix_data.as_ref().map(|dir| MixIn {
            data: dir.clone(),
            fraction: args.mix_fraction,
        }),
        model: args.model.clone(),
        samples: args.samples,
        width: args.side,
        height: args.side,
        shard_size: args.shard_size,
        seed: args.seed,
        zoom: match args.zoom {
            ZoomArg::Cover => Zoom::Cover,
            ZoomArg::Native => Zoom::Native,
        },
        p_augment: args.augment,
        ..FeaturesConfig::new(&args.out, data)
    };
    let libraries = args.libraries.load(args.cache_mb)?;
    let mut inputs = libraries.roots();
    inputs.extend(args.data.as_deref());
    inputs.extend(args.mix_data.as_deref());
    check_apart(&args.out, &inputs)?;
    let report = make_features(
        &config,
        &libraries,
        device,
        args.loader_threads,
        &BarProgress::default(),
    )?;
    println!(
        "{}: {} samples made, {} already complete; {:.1} MB in shards; {:.1} s ({:.1} samples/s)",
        args.out.display(),
        report.made,
        report.kept,
        report.bytes as f64 / 1e6,
        report.seconds,
        report.made as f64 / report.seconds.max(1e-9)
    );
    Ok(())
}
