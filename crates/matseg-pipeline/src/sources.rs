//! Where the pipeline's inputs come from: the bundled sample assets, the
//! corpus `matseg assets fetch` made in the user's cache, or the folders a
//! user names; and the photo and texture libraries scanned from them.

use matseg_extract::material_library::{colour_map, find_materials, MaterialError};
use matseg_image::{LibraryError, LicenceFilter, MemoryBudget, PhotoLibrary, SkippedFile};
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// Why the sources could not be resolved or scanned; the message names the
/// file or folder.
#[derive(Debug, thiserror::Error)]
pub enum SourceError {
    /// A photo or texture library could not be scanned.
    #[error(transparent)]
    Library(#[from] LibraryError),
    /// A folder of material folders could not be read.
    #[error(transparent)]
    Material(#[from] MaterialError),
    /// Neither `MATSEG_CACHE`, `XDG_CACHE_HOME` nor `HOME` is set.
    #[error("no cache folder: set MATSEG_CACHE")]
    NoCache,
    /// No folders of a kind were named, the corpus holds none, and the
    /// bundled assets are not where they were looked for.
    #[error(
        "{}: no such folder, and no {kind} were named nor fetched \
         (set MATSEG_ASSETS to the bundled assets, or run `matseg assets fetch`)",
        looked.display()
    )]
    NoDefault {
        /// The kind of source: photos, textures.
        kind: String,
        /// The bundled folder of that kind.
        looked: PathBuf,
    },
}

/// The user's matseg cache: `$MATSEG_CACHE`, else `$XDG_CACHE_HOME/matseg`,
/// else `~/.cache/matseg`.
pub fn cache_root() -> Result<PathBuf, SourceError> {
    let var = |k: &str| {
        std::env::var_os(k)
            .filter(|v| !v.is_empty())
            .map(PathBuf::from)
    };
    if let Some(dir) = var("MATSEG_CACHE") {
        return Ok(dir);
    }
    if let Some(dir) = var("XDG_CACHE_HOME") {
        return Ok(dir.join("matseg"));
    }
    var("HOME")
        .map(|home| home.join(".cache/matseg"))
        .ok_or(SourceError::NoCache)
}

/// Default bound on decoded source photos held in memory, per process.
pub const DEFAULT_CACHE_MB: usize = 2048;

/// The bundled sample assets: `$MATSEG_ASSETS`, else the repository's `assets/`.
pub fn assets_dir() -> PathBuf {
    std::env::var_os("MATSEG_ASSETS")
        .map(PathBuf::from)
        .unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("../../assets"))
}

/// The fetched corpus (`CACHE/corpus`), when it has a catalogue.
pub fn corpus_dir() -> Option<PathBuf> {
    let dir = cache_root().ok()?.join("corpus");
    dir.join(matseg_assets::catalogue::CATALOGUE_FILE)
        .is_file()
        .then_some(dir)
}

/// Where a job's sources come from when the user names none.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Defaults {
    /// The corpus `matseg assets fetch` made, for each kind it holds; the
    /// bundled sample set otherwise (generators and training).
    CorpusOrBundled,
    /// Always the bundled sample set (the demo and the benchmarks, whose
    /// results must not depend on what a machine has fetched).
    Bundled,
}

impl Defaults {
    /// The corpus folder of `kind` when these defaults take the corpus and
    /// it holds that kind.
    pub fn corpus_folder(self, kind: &str) -> Option<PathBuf> {
        if self != Defaults::CorpusOrBundled {
            return None;
        }
        corpus_dir().map(|c| c.join(kind)).filter(|d| d.is_dir())
    }

    /// The default folders of `kind` (`photos`, `textures`, `hdris`,
    /// `meshes`); empty when there are none.
    pub fn folders(self, kind: &str) -> Vec<PathBuf> {
        let folder = self
            .corpus_folder(kind)
            .or_else(|| Some(assets_dir().join(kind)).filter(|d| d.is_dir()));
        folder.into_iter().collect()
    }

    /// `given` when the user named any, else the default folders of `kind`.
    pub fn or(self, given: &[PathBuf], kind: &str) -> Vec<PathBuf> {
        if given.is_empty() {
            self.folders(kind)
        } else {
            given.to_vec()
        }
    }

    /// [`Defaults::or`] for a kind a job cannot do without: an error naming
    /// the bundled folder when there is no folder of `kind` at all.
    pub fn required(self, given: &[PathBuf], kind: &str) -> Result<Vec<PathBuf>, SourceError> {
        let folders = self.or(given, kind);
        if folders.is_empty() {
            return Err(SourceError::NoDefault {
                kind: kind.to_string(),
                looked: assets_dir().join(kind),
            });
        }
        Ok(folders)
    }
}

/// Texture sources: a folder of PBR material folders (from `matseg pbr`,
/// ambientCG, MatSeg or MatSynth) stands for the colour maps of its
/// materials; anything else (a texture library, image files) for itself.
fn texture_sources(given: &[PathBuf]) -> Result<Vec<PathBuf>, MaterialError> {
    let mut sources = Vec::new();
    for path in given {
        let materials = if path.is_dir() {
            find_materials(path)?
        } else {
            Vec::new()
        };
        if materials.is_empty() {
            sources.push(path.clone());
        }
        for dir in materials {
            sources.extend(colour_map(&dir)?);
        }
    }
    Ok(sources)
}

/// The photo and texture libraries a generator draws from.
pub struct Libraries {
    /// Map sources and backgrounds.
    pub photos: PhotoLibrary,
    /// Textures (and the colour maps of PBR materials).
    pub textures: PhotoLibrary,
    scan_skipped: Vec<SkippedFile>,
    budget: Arc<MemoryBudget>,
    roots: Vec<PathBuf>,
}

impl Libraries {
    /// Scans `photos` and `textures` (the `defaults` when empty) with
    /// `cache_mb` of decoded images between them, and keeps the files whose
    /// licence `licences` accepts. Unreadable files are skipped
    /// ([`Libraries::skipped_at_scan`]; those that fail to decode later:
    /// `PhotoLibrary::failures`); libraries with no photo that decodes are
    /// refused.
    pub fn load(
        photos: &[PathBuf],
        textures: &[PathBuf],
        cache_mb: usize,
        defaults: Defaults,
        licences: &LicenceFilter,
    ) -> Result<Self, SourceError> {
        let budget = MemoryBudget::new(cache_mb.saturating_mul(1 << 20));
        Self::load_within(photos, textures, budget, defaults, licences)
    }

    /// [`Libraries::load`] with the decoded images counted against
    /// `budget`, the process's budget that other caches share.
    pub fn load_within(
        photos: &[PathBuf],
        textures: &[PathBuf],
        budget: Arc<MemoryBudget>,
        defaults: Defaults,
        licences: &LicenceFilter,
    ) -> Result<Self, SourceError> {
        let photo_roots = defaults.required(photos, "photos")?;
        let texture_roots = defaults.required(textures, "textures")?;
        let (photos, r1) = PhotoLibrary::scan(&photo_roots, 0)?;
        let photos = photos.retain_licences(licences)?.sharing(budget.clone());
        let textures = texture_sources(&texture_roots)?;
        let (textures, r2) = PhotoLibrary::scan(&textures, 0)?;
        let textures = textures.retain_licences(licences)?.sharing(budget.clone());
        photos.ensure_usable()?;
        textures.ensure_usable()?;
        let scan_skipped = r1.skipped.into_iter().chain(r2.skipped).collect();
        Ok(Self {
            photos,
            textures,
            scan_skipped,
            budget,
            roots: photo_roots.into_iter().chain(texture_roots).collect(),
        })
    }

    /// The folders (or files) the photos and textures were scanned from:
    /// inputs that an output must not overlap.
    pub fn roots(&self) -> Vec<&Path> {
        self.roots.iter().map(PathBuf::as_path).collect()
    }

    /// The memory budget of the decoded images, to share with the
    /// process's other caches (the 3D renderer's `AssetCache::sharing`).
    pub fn budget(&self) -> Arc<MemoryBudget> {
        self.budget.clone()
    }

    /// The scene sources.
    pub fn sources(&self) -> matseg_scene::Sources<'_> {
        matseg_scene::Sources {
            photos: &self.photos,
            textures: &self.textures,
        }
    }

    /// Files found unreadable when the libraries were scanned.
    pub fn skipped_at_scan(&self) -> &[SkippedFile] {
        &self.scan_skipped
    }

    /// Files that failed to decode since the scan, photos then textures.
    pub fn failed_since_scan(&self) -> Vec<SkippedFile> {
        let mut failed = self.photos.failures();
        failed.extend(self.textures.failures());
        failed
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn material_folders_stand_for_their_colour_maps_and_other_paths_for_themselves() {
        let root = tempfile::tempdir().unwrap();
        let materials = root.path().join("materials");
        for name in ["b", "a"] {
            std::fs::create_dir_all(materials.join(name)).unwrap();
            std::fs::write(materials.join(name).join("Color.png"), b"").unwrap();
            std::fs::write(materials.join(name).join("Roughness.png"), b"").unwrap();
        }
        let plain = root.path().join("textures");
        std::fs::create_dir_all(&plain).unwrap();
        let file = root.path().join("one.jpg");
        let found = texture_sources(&[materials.clone(), plain.clone(), file.clone()]).unwrap();
        assert_eq!(
            found,
            [
                materials.join("a/Color.png"),
                materials.join("b/Color.png"),
                plain,
                file
            ]
        );
    }

    #[test]
    fn named_folders_win_over_the_defaults() {
        let given = [PathBuf::from("mine")];
        assert_eq!(Defaults::Bundled.or(&given, "photos"), given);
        assert_eq!(
            Defaults::Bundled.or(&[], "photos"),
            [assets_dir().join("photos")]
        );
        assert_eq!(Defaults::Bundled.corpus_folder("photos"), None);
    }
}
