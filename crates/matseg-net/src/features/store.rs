//! A feature cache on disk: the manifest, shards written whole under a
//! temporary name, and random access to samples.

use super::record::CachedSample;
use super::{CacheManifest, MANIFEST_FILE, MEMBER_SUFFIX};
use crate::NetError;
use matseg_data::wds::{append_member, sample_key, shard_path};
use matseg_data::{index_tar, read_tar_member, TarMember};
use matseg_image::outputs::{temporary_path, Layout, SharedFolder, Sign};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::Arc;

fn file_error(path: &Path, message: impl std::fmt::Display) -> NetError {
    NetError::File {
        file: path.display().to_string(),
        message: message.to_string(),
    }
}

/// Samples `first..end` of shard `shard` under `manifest`.
fn shard_range(manifest: &CacheManifest, shard: u64) -> (u64, u64) {
    let first = shard * manifest.shard_size;
    (
        first,
        first
            .saturating_add(manifest.shard_size)
            .min(manifest.samples),
    )
}

/// An opened feature cache: its manifest and where each sample is.
#[derive(Clone, Debug)]
pub struct FeatureCache {
    dir: PathBuf,
    /// What the cache holds.
    pub manifest: CacheManifest,
    samples: Vec<(Arc<PathBuf>, TarMember)>,
}

impl FeatureCache {
    /// Opens the cache in `dir`: its manifest and every shard's index. A
    /// missing shard, one that is truncated, or one that is not this
    /// cache's is a one-line error naming it.
    pub fn open(dir: &Path) -> Result<Self, NetError> {
        let manifest = CacheManifest::read(dir)?;
        // The manifest's sample count is only a claim until the shards
        // hold as many: nothing of its size is made before they are read.
        let mut samples = Vec::new();
        for shard in 0..manifest.shards() {
            let path = shard_path(dir, shard);
            if !path.is_file() {
                return Err(file_error(
                    &path,
                    "missing: the cache is incomplete (run the matseg features command that \
                     made it again to finish it)",
                ));
            }
            let members = index_tar(&path).map_err(|e| file_error(&path, e))?;
            let (first, end) = shard_range(&manifest, shard);
            let expected = (first..end).map(|i| format!("{}.{MEMBER_SUFFIX}", sample_key(i)));
            let same = members.len() as u64 == end - first
                && members.iter().zip(expected).all(|(m, name)| m.name == name);
            if !same {
                return Err(file_error(
                    &path,
                    format!(
                        "not a shard of this cache: expected samples {first}..{end} as \
                         {} members, found {} members{}",
                        end - first,
                        members.len(),
                        members
                            .first()
                            .map_or(String::new(), |m| format!(" from {}", m.name))
                    ),
                ));
            }
            let shared = Arc::new(path);
            samples.extend(members.into_iter().map(|m| (shared.clone(), m)));
        }
        Ok(Self {
            dir: dir.to_path_buf(),
            manifest,
            samples,
        })
    }

    /// The cache's folder.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// Samples in the cache.
    pub fn len(&self) -> u64 {
        self.samples.len() as u64
    }

    /// True when the cache holds no sample.
    pub fn is_empty(&self) -> bool {
        self.samples.is_empty()
    }

    /// Reads sample `index` (below [`FeatureCache::len`]); a member that
    /// does not hold what the manifest says is an error naming it.
    pub fn get(&self, index: u64) -> Result<CachedSample, NetError> {
        let (path, member) = &self.samples[index as usize];
        let named = || format!("{}!{}", path.display(), member.name);
        let bytes = read_tar_member(path, member).map_err(|e| file_error(path, e))?;
        CachedSample::from_bytes(&bytes, &self.manifest, &named()).map_err(|e| NetError::File {
            file: named(),
            message: e.to_string(),
        })
    }
}

/// Whether `path`, an entry of a cache folder, is one a cache writer
/// writes: a shard, or one being written.
fn is_cache_entry(path: &Path) -> bool {
    let name = path.file_name().unwrap_or_default().to_string_lossy();
    name.strip_prefix("shard-")
        .and_then(|s| s.split_once(".tar"))
        .is_some_and(|(index, rest)| {
            !index.is_empty()
                && index.bytes().all(|b| b.is_ascii_digit())
                && (rest.is_empty() || rest.starts_with(".tmp"))
        })
}

/// Writes a cache's shards: the manifest first (or the check that the
/// folder's matches), then each shard whole.
pub struct CacheWriter {
    dir: PathBuf,
    manifest: CacheManifest,
}

impl CacheWriter {
    /// Starts (or continues) the cache `manifest` describes in `dir` (a
    /// folder `matseg features` adds to: matseg_image::outputs::SharedFolder).
    /// A folder holding a cache made with other settings, or anything but a
    /// cache's files, is refused.
    pub fn create(dir: &Path, manifest: CacheManifest) -> Result<Self, NetError> {
        let has_manifest = |d: &Path| d.join(MANIFEST_FILE).is_file();
        let layout = Layout {
            command: "features",
            sign: Sign::Own(&has_manifest),
            owns: &is_cache_entry,
        };
        let folder =
            SharedFolder::open(dir, &layout, &[]).map_err(|e| file_error(&e.path, e.message))?;
        let dir = folder.dir();
        let path = dir.join(MANIFEST_FILE);
        if path.is_file() {
            let have = CacheManifest::read(dir)?;
            if let Some(what) = have.difference(&manifest) {
                return Err(file_error(
                    &path,
                    format!(
                        "holds a cache made with other settings ({what} differs); choose \
                         another --out"
                    ),
                ));
            }
        } else {
            let json = serde_json::to_vec_pretty(&manifest).expect("a manifest serialises");
            matseg_image::outputs::write_atomic(&path, &json)
                .map_err(|e| file_error(&path, format!("cannot write: {e}")))?;
        }
        Ok(Self {
            dir: dir.to_path_buf(),
            manifest,
        })
    }

    /// What the cache holds.
    pub fn manifest(&self) -> &CacheManifest {
        &self.manifest
    }

    /// The shards not yet written, in order.
    pub fn missing_shards(&self) -> Vec<u64> {
        (0..self.manifest.shards())
            .filter(|&s| !shard_path(&self.dir, s).is_file())
            .collect()
    }

    /// The samples `first..end` of shard `shard`.
    pub fn shard_samples(&self, shard: u64) -> std::ops::Range<u64> {
        let (first, end) = shard_range(&self.manifest, shard);
        first..end
    }

    /// Writes shard `shard` from `samples` (its samples in order, each
    /// made when asked for): to a temporary file of this process, renamed
    /// when complete.
    /// On any error the temporary file is removed and the error names the
    /// shard.
    pub fn write_shard(
        &self,
        shard: u64,
        samples: impl IntoIterator<Item = Result<CachedSample, NetError>>,
    ) -> Result<(), NetError> {
        let path = shard_path(&self.dir, shard);
        // This process's own temporary file: two jobs making the same cache
        // never write into one file (each renames a complete shard).
        let tmp = PathBuf::from(format!(
            "{}.{}",
            temporary_path(&path).display(),
            std::process::id()
        ));
        let written = write_tar(&tmp, &path, self.shard_samples(shard), samples);
        if written.is_err() {
            let _ = std::fs::remove_file(&tmp);
        }
        written
    }
}

/// Writes `samples` (indices `range`) as a tar to `tmp`, then renames it
/// to `path`.
fn write_tar(
    tmp: &Path,
    path: &Path,
    range: std::ops::Range<u64>,
    samples: impl IntoIterator<Item = Result<CachedSample, NetError>>,
) -> Result<(), NetError> {
    let disk = |e: std::io::Error| file_error(path, format!("cannot write: {e}"));
    let file = std::fs::File::create(tmp).map_err(disk)?;
    let mut tar = tar::Builder::new(std::io::BufWriter::new(file));
    tar.mode(tar::HeaderMode::Deterministic);
    let mut count = 0;
    for (index, sample) in range.clone().zip(samples) {
        let name = format!("{}.{MEMBER_SUFFIX}", sample_key(index));
        append_member(&mut tar, &name, &sample?.to_bytes()).map_err(disk)?;
        count += 1;
    }
    if count != range.end - range.start {
        return Err(file_error(
            path,
            format!(
                "{count} samples made for a shard of {}",
                range.end - range.start
            ),
        ));
    }
    let mut out = tar.into_inner().map_err(disk)?;
    out.flush().map_err(disk)?;
    out.into_inner()
        .map_err(|e| disk(e.into_error()))?
        .sync_all()
        .map_err(disk)?;
    std::fs::rename(tmp, path).map_err(disk)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A manifest of `samples` samples, `shard_size` a shard, over one
    /// shard of two members named as its first two samples.
    fn cache(dir: &Path, samples: u64, shard_size: u64) -> Result<FeatureCache, NetError> {
        let manifest = CacheManifest {
            format: super::super::CACHE_FORMAT.into(),
            version: super::super::CACHE_VERSION,
            encoder: crate::EncoderConfig::MobilenetV2,
            encoder_digest: String::new(),
            model: "test".into(),
            width: 32,
            height: 32,
            taps: [1; 4],
            samples,
            shard_size,
            data: "online".into(),
            mix: None,
            seed: 0,
            zoom: crate::data::Zoom::Cover,
            p_augment: 0.0,
            sources_fingerprint: String::new(),
        };
        let json = serde_json::to_vec(&manifest).unwrap();
        std::fs::write(dir.join(MANIFEST_FILE), json).unwrap();
        let mut tar = tar::Builder::new(Vec::new());
        for i in 0..2 {
            let name = format!("{}.{MEMBER_SUFFIX}", sample_key(i));
            append_member(&mut tar, &name, b"").unwrap();
        }
        std::fs::write(shard_path(dir, 0), tar.into_inner().unwrap()).unwrap();
        FeatureCache::open(dir)
    }

    /// Manifests the property tests found: a sample count of 2^64 - 1 (a
    /// list of that many was made room for) and, with as large a shard
    /// size, the list of names the first shard should hold.
    #[test]
    fn sample_counts_that_lie_are_errors() {
        let dir = tempfile::tempdir().unwrap();
        assert_eq!(cache(dir.path(), 2, 2).unwrap().len(), 2);
        let err = cache(dir.path(), u64::MAX, 2).unwrap_err().to_string();
        assert!(err.contains("shard-000001.tar: missing"), "{err}");
        let err = cache(dir.path(), u64::MAX, u64::MAX)
            .unwrap_err()
            .to_string();
        assert!(err.contains("not a shard of this cache"), "{err}");
    }
}
