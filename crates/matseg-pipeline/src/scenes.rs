//! The sources of generated scenes of either kind, loaded once: what
//! `matseg generate` and Python's `matseg.Generator` draw samples from.
//! Each front end builds the recipe from its own settings; loading the
//! files the recipe draws from and making the sample maker is done here.

use crate::error::PipelineError;
use crate::files3d::Files3d;
use crate::progress::Progress;
use crate::sources::{Defaults, Libraries};
use matseg_data::{Generator2d, Generator3d, SampleMaker};
use matseg_image::LicenceFilter;
use matseg_render::cache::AssetCache;
use matseg_scene::{CameraPath, Recipe2d, Recipe3d};
use std::path::PathBuf;

/// A scene recipe of either kind.
#[derive(Clone, Debug)]
pub enum SceneRecipe {
    /// Textures mixed by soft maps over a photo background.
    TwoD(Recipe2d),
    /// Objects carrying PBR materials, lit by HDRIs and path traced.
    ThreeD(Recipe3d),
}

/// The folders (or files) a user named for each kind of source; an empty
/// list means the defaults (the fetched corpus, else the bundled assets).
/// 2D scenes read `photos` and `textures`, 3D scenes `photos`,
/// `materials`, `meshes` and `hdris`.
#[derive(Clone, Debug, Default)]
pub struct SceneFolders {
    /// Photos (backgrounds and soft maps in 2D, channel maps in 3D).
    pub photos: Vec<PathBuf>,
    /// Texture folders (2D).
    pub textures: Vec<PathBuf>,
    /// Folders of PBR material folders (3D).
    pub materials: Vec<PathBuf>,
    /// Mesh files or folders, OBJ/OFF/PLY (3D).
    pub meshes: Vec<PathBuf>,
    /// HDRI files or folders, .hdr/.exr (3D).
    pub hdris: Vec<PathBuf>,
}

/// The loaded sources of one kind of scene, with its recipe.
pub enum SceneSources {
    /// 2D scenes: the photo and texture libraries.
    TwoD {
        /// The photo and texture libraries.
        libraries: Libraries,
        /// The 2D recipe.
        recipe: Recipe2d,
    },
    /// 3D scenes: the checked files and the cache that decodes them.
    ThreeD {
        /// The photos, materials, meshes and HDRIs that decode.
        files: Files3d,
        /// Decoded meshes, materials and HDRIs.
        cache: AssetCache,
        /// The 3D recipe.
        recipe: Recipe3d,
    },
}

impl SceneSources {
    /// Loads what `recipe` draws from: the files of `folders` (or of
    /// `defaults`) whose licence `licences` accepts, decoded within
    /// `cache_mb` MiB. Each unreadable file is reported as one
    /// `progress.warn` ("PATH: reason") and skipped.
    pub fn load(
        recipe: SceneRecipe,
        folders: &SceneFolders,
        cache_mb: usize,
        defaults: Defaults,
        licences: &LicenceFilter,
        progress: &dyn Progress,
    ) -> Result<Self, PipelineError> {
        match recipe {
            SceneRecipe::TwoD(recipe) => {
                let libraries = Libraries::load(
                    &folders.photos,
                    &folders.textures,
                    cache_mb,
                    defaults,
                    licences,
                )?;
                for s in libraries.skipped_at_scan() {
                    progress.warn(&format!("{}: {}", s.path.display(), s.reason));
                }
                Ok(Self::TwoD { libraries, recipe })
            }
            SceneRecipe::ThreeD(recipe) => {
                let cache = AssetCache::new(cache_mb.saturating_mul(1 << 20));
                let files = Files3d::load(folders, &cache, defaults, licences, progress)?;
                for s in &files.skipped {
                    progress.warn(s);
                }
                Ok(Self::ThreeD {
                    files,
                    cache,
                    recipe,
                })
            }
        }
    }

    /// Runs `f` with the sample maker of these sources; 3D scenes become
    /// sequences along `path` when given (2D scenes ignore it).
    pub fn with_maker<R>(
        &self,
        path: Option<&CameraPath>,
        f: impl FnOnce(&dyn SampleMaker) -> R,
    ) -> R {
        match self {
            Self::TwoD { libraries, recipe } => f(&Generator2d {
                recipe,
                sources: libraries.sources(),
            }),
            Self::ThreeD {
                files,
                cache,
                recipe,
            } => f(&Generator3d {
                recipe,
                sources: files.sources(),
                cache,
                path,
            }),
        }
    }

    /// How many source files were reported unreadable at load.
    pub fn skipped_at_load(&self) -> usize {
        match self {
            Self::TwoD { libraries, .. } => libraries.skipped_at_scan().len(),
            Self::ThreeD { files, .. } => files.skipped.len(),
        }
    }

    /// The photos that failed to decode since the load, as "PATH: reason"
    /// (3D files are all checked at load, so none for 3D).
    pub fn failed_since_load(&self) -> Vec<String> {
        match self {
            Self::TwoD { libraries, .. } => libraries
                .failed_since_scan()
                .iter()
                .map(|s| format!("{}: {}", s.path.display(), s.reason))
                .collect(),
            Self::ThreeD { .. } => Vec::new(),
        }
    }
}
