//! A scene as data: everything a render needs (objects, their material
//! layouts, materials, photo maps, lights, environment, camera, settings)
//! in one JSON-serialisable description, and its loading into the
//! structures the path tracer reads. Relative file paths are resolved
//! against a base folder (the scene file's).

use crate::cache::AssetCache;
use crate::camera::Camera;
use crate::environment::{Environment, Light};
use crate::math::{Transform, Vec3};
use crate::mesh::{Mesh, UvProjection};
use crate::primitives::Primitive;
use crate::texture::{Placement, Texture};
use matseg_image::{Channel, Ramp};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// Everything one image is rendered from.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SceneDescription {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Samples per pixel.
    #[serde(default = "default_spp")]
    pub spp: u32,
    /// Seed of the pixel random streams.
    #[serde(default)]
    pub seed: u64,
    /// Longest path, in surface bounces.
    #[serde(default = "default_bounces")]
    pub max_bounces: u32,
    /// Exposure in stops, applied before tone mapping.
    #[serde(default)]
    pub exposure_ev: f32,
    /// Denoise the image (edge-aware, guided by normals and base colour;
    /// the annotation is never filtered).
    #[serde(default)]
    pub denoise: bool,
    /// The camera.
    pub camera: Camera,
    /// Light from far away.
    pub environment: EnvironmentDescription,
    /// Point and spot lights.
    #[serde(default)]
    pub lights: Vec<Light>,
    /// Materials, referred to by index from surface layouts.
    pub materials: Vec<MaterialDescription>,
    /// Photo channels, referred to by index from layout splits.
    #[serde(default)]
    pub maps: Vec<MapDescription>,
    /// The objects.
    pub objects: Vec<ObjectDescription>,
}

fn default_spp() -> u32 {
    16
}

fn default_bounces() -> u32 {
    6
}

/// The environment: an HDRI file, or a uniform colour when there is none.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct EnvironmentDescription {
    /// An equirectangular `.hdr` or `.exr`.
    #[serde(default)]
    pub hdri: Option<PathBuf>,
    /// Radiance when there is no HDRI.
    #[serde(default = "default_sky", rename = "color")]
    pub colour: Vec3,
    /// Multiplier.
    #[serde(default = "one")]
    pub strength: f32,
    /// Turn about the vertical axis, degrees.
    #[serde(default)]
    pub rotation_deg: f32,
}

fn default_sky() -> Vec3 {
    Vec3::splat(0.8)
}

fn one() -> f32 {
    1.0
}

/// A material: a PBR folder (colour, normal, height, roughness, metalness
/// maps) or constants, with a placement for its maps.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct MaterialDescription {
    /// A folder of PBR maps (any naming `matseg pbr` reads).
    #[serde(default)]
    pub pbr: Option<PathBuf>,
    /// Base colour (linear RGB) when there is no colour map.
    #[serde(default = "default_base", rename = "base_color")]
    pub base_colour: Vec3,
    /// Roughness when there is no roughness map.
    #[serde(default = "half")]
    pub roughness: f32,
    /// Metalness when there is no metalness map.
    #[serde(default)]
    pub metallic: f32,
    /// Fraction of light transmitted (glass-like), 0..1.
    #[serde(default)]
    pub transmission: f32,
    /// Index of refraction.
    #[serde(default = "default_ior")]
    pub ior: f32,
    /// Height-map bump strength (texture repeats per height unit).
    #[serde(default = "default_bump")]
    pub bump: f32,
    /// Where the maps sit on the surface.
    #[serde(default)]
    pub placement: Placement,
}

impl MaterialDescription {
    /// The PBR material in folder `dir` at `placement` (the constants, used
    /// for maps the folder lacks, at their defaults).
    pub fn pbr(dir: PathBuf, placement: Placement) -> Self {
        MaterialDescription {
            pbr: Some(dir),
            base_colour: default_base(),
            roughness: half(),
            metallic: 0.0,
            transmission: 0.0,
            ior: default_ior(),
            bump: default_bump(),
            placement,
        }
    }
}

fn default_base() -> Vec3 {
    Vec3::splat(0.5)
}

fn half() -> f32 {
    0.5
}

fn default_ior() -> f32 {
    1.45
}

fn default_bump() -> f32 {
    0.02
}

/// How a photo channel's levels become values in [0, 1].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Normalise {
    /// Divide by the channel's largest level.
    Max,
    /// Divide by 255.
    Range,
}

/// One channel of a natural photo, used as a field on surfaces.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct MapDescription {
    /// The photo.
    pub photo: PathBuf,
    /// Which channel.
    pub channel: Channel,
    /// How its levels are scaled to [0, 1].
    pub normalise: Normalise,
}

/// Which material is where on a surface: one material, or a split of the
/// surface by a photo channel through a ramp into two sub-layouts.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Layout {
    /// One material everywhere (index into the materials).
    Material(usize),
    /// `above` where the ramp of the map is 1, `below` where it is 0,
    /// mixed in between.
    Split {
        /// Index into the maps.
        map: usize,
        /// Where the photo sits on the surface.
        placement: Placement,
        /// The threshold ramp.
        ramp: Ramp,
        /// Layout where the map is low.
        below: Box<Layout>,
        /// Layout where the map is high.
        above: Box<Layout>,
    },
}

impl Layout {
    /// Every material index in the layout, in order of appearance.
    pub fn materials(&self, out: &mut Vec<usize>) {
        match self {
            Layout::Material(m) => {
                if !out.contains(m) {
                    out.push(*m)
                }
            }
            Layout::Split { below, above, .. } => {
                below.materials(out);
                above.materials(out);
            }
        }
    }
}

/// Where an object's triangles come from.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum MeshSource {
    /// An OBJ, OFF or PLY file.
    File(PathBuf),
    /// A procedural shape.
    Primitive(Primitive),
    /// A flat square of half-side 1 in the xy plane, facing up (ground).
    Plane,
}

/// An object: a mesh, its placement, and its surface layout.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ObjectDescription {
    /// The geometry.
    pub mesh: MeshSource,
    /// Replace the mesh's texture coordinates by a projection.
    #[serde(default)]
    pub uv_projection: Option<UvProjection>,
    /// Scale the mesh (centred) to this bounding radius before the transform.
    #[serde(default)]
    pub radius: Option<f32>,
    /// Uniform scale, rotation (degrees about x, y, z) and translation.
    #[serde(default)]
    pub transform: TransformDescription,
    /// Which material is where.
    pub surface: Layout,
    /// Whether this object is annotated (part of the main object).
    #[serde(default)]
    pub main: bool,
}

/// The parts of [`Transform::from_parts`].
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct TransformDescription {
    /// Uniform scale.
    #[serde(default = "one")]
    pub scale: f32,
    /// Euler angles in degrees.
    #[serde(default)]
    pub rotation_deg: Vec3,
    /// Translation.
    #[serde(default)]
    pub translation: Vec3,
}

impl Default for TransformDescription {
    fn default() -> Self {
        TransformDescription {
            scale: 1.0,
            rotation_deg: Vec3::ZERO,
            translation: Vec3::ZERO,
        }
    }
}

/// Whether `v` is a number above zero (NaN is not).
fn positive(v: f32) -> bool {
    v > 0.0 && v.is_finite()
}

/// A scene that cannot be loaded or rendered: the file or item, and what is
/// wrong.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// The scene file cannot be read or parsed.
    #[error("{}: {message}", path.display())]
    File {
        /// The scene file.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// A material folder it names cannot be read.
    #[error(transparent)]
    Material(#[from] matseg_extract::material_library::MaterialError),
    /// A photo it names cannot be read.
    #[error(transparent)]
    Image(#[from] matseg_image::ImageIoError),
    /// An HDRI it names cannot be read.
    #[error(transparent)]
    Hdr(#[from] crate::hdr_io::HdrError),
    /// A mesh it names cannot be read.
    #[error(transparent)]
    Mesh(#[from] crate::mesh_io::MeshError),
    /// The description breaks a rule (an index out of range, a size or
    /// scale out of bounds, a camera on its target); the message says which.
    #[error("{0}")]
    Invalid(String),
}

/// The decoded maps of a PBR material folder.
#[derive(Clone, Debug, Default)]
pub struct MaterialTextures {
    /// Colour map (sRGB).
    pub colour: Option<Texture>,
    /// Roughness map.
    pub roughness: Option<Texture>,
    /// Metalness map.
    pub metalness: Option<Texture>,
    /// Tangent-space normal map (OpenGL).
    pub normal: Option<Texture>,
    /// Height map (used for bump when there is no normal map).
    pub height: Option<Texture>,
}

impl MaterialTextures {
    /// Reads the maps of the material folder `dir`.
    pub fn read(dir: &Path) -> Result<Self, SceneError> {
        let maps = matseg_extract::material_library::read_material(dir)?;
        Ok(MaterialTextures {
            colour: Some(Texture::from_rgb(maps.colour)),
            roughness: maps.roughness.map(Texture::from_grey),
            metalness: maps.metalness.map(Texture::from_grey),
            normal: maps.normal.map(Texture::from_rgb),
            height: maps.height.map(Texture::from_grey),
        })
    }

    /// Bytes held.
    pub fn bytes(&self) -> usize {
        [
            &self.colour,
            &self.roughness,
            &self.metalness,
            &self.normal,
            &self.height,
        ]
        .iter()
        .filter_map(|t| t.as_ref().map(Texture::bytes))
        .sum()
    }
}

/// A material: its description and its decoded maps (none for a constant
/// material).
#[derive(Clone, Debug)]
pub struct LoadedMaterial {
    /// The description (constants, placement).
    pub description: MaterialDescription,
    /// The maps, shared through the asset cache.
    pub maps: Arc<MaterialTextures>,
}

/// A photo channel as levels, with its largest level.
#[derive(Clone, Debug)]
pub struct LoadedMap {
    /// The channel's levels.
    pub levels: Texture,
    /// The largest level.
    pub max_level: u8,
}

impl LoadedMap {
    /// Channel `channel` of the photo at `path`.
    pub fn read(path: &Path, channel: Channel) -> Result<Self, SceneError> {
        let img = matseg_image::io::read_rgb(path)?;
        let levels: Vec<u8> = img.pixels().map(|p| channel.level(p.0)).collect();
        Ok(LoadedMap {
            max_level: levels.iter().copied().max().unwrap_or(0),
            levels: Texture::from_levels(img.width() as usize, img.height() as usize, levels),
        })
    }

    /// The multiplier from a level's value in [0, 1] to the normalised value.
    pub fn scale(&self, normalise: Normalise) -> f32 {
        match normalise {
            Normalise::Max if self.max_level > 0 => 255.0 / self.max_level as f32,
            _ => 1.0,
        }
    }
}

/// A map in a scene: the shared channel and this scene's normalisation.
#[derive(Clone, Debug)]
pub struct SceneMap {
    /// The channel.
    pub map: Arc<LoadedMap>,
    /// Multiplier to the normalised value.
    pub scale: f32,
}

/// An object's layout and role after loading.
#[derive(Clone, Debug)]
pub struct LoadedObject {
    /// Which material is where.
    pub surface: Layout,
    /// Whether it is annotated.
    pub main: bool,
}

/// Everything decoded and in world space, ready to render.
#[derive(Clone, Debug)]
pub struct LoadedScene {
    /// The description it came from.
    pub description: SceneDescription,
    /// All objects' triangles in world space, one mesh.
    pub mesh: Mesh,
    /// The object of each triangle.
    pub triangle_object: Vec<u32>,
    /// Per object.
    pub objects: Vec<LoadedObject>,
    /// Per material.
    pub materials: Vec<LoadedMaterial>,
    /// Per map.
    pub maps: Vec<SceneMap>,
    /// The environment.
    pub environment: Environment,
    /// Materials of the main object(s), in annotation order.
    pub annotated: Vec<usize>,
}

impl SceneDescription {
    /// The materials of the main object(s), in annotation order: one mask
    /// each in a rendered sample.
    pub fn annotated_materials(&self) -> Vec<usize> {
        let mut annotated = Vec::new();
        for o in self.objects.iter().filter(|o| o.main) {
            o.surface.materials(&mut annotated);
        }
        annotated
    }

    /// Reads a scene file.
    pub fn read(path: &Path) -> Result<SceneDescription, SceneError> {
        let file = |message: String| SceneError::File {
            path: path.to_path_buf(),
            message,
        };
        let text = std::fs::read_to_string(path).map_err(|e| file(format!("cannot read: {e}")))?;
        serde_json::from_str(&text).map_err(|e| file(e.to_string()))
    }

    /// Checks indices and numbers before anything is decoded.
    pub fn validate(&self) -> Result<(), SceneError> {
        if self.width == 0 || self.height == 0 || self.width > 16384 || self.height > 16384 {
            return Err(SceneError::Invalid(format!(
                "image size {}x{} out of 1..16384",
                self.width, self.height
            )));
        }
        if self.spp == 0 {
            return Err(SceneError::Invalid("spp must be at least 1".into()));
        }
        if self.objects.is_empty() {
            return Err(SceneError::Invalid("no objects".into()));
        }
        fn check(
            layout: &Layout,
            materials: usize,
            maps: usize,
            object: usize,
        ) -> Result<(), SceneError> {
            match layout {
                Layout::Material(m) if *m >= materials => Err(SceneError::Invalid(format!(
                    "object {object}: material {m} of {materials}"
                ))),
                Layout::Material(_) => Ok(()),
                Layout::Split {
                    map,
                    below,
                    above,
                    placement,
                    ..
                } => {
                    if *map >= maps {
                        return Err(SceneError::Invalid(format!(
                            "object {object}: map {map} of {maps}"
                        )));
                    }
                    if !positive(placement.scale) {
                        return Err(SceneError::Invalid(format!(
                            "object {object}: map placement scale must be positive"
                        )));
                    }
                    check(below, materials, maps, object)?;
                    check(above, materials, maps, object)
                }
            }
        }
        for (i, o) in self.objects.iter().enumerate() {
            check(&o.surface, self.materials.len(), self.maps.len(), i)?;
            if o.radius.is_some_and(|r| !positive(r)) {
                return Err(SceneError::Invalid(format!(
                    "object {i}: radius must be positive"
                )));
            }
        }
        for (i, m) in self.materials.iter().enumerate() {
            if !positive(m.placement.scale) || !positive(m.ior) {
                return Err(SceneError::Invalid(format!(
                    "material {i}: placement scale and ior must be positive"
                )));
            }
        }
        Ok(())
    }

    /// Decodes every file (relative paths against `base`) and builds the
    /// world-space mesh.
    pub fn load(&self, base: &Path) -> Result<LoadedScene, SceneError> {
        self.load_cached(base, &AssetCache::default())
    }

    /// As [`SceneDescription::load`], taking decoded files from `cache`
    /// (and leaving new ones there).
    pub fn load_cached(&self, base: &Path, cache: &AssetCache) -> Result<LoadedScene, SceneError> {
        self.validate()?;
        let resolve = |p: &Path| {
            if p.is_absolute() {
                p.to_path_buf()
            } else {
                base.join(p)
            }
        };
        let mut mesh = Mesh::default();
        let mut triangle_object = Vec::new();
        for (i, o) in self.objects.iter().enumerate() {
            let mut m = match &o.mesh {
                MeshSource::File(p) => Mesh::clone(&*cache.mesh(&resolve(p))?),
                MeshSource::Primitive(p) => p.mesh(),
                MeshSource::Plane => crate::primitives::ground_plane(),
            };
            if let Some(projection) = o.uv_projection {
                m.project_uvs(projection);
            }
            if let Some(r) = o.radius {
                m.normalise_to_radius(r);
            }
            let t = &o.transform;
            m.transform(&Transform::from_parts(
                t.scale,
                t.rotation_deg,
                t.translation,
            ));
            triangle_object.extend(std::iter::repeat_n(i as u32, m.triangles.len()));
            mesh.append(&m);
        }
        let materials = self
            .materials
            .iter()
            .map(|d| {
                let maps = match &d.pbr {
                    Some(dir) => cache.material(&resolve(dir))?,
                    None => Arc::new(MaterialTextures::default()),
                };
                Ok(LoadedMaterial {
                    description: d.clone(),
                    maps,
                })
            })
            .collect::<Result<Vec<_>, SceneError>>()?;
        let maps = self
            .maps
            .iter()
            .map(|d| {
                let map = cache.map(&resolve(&d.photo), d.channel)?;
                let scale = map.scale(d.normalise);
                Ok(SceneMap { map, scale })
            })
            .collect::<Result<Vec<_>, SceneError>>()?;
        let env = &self.environment;
        let environment = match &env.hdri {
            Some(p) => {
                Environment::with_map(cache.hdri(&resolve(p))?, env.strength, env.rotation_deg)
            }
            None => Environment::uniform(env.colour * env.strength),
        };
        let annotated = self.annotated_materials();
        Ok(LoadedScene {
            description: self.clone(),
            mesh,
            triangle_object,
            objects: self
                .objects
                .iter()
                .map(|o| LoadedObject {
                    surface: o.surface.clone(),
                    main: o.main,
                })
                .collect(),
            materials,
            maps,
            environment,
            annotated,
        })
    }
}
