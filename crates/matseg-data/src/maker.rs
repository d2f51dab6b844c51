//! What makes the samples of a dataset: the 2D composer or the 3D builder
//! and renderer, behind one interface so the writer (folders or shards,
//! resume, sharding) is shared.

use crate::encode::{encode_sample, encode_scene, EncodedSample, SampleMeta};
use crate::generate::{sources_fingerprint, Fingerprint};
use crate::seed::sample_rng;
use matseg_image::licence_of;
use matseg_render::cache::AssetCache;
use matseg_render::scene::{MeshSource, SceneDescription};
use matseg_render::{render, tone_map};
use matseg_scene::{
    build_scene_3d, generate_2d, quantise_fractions, CameraPath, Recipe2d, Recipe3d, SourceRef,
    Sources, Sources3d,
};
use rand::Rng;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// Why a sample could not be made.
#[derive(Debug, thiserror::Error)]
pub enum SampleError {
    /// The 2D composer failed (a source that cannot be read).
    #[error(transparent)]
    Compose(#[from] matseg_scene::ComposeError),
    /// The 3D scene could not be drawn (no photos, a recipe out of range).
    #[error(transparent)]
    Scene(#[from] matseg_scene::Scene3dError),
    /// The 3D scene could not be loaded or rendered.
    #[error(transparent)]
    Render(#[from] matseg_render::SceneError),
}

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
    fn make(&self, seed: u64, index: u64) -> Result<EncodedSample, SampleError>;
}

/// 2D scenes (pipeline.md §2).
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

    fn make(&self, seed: u64, index: u64) -> Result<EncodedSample, SampleError> {
        let mut rng = sample_rng(seed, index);
        let scene = generate_2d(&mut rng, self.recipe, self.sources)?;
        Ok(encode_scene(&scene, seed, index, self.sources))
    }
}

/// 3D scenes (pipeline.md §3): drawn by the scene builder, rendered by the
/// path tracer, annotated from the primary hits.
pub struct Generator3d<'a> {
    /// The recipe.
    pub recipe: &'a Recipe3d,
    /// Photos, materials, meshes, HDRIs.
    pub sources: Sources3d<'a>,
    /// Decoded assets shared by the samples.
    pub cache: &'a AssetCache,
    /// Sequences (pipeline.md §3.4): sample `i` is frame `i % frames` of
    /// scene `i / frames`, seen along this path. `None`: one frame a scene.
    pub path: Option<&'a CameraPath>,
}

/// Where a frame of a sequence sits, as its sidecar records it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct FrameOf {
    /// The sequence (the scene drawn).
    pub sequence: u64,
    /// The frame, from 0.
    pub frame: u32,
    /// Frames in the sequence.
    pub frames: u32,
}

impl Generator3d<'_> {
    /// The scene description of sample `index`: scene `index` itself, or
    /// in a sequence the frame of its scene.
    pub fn describe(&self, seed: u64, index: u64) -> Result<SceneDescription, SampleError> {
        let (scene, frame) = match self.frame_of(index) {
            Some(f) => (f.sequence, Some(f.frame)),
            None => (index, None),
        };
        let mut rng = sample_rng(seed, scene);
        let render_seed: u64 = rng.random();
        let first = build_scene_3d(&mut rng, self.recipe, self.sources, render_seed)?;
        Ok(match (self.path, frame) {
            (Some(path), Some(frame)) => path.frame(&first, frame),
            _ => first,
        })
    }

    /// Which frame of which sequence sample `index` is (sequences only).
    pub fn frame_of(&self, index: u64) -> Option<FrameOf> {
        self.path.map(|path| {
            let frames = path.frames.max(1);
            FrameOf {
                sequence: index / frames as u64,
                frame: (index % frames as u64) as u32,
                frames,
            }
        })
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
        let recipe = serde_json::to_value(self.recipe).expect("recipe serialises");
        match self.path {
            None => recipe,
            Some(path) => serde_json::json!({ "scene": recipe, "camera_path": path }),
        }
    }

    fn sources_fingerprint(&self) -> String {
        let s = self.sources;
        let mut h = Fingerprint::default();
        for list in [s.photos, s.materials, s.meshes, s.hdris] {
            for p in list {
                let size = std::fs::metadata(p).map(|m| m.len()).unwrap_or(0);
                h.add(p.to_string_lossy().bytes().chain(size.to_le_bytes()));
            }
            h.end_list();
        }
        h.hex()
    }

    fn make(&self, seed: u64, index: u64) -> Result<EncodedSample, SampleError> {
        let scene = self.describe(seed, index)?;
        let loaded = scene.load_cached(Path::new(""), self.cache)?;
        let out = render(&loaded)?;
        let (w, h) = (out.width, out.height);
        let image = tone_map(&out.radiance, w, h, scene.exposure_ev);
        let annotation = quantise_fractions(w, h, &out.fractions, &out.roi);
        let scene_json = serde_json::to_value(&scene).expect("a scene description serialises");
        let mut meta = SampleMeta::new("3d", seed, index, scene_sources(&scene), scene_json);
        meta.frame = self.frame_of(index);
        Ok(encode_sample(index, &image, &annotation, &meta))
    }
}
