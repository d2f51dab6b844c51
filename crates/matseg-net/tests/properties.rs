//! Property tests of the feature cache's files as `FeatureCache::open`
//! and `FeatureCache::get` read them: the manifest `cache.json` and the
//! tar shards of safetensors samples.
//!
//! Samples made at random (16-bit tensors of the manifest's shapes)
//! and written by `CacheWriter` read back as written, for any sample
//! count and shard size. Whatever a cache holds instead (a manifest of
//! arbitrary bytes, any JSON, or a valid one with a value replaced; a
//! shard cut short, with bits flipped, or whose members hold any bytes),
//! opening it and reading each sample gives samples or one-line errors,
//! never a panic, and opening it allocates no more than a small multiple
//! of its files (a counting allocator measures it), whatever sample count
//! the manifest claims.

#[path = "../../../testing/properties.rs"]
mod support;

use support::{mutate, mutation};

use matseg_data::wds::{append_member, sample_key, shard_path};
use matseg_net::data::Zoom;
use matseg_net::features::{
    CacheManifest, CacheWriter, CachedSample, FeatureCache, CACHE_FORMAT, CACHE_VERSION,
    MANIFEST_FILE, MEMBER_SUFFIX,
};
use matseg_net::EncoderConfig;
use matseg_weights::{write_safetensors, DType, Tensor};
use proptest::prelude::*;
use serde_json::Value;
use std::path::Path;
use support::allocations;

#[global_allocator]
static ALLOCATOR: allocations::Counting = allocations::Counting;

/// The seed of the cases.
const SEED: u64 = 5;

fn config() -> ProptestConfig {
    support::config(SEED)
}

// ---------------------------------------------------------------- inputs

/// Numbers: small, at the edges of the integer types, negative, fractional.
fn json_number() -> impl Strategy<Value = Value> {
    prop_oneof![
        (0u64..70).prop_map(Value::from),
        any::<u64>().prop_map(Value::from),
        prop::sample::select(vec![u64::MAX, u64::MAX / 2 + 1, 1 << 62, 1 << 32])
            .prop_map(Value::from),
        any::<i64>().prop_map(Value::from),
        (-1e3f64..1e3).prop_map(Value::from),
    ]
}

/// Any JSON value, a few levels deep.
fn json_value() -> impl Strategy<Value = Value> {
    support::json_value(json_number(), 3, 4)
}

/// A manifest of `samples` samples of 32 x 32 pixels, `shard_size` a shard.
fn manifest(samples: u64, shard_size: u64) -> CacheManifest {
    CacheManifest {
        format: CACHE_FORMAT.into(),
        version: CACHE_VERSION,
        encoder: EncoderConfig::MobilenetV2,
        encoder_digest: "digest".into(),
        model: "test".into(),
        width: 32,
        height: 32,
        taps: [2, 3, 2, 1],
        samples,
        shard_size,
        data: "online".into(),
        mix: None,
        seed: 1,
        zoom: Zoom::Cover,
        p_augment: 0.5,
        sources_fingerprint: String::new(),
    }
}

/// The shapes of a sample of [`manifest`] with `materials` materials.
fn shapes(materials: usize) -> [(&'static str, Vec<usize>); 7] {
    [
        ("s4", vec![2, 8, 8]),
        ("s8", vec![3, 4, 4]),
        ("s16", vec![2, 2, 2]),
        ("s32", vec![1, 1, 1]),
        ("lab", vec![3, 8, 8]),
        ("weights", vec![materials, 8, 8]),
        ("roi", vec![8, 8]),
    ]
}

/// A sample of [`manifest`]: its stored tensors, of any 16-bit values.
fn sample() -> impl Strategy<Value = Vec<Tensor>> {
    (1usize..4).prop_flat_map(|materials| {
        shapes(materials)
            .map(|(name, shape)| {
                let len = shape.iter().product::<usize>() * 2;
                prop::collection::vec(any::<u8>(), len).prop_map(move |data| Tensor {
                    name: name.into(),
                    dtype: DType::F16,
                    shape: shape.clone(),
                    data,
                })
            })
            .to_vec()
    })
}

/// A cache written by [`CacheWriter`]: its manifest and samples.
fn cache() -> impl Strategy<Value = (u64, Vec<Vec<Tensor>>)> {
    (1u64..4, prop::collection::vec(sample(), 1..6))
}

fn cached(tensors: &[Tensor], manifest: &CacheManifest) -> CachedSample {
    CachedSample::from_bytes(&write_safetensors(tensors, &[]), manifest, "made").unwrap()
}

/// Writes the cache of `samples`, `shard_size` a shard, into `dir`.
fn write_cache(dir: &Path, shard_size: u64, samples: &[Vec<Tensor>]) -> CacheManifest {
    let manifest = manifest(samples.len() as u64, shard_size);
    let writer = CacheWriter::create(dir, manifest.clone()).unwrap();
    for shard in writer.missing_shards() {
        let made = writer
            .shard_samples(shard)
            .map(|i| Ok(cached(&samples[i as usize], &manifest)));
        writer.write_shard(shard, made).unwrap();
    }
    manifest
}

/// Opens the cache in `dir` and reads every sample: no panic, one-line
/// errors, and opening bounded by the size of the cache's files.
fn read_any(dir: &Path) -> Result<(), TestCaseError> {
    let files: u64 = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().metadata().unwrap().len())
        .sum();
    let limit = 64 * files as usize + (1 << 20);
    let (opened, held) = allocations::peak(|| FeatureCache::open(dir));
    prop_assert!(held <= limit, "opening held {} bytes, over {}", held, limit);
    let one_line = |e: &dyn std::fmt::Display| -> Result<(), TestCaseError> {
        let text = e.to_string();
        prop_assert!(!text.contains('\n'), "{:?}", text);
        prop_assert!(text.starts_with(&dir.display().to_string()), "{}", text);
        Ok(())
    };
    match opened {
        Ok(cache) => {
            for i in 0..cache.len() {
                if let Err(e) = cache.get(i) {
                    one_line(&e)?;
                }
            }
        }
        Err(e) => one_line(&e)?,
    }
    Ok(())
}

/// Writes `members` (name, bytes) as a shard file.
fn write_tar(path: &Path, members: &[(String, Vec<u8>)]) {
    let mut tar = tar::Builder::new(Vec::new());
    for (name, data) in members {
        append_member(&mut tar, name, data).unwrap();
    }
    std::fs::write(path, tar.into_inner().unwrap()).unwrap();
}

// ---------------------------------------------------------------- properties

proptest! {
    #![proptest_config(config())]

    #[test]
    fn samples_read_back_as_written((shard_size, samples) in cache()) {
        let dir = tempfile::tempdir().unwrap();
        let manifest = write_cache(dir.path(), shard_size, &samples);
        let cache = FeatureCache::open(dir.path()).unwrap();
        prop_assert_eq!(&cache.manifest, &manifest);
        prop_assert_eq!(cache.len(), samples.len() as u64);
        for (i, want) in samples.iter().enumerate() {
            prop_assert_eq!(&cache.get(i as u64).unwrap().into_stored(), want);
        }
    }

    #[test]
    fn manifests_of_arbitrary_bytes_never_panic(
        (shard_size, samples) in cache(),
        bytes in prop::collection::vec(any::<u8>(), 0..256),
    ) {
        let dir = tempfile::tempdir().unwrap();
        write_cache(dir.path(), shard_size, &samples);
        std::fs::write(dir.path().join(MANIFEST_FILE), bytes).unwrap();
        read_any(dir.path())?;
    }

    #[test]
    fn manifests_of_any_json_never_panic((shard_size, samples) in cache(), json in json_value()) {
        let dir = tempfile::tempdir().unwrap();
        write_cache(dir.path(), shard_size, &samples);
        std::fs::write(dir.path().join(MANIFEST_FILE), json.to_string()).unwrap();
        read_any(dir.path())?;
    }

    #[test]
    fn manifests_with_values_replaced_never_panic(
        (shard_size, samples) in cache(),
        changes in prop::collection::vec((
            // The counts most often, and both at once now and then.
            prop::sample::select(vec![
                "samples", "samples", "samples", "shard_size", "shard_size", "shard_size",
                "width", "height", "taps", "encoder", "zoom", "mix", "version", "format",
                "p_augment", "seed",
            ]),
            prop_oneof![3 => json_number(), 1 => json_value()],
        ), 1..4),
    ) {
        let dir = tempfile::tempdir().unwrap();
        let manifest = write_cache(dir.path(), shard_size, &samples);
        let mut json = serde_json::to_value(&manifest).unwrap();
        for (key, value) in changes {
            json[key] = value;
        }
        std::fs::write(dir.path().join(MANIFEST_FILE), json.to_string()).unwrap();
        read_any(dir.path())?;
    }

    #[test]
    fn damaged_shards_never_panic(
        (shard_size, samples) in cache(),
        which in any::<prop::sample::Index>(),
        m in mutation(),
    ) {
        let dir = tempfile::tempdir().unwrap();
        let manifest = write_cache(dir.path(), shard_size, &samples);
        let path = shard_path(dir.path(), which.index(manifest.shards() as usize) as u64);
        let bytes = std::fs::read(&path).unwrap();
        std::fs::write(&path, mutate(&bytes, &m)).unwrap();
        read_any(dir.path())?;
    }

    #[test]
    fn members_of_any_bytes_are_errors(
        (shard_size, samples) in cache(),
        which in any::<prop::sample::Index>(),
        sample in prop_oneof![
            prop::collection::vec(any::<u8>(), 0..256),
            (sample(), any::<prop::sample::Index>(), any::<prop::sample::Index>()).prop_map(
                |(mut tensors, t, d)| {
                    // A valid file but for one tensor: of another type,
                    // another shape, or missing.
                    let k = t.index(tensors.len());
                    match d.index(3) {
                        0 => tensors[k].dtype = DType::BF16,
                        1 => {
                            tensors[k].shape.insert(0, 1);
                            tensors[k].shape.push(1);
                        }
                        _ => {
                            tensors.remove(k);
                        }
                    }
                    write_safetensors(&tensors, &[])
                }
            ),
        ],
    ) {
        let dir = tempfile::tempdir().unwrap();
        let manifest = write_cache(dir.path(), shard_size, &samples);
        let i = which.index(samples.len()) as u64;
        let shard = i / shard_size;
        let mut members: Vec<(String, Vec<u8>)> = (shard * shard_size..(shard + 1) * shard_size)
            .take_while(|&k| k < manifest.samples)
            .map(|k| {
                let bytes = cached(&samples[k as usize], &manifest).to_bytes();
                (format!("{}.{MEMBER_SUFFIX}", sample_key(k)), bytes)
            })
            .collect();
        members[(i - shard * shard_size) as usize].1 = sample;
        write_tar(&shard_path(dir.path(), shard), &members);
        let cache = FeatureCache::open(dir.path()).unwrap();
        let err = cache.get(i).unwrap_err().to_string();
        prop_assert!(!err.contains('\n'), "{:?}", err);
        prop_assert!(err.contains(&sample_key(i)), "{}", err);
        read_any(dir.path())?;
    }
}
