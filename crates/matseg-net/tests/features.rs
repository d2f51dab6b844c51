//! Training on cached encoder features: a few steps on a tiny cache lower
//! the loss, a resumed run takes the same steps as an uninterrupted one,
//! the net's weights move but its encoder's do not, and bad caches (a
//! truncated or foreign shard, a shape that is not the manifest's, a
//! missing shard, a full disk while writing) are one-line errors naming
//! the file, with nothing half-written left.

mod common;

use matseg_net::data::{cached_view, BatchPlan, Zoom};
use matseg_net::features::{
    encode_samples, encoder_digest, CacheManifest, CacheWriter, FeatureCache, CACHE_FORMAT,
    CACHE_VERSION, MANIFEST_FILE,
};
use matseg_net::train::{
    self, CachedFeatures, RunConfig, StepMetrics, TrainOptions, Trainer, TrainingData, Validation,
};
use matseg_scene::Recipe2d;
use std::path::Path;
use tch::Device;

const SIDE: usize = 64;
const SAMPLES: u64 = 6;

fn run_config(steps: u64, cache: &Path, manifest: CacheManifest) -> RunConfig {
    RunConfig {
        net: common::tiny_net(true),
        options: TrainOptions {
            steps,
            lr: 3e-3,
            warmup: 1,
            decay: 0,
            weight_decay: 4e-5,
            plan: BatchPlan {
                min_side: SIDE,
                max_side: SIDE,
                pixels: 3 * SIDE * SIDE,
                min_images: 2,
                max_images: 3,
                p_augment: 0.5,
            },
            seed: 4,
            checkpoint_every: 3,
            validation_batches: 0,
            lr_scales: vec![train::LrScale {
                prefix: "encoder.".into(),
                scale: 0.0,
            }],
        },
        init: "scratch".into(),
        data: "online".into(),
        mix: None,
        inference_side: None,
        extra_inference_sides: Vec::new(),
        features: Some(CachedFeatures {
            cache: cache.display().to_string(),
            manifest,
        }),
    }
}

/// A trainer of [`net`] starting from the weights of `start`.
fn fresh(steps: u64, cache: &Path, manifest: CacheManifest, start: &Trainer) -> Trainer {
    let mut trainer = Trainer::new(run_config(steps, cache, manifest), Device::Cpu);
    trainer.vs.copy(&start.vs).unwrap();
    trainer
}

/// Writes a cache of [`SAMPLES`] generated scenes in `dir`, two a shard,
/// with the encoder of a new net; its manifest and that net.
fn make_cache(dir: &Path) -> (CacheManifest, Trainer) {
    let mut recipe = Recipe2d::default();
    recipe.scene.size_min = 64;
    recipe.scene.size_max = 96;
    let source = common::generator(recipe, 3);
    let probe = Trainer::new(
        RunConfig {
            features: None,
            ..run_config(1, dir, placeholder())
        },
        Device::Cpu,
    );
    let manifest = CacheManifest {
        encoder: common::tiny_net(true).encoder,
        encoder_digest: encoder_digest(&probe.vs),
        taps: probe.net.tap_channels(),
        ..placeholder()
    };
    let writer = CacheWriter::create(dir, manifest.clone()).unwrap();
    for shard in writer.missing_shards() {
        let views: Vec<_> = writer
            .shard_samples(shard)
            .map(|i| cached_view(&source, i, (SIDE, SIDE), Zoom::Native, 0.5, 1).unwrap())
            .collect();
        let cached = encode_samples(&probe.net, &views, Device::Cpu);
        writer
            .write_shard(shard, cached.into_iter().map(Ok))
            .unwrap();
    }
    (manifest, probe)
}

/// A manifest of [`SAMPLES`] samples of [`SIDE`] pixels, two a shard.
fn placeholder() -> CacheManifest {
    CacheManifest {
        format: CACHE_FORMAT.into(),
        version: CACHE_VERSION,
        encoder: common::tiny_net(true).encoder,
        encoder_digest: String::new(),
        model: "scratch".into(),
        width: SIDE,
        height: SIDE,
        taps: [8, 16, 16, 24],
        samples: SAMPLES,
        shard_size: 2,
        data: "online".into(),
        mix: None,
        seed: 1,
        zoom: Zoom::Native,
        p_augment: 0.5,
        sources_fingerprint: String::new(),
    }
}

fn train_to(
    trainer: &mut Trainer,
    steps: u64,
    cache: &FeatureCache,
    dir: &Path,
) -> Vec<StepMetrics> {
    trainer.config.options.steps = steps;
    let mut seen = Vec::new();
    let validation = Validation {
        samples: None,
        points: None,
    };
    train::run(
        trainer,
        TrainingData::Features(cache),
        validation,
        dir,
        2,
        |m| {
            seen.push(StepMetrics {
                seconds: 0.0,
                data_seconds: 0.0,
                ..m.clone()
            })
        },
    )
    .unwrap();
    seen
}

#[test]
fn a_few_steps_on_a_tiny_cache_lower_the_loss_and_leave_the_encoder() {
    let cache_dir = tempfile::tempdir().unwrap();
    let run = tempfile::tempdir().unwrap();
    let (manifest, start) = make_cache(cache_dir.path());
    let cache = FeatureCache::open(cache_dir.path()).unwrap();
    assert_eq!(cache.len(), SAMPLES);
    let mut trainer = fresh(30, cache_dir.path(), manifest.clone(), &start);
    let before = encoder_digest(&trainer.vs);
    assert_eq!(before, manifest.encoder_digest);
    let head_before = trainer.vs.variables()["head.weight"].copy();
    let seen = train_to(&mut trainer, 30, &cache, run.path());
    // Three images a step from six samples: every two steps an epoch.
    assert!(seen.iter().all(|m| m.images == 3 && m.width == SIDE));
    let losses: Vec<f64> = seen.iter().filter_map(|m| m.loss).collect();
    assert!(losses.len() >= 20, "{losses:?}");
    let mean = |l: &[f64]| l.iter().sum::<f64>() / l.len() as f64;
    let (first, last) = (mean(&losses[..6]), mean(&losses[losses.len() - 6..]));
    assert!(last < 0.85 * first, "loss {first} -> {last}");
    assert_eq!(encoder_digest(&trainer.vs), before, "the encoder is frozen");
    assert_ne!(trainer.vs.variables()["head.weight"], head_before);
}

#[test]
fn a_resumed_run_on_a_cache_takes_exactly_the_same_steps() {
    let cache_dir = tempfile::tempdir().unwrap();
    let (straight_dir, resumed_dir) = (tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap());
    let (manifest, start) = make_cache(cache_dir.path());
    let cache = FeatureCache::open(cache_dir.path()).unwrap();

    let mut straight = fresh(6, cache_dir.path(), manifest.clone(), &start);
    train::write_run_config(straight_dir.path(), &straight.config).unwrap();
    let all = train_to(&mut straight, 6, &cache, straight_dir.path());

    let mut first = fresh(6, cache_dir.path(), manifest, &start);
    train::write_run_config(resumed_dir.path(), &first.config).unwrap();
    let early = train_to(&mut first, 3, &cache, resumed_dir.path());
    drop(first);
    let mut resumed = Trainer::resume(resumed_dir.path(), Device::Cpu).unwrap();
    assert_eq!(resumed.step, 3);
    let late = train_to(&mut resumed, 6, &cache, resumed_dir.path());
    assert_eq!([early, late].concat(), all);
    let model = |d: &Path| std::fs::read(d.join(train::MODEL_FILE)).unwrap();
    assert_eq!(model(straight_dir.path()), model(resumed_dir.path()));
    assert_eq!(
        train::read_run_config(resumed_dir.path()).unwrap().features,
        straight.config.features
    );
}

#[test]
fn bad_caches_are_named_in_one_line() {
    let dir = tempfile::tempdir().unwrap();
    let (manifest, _) = make_cache(dir.path());
    let shard = |i: u64| dir.path().join(format!("shard-{i:06}.tar"));
    let open_error = |d: &Path| FeatureCache::open(d).expect_err("refused").to_string();
    let last_shard: Vec<_> = {
        let cache = FeatureCache::open(dir.path()).unwrap();
        (4..6).map(|i| cache.get(i).unwrap()).collect()
    };

    // Not a cache at all.
    let empty = tempfile::tempdir().unwrap();
    let e = open_error(empty.path());
    assert!(
        e.ends_with(
            "cache.json: no such file: not a feature cache (make one with matseg features)"
        ),
        "{e}"
    );

    // A shard cut short.
    let whole = std::fs::read(shard(1)).unwrap();
    std::fs::write(shard(1), &whole[..whole.len() / 2]).unwrap();
    let e = open_error(dir.path());
    assert!(e.starts_with(&shard(1).display().to_string()), "{e}");
    assert!(
        e.contains("truncated") || e.contains("not a shard of this cache"),
        "{e}"
    );
    assert!(!e.contains('\n'));

    // Another cache's shard in its place.
    std::fs::write(shard(1), std::fs::read(shard(2)).unwrap()).unwrap();
    let e = open_error(dir.path());
    assert!(
        e.contains("not a shard of this cache: expected samples 2..4"),
        "{e}"
    );
    std::fs::write(shard(1), &whole).unwrap();
    FeatureCache::open(dir.path()).unwrap();

    // A manifest that does not describe the samples.
    let path = dir.path().join(MANIFEST_FILE);
    let good = std::fs::read(&path).unwrap();
    let wrong = CacheManifest {
        taps: [9, 16, 16, 24],
        ..manifest.clone()
    };
    std::fs::write(&path, serde_json::to_vec(&wrong).unwrap()).unwrap();
    let e = FeatureCache::open(dir.path())
        .unwrap()
        .get(0)
        .err()
        .unwrap()
        .to_string();
    assert!(
        e.contains("shard-000000.tar!00000000.features.safetensors: s4 is F16 [8, 16, 16], the cache's manifest says F16 [9, 16, 16]"),
        "{e}"
    );
    std::fs::write(&path, &good).unwrap();

    // A missing shard.
    std::fs::remove_file(shard(2)).unwrap();
    let e = open_error(dir.path());
    assert!(
        e.contains("shard-000002.tar: missing: the cache is incomplete"),
        "{e}"
    );

    // Another job's settings in the same folder.
    let other = CacheManifest {
        seed: 2,
        ..manifest.clone()
    };
    let e = CacheWriter::create(dir.path(), other)
        .err()
        .unwrap()
        .to_string();
    assert!(
        e.contains("holds a cache made with other settings (the seed differs)"),
        "{e}"
    );

    // A full disk while writing the shard: an error naming it, and neither
    // the shard nor its temporary file left.
    let writer = CacheWriter::create(dir.path(), manifest).unwrap();
    assert_eq!(writer.missing_shards(), [2]);
    let tmp = dir
        .path()
        .join(format!("shard-000002.tar.tmp.{}", std::process::id()));
    std::os::unix::fs::symlink("/dev/full", &tmp).unwrap();
    let e = writer
        .write_shard(2, last_shard.into_iter().map(Ok))
        .expect_err("the disk is full")
        .to_string();
    assert!(e.starts_with(&shard(2).display().to_string()), "{e}");
    assert!(e.contains("No space left on device"), "{e}");
    assert!(!shard(2).exists() && !tmp.exists());
}
