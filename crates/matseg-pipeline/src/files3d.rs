//! The files the 3D generator draws from (photos, PBR materials, meshes,
//! HDRIs), found from the user's folders or the defaults, filtered by
//! licence, and each checked by decoding it once into the asset cache.

use crate::error::PipelineError;
use crate::materials::default_materials;
use crate::progress::Progress;
use crate::scenes::SceneFolders;
use crate::sources::Defaults;
use matseg_extract::material_library::find_materials;
use matseg_image::io::find_files;
use matseg_image::{licence_of, LicenceFilter, PhotoLibrary};
use matseg_render::cache::AssetCache;
use matseg_render::hdr_io::HDR_EXTENSIONS;
use matseg_render::mesh_io::MESH_EXTENSIONS;
use matseg_scene::{Recipe3d, Sources3d};
use rayon::prelude::*;
use std::path::{Path, PathBuf};

/// The checked files 3D scenes draw from.
pub struct Files3d {
    photos: Vec<PathBuf>,
    materials: Vec<PathBuf>,
    meshes: Vec<PathBuf>,
    hdris: Vec<PathBuf>,
    /// Files left out as unreadable, each as `FILE: problem`.
    pub skipped: Vec<String>,
}

impl Files3d {
    /// Finds the files of `folders` (or of `defaults`) whose licence
    /// `licences` accepts and keeps those that decode (into `cache`);
    /// default materials are made once from the default textures, with
    /// `progress` reporting it.
    pub fn load(
        folders: &SceneFolders,
        cache: &AssetCache,
        defaults: Defaults,
        licences: &LicenceFilter,
        progress: &dyn Progress,
    ) -> Result<Self, PipelineError> {
        let (library, report) =
            PhotoLibrary::scan(&defaults.required(&folders.photos, "photos")?, 0)
                .map_err(crate::sources::SourceError::from)?;
        let library = library
            .retain_licences(licences)
            .map_err(crate::sources::SourceError::from)?;
        let mut skipped: Vec<String> = report
            .skipped
            .iter()
            .map(|s| format!("{}: {}", s.path.display(), s.reason))
            .collect();
        let photos: Vec<PathBuf> = library.entries().iter().map(|e| e.path.clone()).collect();
        let material_roots = if folders.materials.is_empty() {
            vec![default_materials(defaults, progress)?]
        } else {
            folders.materials.clone()
        };
        let mut found = Vec::new();
        for root in &material_roots {
            if !root.is_dir() {
                return Err(PipelineError::file(root.display(), "no such folder"));
            }
            found.extend(find_materials(root)?);
        }
        let materials = licensed(found, licences, "materials")?;
        let materials = keep_readable(materials, &mut skipped, |p| cache.material(p).map(drop));
        let meshes = find(&defaults.or(&folders.meshes, "meshes"), &MESH_EXTENSIONS)?;
        let meshes = licensed(meshes, licences, "meshes")?;
        let meshes = keep_readable(meshes, &mut skipped, |p| cache.mesh(p).map(drop));
        let hdris = find(&defaults.or(&folders.hdris, "hdris"), &HDR_EXTENSIONS)?;
        let hdris = licensed(hdris, licences, "HDRIs")?;
        let hdris = keep_readable(hdris, &mut skipped, |p| cache.hdri(p).map(drop));
        Ok(Files3d {
            photos,
            materials,
            meshes,
            hdris,
            skipped,
        })
    }

    /// As scene sources.
    pub fn sources(&self) -> Sources3d<'_> {
        Sources3d {
            photos: &self.photos,
            materials: &self.materials,
            meshes: &self.meshes,
            hdris: &self.hdris,
        }
    }
}

/// The 3D recipe: defaults, then a TOML file, then the image side and the
/// samples per pixel when given.
pub fn recipe_3d(
    config: Option<&Path>,
    size: Option<u32>,
    spp: Option<u32>,
) -> Result<Recipe3d, PipelineError> {
    let mut recipe = match config {
        Some(path) => Recipe3d::from_toml_file(path)?,
        None => Recipe3d::default(),
    };
    recipe.size = size.unwrap_or(recipe.size);
    recipe.spp = spp.unwrap_or(recipe.spp);
    recipe
        .validate()
        .map_err(|e| PipelineError::Settings(format!("image size and spp: invalid recipe: {e}")))?;
    Ok(recipe)
}

/// The files under `roots` with one of `extensions`.
fn find(roots: &[PathBuf], extensions: &[&str]) -> Result<Vec<PathBuf>, PipelineError> {
    Ok(find_files(roots, extensions).map_err(crate::sources::SourceError::from)?)
}

/// The paths whose licence (from the `licenses.json` beside or inside
/// them) `filter` accepts; an error naming `what` when the filter removed
/// every one.
fn licensed(
    paths: Vec<PathBuf>,
    filter: &LicenceFilter,
    what: &str,
) -> Result<Vec<PathBuf>, PipelineError> {
    if filter.accepts_all() || paths.is_empty() {
        return Ok(paths);
    }
    let kept: Vec<PathBuf> = paths
        .into_iter()
        .filter(|p| filter.accepts(&licence_of(p)))
        .collect();
    if kept.is_empty() {
        return Err(PipelineError::setting(
            "licences",
            Some(filter),
            format!("none of the {what} has such a licence"),
        ));
    }
    Ok(kept)
}

/// The paths `check` accepts; the others go into `skipped` with why (in
/// parallel: the checks decode files).
fn keep_readable(
    paths: Vec<PathBuf>,
    skipped: &mut Vec<String>,
    check: impl Fn(&Path) -> Result<(), matseg_render::SceneError> + Sync,
) -> Vec<PathBuf> {
    let results: Vec<(PathBuf, Result<(), matseg_render::SceneError>)> = paths
        .into_par_iter()
        .map(|p| {
            let r = check(&p);
            (p, r)
        })
        .collect();
    let mut kept = Vec::new();
    for (path, result) in results {
        match result {
            Ok(()) => kept.push(path),
            Err(e) => skipped.push(e.to_string()),
        }
    }
    kept
}
