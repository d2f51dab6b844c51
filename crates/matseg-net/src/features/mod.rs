//! Cached encoder features: the fast way to train on two CPU cores.
//!
//! A feature cache holds, for each of its training samples (a scene fitted
//! to one fixed size and maybe augmented, as `matseg train` fits its
//! batches), what the rest of the net needs when the encoder is frozen: the
//! encoder's taps at strides 4, 8, 16 and 32, each stride-4 cell's mean
//! L*a*b* colour (for the colour part), and the ground truth on the stride-4
//! grid ([`crate::grid::GridTargets`]). A run on it trains the PSP module,
//! the decoder, the head and the descriptor's part weights, with the loss
//! on the grid: no encoder pass, no backward pass through it, no loss at
//! full size, no scene generation, for several epochs over the cache.
//!
//! On disk (docs/formats.md):
//!
//! ```text
//! CACHE/cache.json              the manifest: encoder, its weights' digest, size, count...
//! CACHE/shard-000000.tar        samples 0..shard_size, one member each:
//!       00000000.features.safetensors   s4, s8, s16, s32, lab, weights, roi (16-bit floats)
//! ```
//!
//! Shards are written under a temporary name and renamed when complete;
//! the manifest is written first, and a cache is usable once every shard
//! is there.

mod encode;
mod epochs;
mod record;
mod store;

pub use encode::{encode_samples, encoder_digest};
pub use epochs::epoch_indices;
pub use record::{CachedBatch, CachedSample};
pub use store::{CacheWriter, FeatureCache};

use crate::encoder::EncoderConfig;
use crate::NetError;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// `format` of a cache manifest.
pub const CACHE_FORMAT: &str = "matseg-feature-cache";
/// The version of the layout this code reads and writes.
pub const CACHE_VERSION: u32 = 1;
/// The manifest's file name.
pub const MANIFEST_FILE: &str = "cache.json";
/// The suffix of a sample's member in a shard.
pub const MEMBER_SUFFIX: &str = "features.safetensors";

/// What a cache holds and how it was made (`cache.json`). A run on the
/// cache keeps a copy in its `run.json`; a resumed run, or another cache
/// job writing into the same folder, must find the same.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CacheManifest {
    /// [`CACHE_FORMAT`].
    pub format: String,
    /// [`CACHE_VERSION`].
    pub version: u32,
    /// The encoder that made the taps.
    pub encoder: EncoderConfig,
    /// [`encoder_digest`] of its weights: a run must start from the same.
    pub encoder_digest: String,
    /// The weights the encoder was taken from, as named when the cache
    /// was made (`default`, `imagenet`, a file).
    pub model: String,
    /// Sample width in pixels (a multiple of 32).
    pub width: usize,
    /// Sample height in pixels (a multiple of 32).
    pub height: usize,
    /// Channels of the taps at strides 4, 8, 16 and 32.
    pub taps: [i64; 4],
    /// Samples in the cache.
    pub samples: u64,
    /// Samples per shard (the last shard may hold fewer).
    pub shard_size: u64,
    /// Where the scenes came from: `online` (the 2D generator) or a
    /// dataset's folder.
    pub data: String,
    /// A dataset mixed into `data`, with its share, if any.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mix: Option<crate::train::Mix>,
    /// The seed of the scenes and of their fitting and augmentation.
    pub seed: u64,
    /// How the scenes were scaled before their windows were cut out.
    #[serde(default)]
    pub zoom: crate::data::Zoom,
    /// The share of samples augmented.
    pub p_augment: f64,
    /// The generator's source files and recipe, when `data` is `online`
    /// (their fingerprint, as a dataset manifest records it).
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub sources_fingerprint: String,
}

impl CacheManifest {
    /// The stride-4 grid's (width, height) in cells.
    pub fn grid(&self) -> (usize, usize) {
        (
            self.width / crate::grid::GRID_STRIDE,
            self.height / crate::grid::GRID_STRIDE,
        )
    }

    /// The number of shards.
    pub fn shards(&self) -> u64 {
        self.samples.div_ceil(self.shard_size.max(1))
    }

    /// Reads `dir/cache.json`; a folder without one, or with a file of
    /// another kind or version, is a one-line error naming it.
    pub fn read(dir: &Path) -> Result<Self, NetError> {
        let path = dir.join(MANIFEST_FILE);
        let bad = |message: String| NetError::File {
            file: path.display().to_string(),
            message,
        };
        let text = std::fs::read_to_string(&path).map_err(|e| {
            bad(if e.kind() == std::io::ErrorKind::NotFound {
                "no such file: not a feature cache (make one with matseg features)".into()
            } else {
                format!("cannot read: {e}")
            })
        })?;
        let value: serde_json::Value =
            serde_json::from_str(&text).map_err(|e| bad(format!("not JSON: {e}")))?;
        if value["format"] != CACHE_FORMAT {
            return Err(bad("not a feature cache manifest".into()));
        }
        if value["version"] != CACHE_VERSION {
            return Err(bad(format!(
                "a feature cache of version {}, this matseg reads version {CACHE_VERSION}",
                value["version"]
            )));
        }
        serde_json::from_value(value).map_err(|e| bad(format!("not a feature cache manifest: {e}")))
    }

    /// What differs between this cache and `other` (the first difference
    /// found, in words), or `None` when they are the same.
    pub fn difference(&self, other: &CacheManifest) -> Option<&'static str> {
        let checks: [(bool, &'static str); 9] = [
            (self.encoder == other.encoder, "the encoder"),
            (
                self.encoder_digest == other.encoder_digest,
                "the encoder's weights",
            ),
            (
                (self.width, self.height) == (other.width, other.height),
                "the sample size",
            ),
            (
                (self.samples, self.shard_size) == (other.samples, other.shard_size),
                "the sample count or shard size",
            ),
            (self.data == other.data && self.mix == other.mix, "the data"),
            (self.seed == other.seed, "the seed"),
            (self.p_augment == other.p_augment, "the augmentation"),
            (self.zoom == other.zoom, "the zoom"),
            (
                self.sources_fingerprint == other.sources_fingerprint,
                "the source files",
            ),
        ];
        checks
            .into_iter()
            .find(|(same, _)| !same)
            .map(|(_, what)| what)
    }
}
