//! What makes the samples of a dataset: the 2D composer or the 3D builder
//! and renderer, behind one interface so the writer (folders or shards,
//! resume, sharding) is shared.

use crate::encode::{
    distinct_licences, encode_sample, encode_scene, EncodedSample, SampleMeta, SIDECAR_VERSION,
};
use crate::generate::sources_fingerprint;
use crate::seed::sample_rng;
use matseg_image::licence_of;
use matseg_render::cache::AssetCache;
use matseg_render::scene::{MeshSource, SceneDescription};
use matseg_render::{render, tone_map};
use matseg_scene::{
    build_scene_3d, generate_2d, quantise_fractions, Recipe2d, Recipe3d, SourceRef, Sources,
    Sources3d,
};
use rand::Rng;
use std::path::{Path, PathBuf};

/// Makes sample `index` of a dataset seeded with `seed`; sample i depends
/// only on (seed, i) and the sources.
pub trait SampleMaker: Sync {
    /// Scene kind, as stored in the manifest and sidecars.
    fn kind(&self) -> &'static str;
    /// The recipe, as stored in the manifest.
    fn recipe(&self) -> serde_json::Value;
    /// A fingerprint of the source files, so a resumed run notices changes.
    fn sources_fingerprint(&self) -> String;
    /// The encoded sample, or why it could not be made.
    fn make(&self, seed: u64, index: u64) -> Result<EncodedSample, String>;
}

/// 2D scenes (SPEC section 2).
pub struct Generator2d<'a> {
    /// The recipe.
    pub recipe: &'a Recipe2d,
    /// Photos and textures.
    pub sources: Sources<'a>,
}

impl SampleMaker for Generator2d<'_> {
    fn kind(&self) -> &'static str {
        "2d"
    }

    fn recipe(&self) -> serde_json::Value {
        serde_json::to_value(self.recipe).expect("recipe serialises")
    }

    fn sources_fingerprint(&self) -> String {
        sources_fingerprint(self.sources)
    }

    fn make(&self, seed: u64, index: u64) -> Result<EncodedSample, String> {
        let mut rng = sample_rng(seed, index);
        let scene = generate_2d(&mut rng, self.recipe, self.sources).map_err(|e| e.to_string())?;
        Ok(encode_scene(&scene, seed, index, self.sources))
    }
}

/// 3D scenes (SPEC section 3): drawn by the scene builder, rendered by the
/// path tracer, annotated from the primary hits.
pub struct Generator3d<'a> {
    /// The recipe.
    pub recipe: &'a Recipe3d,
    /// Photos, materials, meshes, HDRIs.
    pub sources: Sources3d<'a>,
    /// Decoded assets shared by the samples.
    pub cache: &'a AssetCache,
}

impl Generator3d<'_> {
    /// The scene description of sample `index`.
    pub fn describe(&self, seed: u64, index: u64) -> SceneDescription {
        let mut rng = sample_rng(seed, index);
        let render_seed: u64 = rng.random();
        build_scene_3d(&mut rng, self.recipe, self.sources, render_seed)
    }
}

/// Every file a 3D scene uses, with its role and licence.
fn scene_sources(scene: &SceneDescription) -> Vec<SourceRef> {
    let entry = |role: &str, path: &Path| SourceRef {
        role: role.into(),
        file: path.display().to_string(),
        licence: licence_of(path),
    };
    let mut refs: Vec<SourceRef> = scene.maps.iter().map(|m| entry("map", &m.photo)).collect();
    refs.extend(
        scene
            .materials
            .iter()
            .filter_map(|m| m.pbr.as_ref())
            .map(|p| entry("material", p)),
    );
    refs.extend(scene.objects.iter().filter_map(|o| match &o.mesh {
        MeshSource::File(p) => Some(entry("mesh", p)),
        _ => None,
    }));
    refs.extend(scene.environment.hdri.iter().map(|p| entry("hdri", p)));
    refs
}

impl SampleMaker for Generator3d<'_> {
    fn kind(&self) -> &'static str {
        "3d"
    }

    fn recipe(&self) -> serde_json::Value {
        serde_json::to_value(self.recipe).expect("recipe serialises")
    }

    fn sources_fingerprint(&self) -> String {
        let s = self.sources;
        let mut h: u64 = 0xcbf2_9ce4_8422_2325;
        for list in [s.photos, s.materials, s.meshes, s.hdris] {
            for p in list {
                let size = std::fs::metadata(p).map(|m| m.len()).unwrap_or(0);
                for b in p.to_string_lossy().bytes().chain(size.to_le_bytes()) {
                    h = (h ^ b as u64).wrapping_mul(0x0100_0000_01b3);
                }
            }
            h = (h ^ 0xff).wrapping_mul(0x0100_0000_01b3);
        }
        format!("{h:016x}")
    }

    fn make(&self, seed: u64, index: u64) -> Result<EncodedSample, String> {
        let scene = self.describe(seed, index);
        let loaded = scene
            .load_cached(Path::new(""), self.cache)
            .map_err(|e| e.to_string())?;
        let out = render(&loaded)?;
        let (w, h) = (out.width, out.height);
        let image = tone_map(&out.radiance, w, h, scene.exposure_ev);
        let annotation = quantise_fractions(w, h, &out.fractions, &out.roi);
        let refs = scene_sources(&scene);
        let meta = SampleMeta {
            version: SIDECAR_VERSION,
            kind: "3d".into(),
            seed,
            index,
            licences: distinct_licences(&refs),
            sources: refs,
            scene: serde_json::to_value(&scene).map_err(|e| e.to_string())?,
        };
        Ok(encode_sample(index, &image, &annotation, &meta))
    }
}

/// The paths below `roots` whose extension is one of `extensions`
/// (case-insensitive), sorted; a root that is such a file counts itself.
pub fn files_with_extensions(
    roots: &[PathBuf],
    extensions: &[&str],
) -> Result<Vec<PathBuf>, String> {
    fn walk(dir: &Path, extensions: &[&str], out: &mut Vec<PathBuf>) -> Result<(), String> {
        let listing =
            std::fs::read_dir(dir).map_err(|e| format!("{}: cannot list: {e}", dir.display()))?;
        for entry in listing.filter_map(|e| e.ok()) {
            let path = entry.path();
            if path.is_dir() {
                walk(&path, extensions, out)?;
            } else if has_extension(&path, extensions) {
                out.push(path);
            }
        }
        Ok(())
    }
    let mut out = Vec::new();
    for root in roots {
        if root.is_dir() {
            walk(root, extensions, &mut out)?;
        } else if root.is_file() && has_extension(root, extensions) {
            out.push(root.clone());
        } else {
            return Err(format!("{}: no such folder", root.display()));
        }
    }
    out.sort();
    Ok(out)
}

fn has_extension(path: &Path, extensions: &[&str]) -> bool {
    path.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| extensions.iter().any(|x| x.eq_ignore_ascii_case(e)))
}
