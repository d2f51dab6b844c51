//! The path tracer's speed on a fixed reference scene (5 objects of ~22k
//! triangles in all, 3 materials each split by photo channels, PBR and
//! principled materials, an HDRI), with the annotation. The scene can be
//! saved (JSON and world-space OBJ meshes) for
//! `scripts/bench-render-cycles.py`, which renders the same scene with
//! Blender Cycles.

use super::clock::{median, peak_rss_mib, process_cpu_seconds};
use crate::error::PipelineError;
use crate::materials::bundled_materials;
use crate::progress::Progress;
use crate::sources::assets_dir;
use matseg_extract::material_library::find_materials;
use matseg_image::outputs::StagedOutput;
use matseg_image::{Channel, Ramp};
use matseg_render::camera::Camera;
use matseg_render::mesh::Mesh;
use matseg_render::mesh_io::obj_text;
use matseg_render::primitives::Primitive;
use matseg_render::scene::{
    EnvironmentDescription, Layout, MapDescription, MaterialDescription, MeshSource, Normalise,
    ObjectDescription, SceneDescription, TransformDescription,
};
use matseg_render::texture::Placement;
use matseg_render::{render, LoadedScene, Vec3};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// What to measure.
#[derive(Clone, Debug)]
pub struct RenderBench {
    /// Image side in pixels (at least 8).
    pub size: u32,
    /// Samples per pixel (at least 1).
    pub spp: u32,
    /// Timed renders (the median is reported; at least 1).
    pub repeats: usize,
    /// Worker threads (0: all cores).
    pub threads: usize,
    /// Also write the scene (scene.json, object_K.obj, image.png) here.
    pub write_scene: Option<PathBuf>,
}

/// What the reference scene measured.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct RenderReport {
    /// Image side.
    pub size: u32,
    /// Samples per pixel.
    pub spp: u32,
    /// Triangles in the scene.
    pub triangles: usize,
    /// Threads rendering.
    pub threads: usize,
    /// Seconds to load the scene (meshes, materials, HDRI, BVH).
    pub load_seconds: f64,
    /// Median wall seconds of a render.
    pub render_seconds: f64,
    /// Median CPU seconds of a render.
    pub render_cpu_seconds: f64,
    /// Renders an hour a core could make.
    pub images_per_hour_per_core: f64,
    /// The process's peak resident memory, in MiB.
    pub peak_rss_mib: Option<f64>,
}

impl RenderBench {
    /// Renders the reference scene from the bundled assets (`progress`
    /// reports making the bundled materials the first time) and measures it.
    pub fn run(&self, progress: &dyn Progress) -> Result<RenderReport, PipelineError> {
        if self.size < 8 || self.spp < 1 || self.repeats < 1 {
            return Err(PipelineError::Settings(
                "the reference scene needs size >= 8, spp >= 1 and repeats >= 1".into(),
            ));
        }
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(self.threads)
            .build()
            .map_err(|e| PipelineError::Settings(format!("threads {}: {e}", self.threads)))?;
        let staged = self
            .write_scene
            .as_ref()
            .map(|dir| StagedOutput::begin(dir, "bench-render", &[&assets_dir()]))
            .transpose()?;
        let library = bundled_materials(progress)?;
        let materials = find_materials(&library)?;
        if materials.is_empty() {
            return Err(PipelineError::file(
                library.display(),
                "no bundled materials",
            ));
        }
        let assets = assets_dir();
        let photos: Vec<PathBuf> = ["coffee.jpg", "chelsea.jpg", "astronaut.jpg", "rocket.jpg"]
            .iter()
            .map(|f| assets.join("photos").join(f))
            .collect();
        let scene = reference_scene(
            &materials,
            &photos,
            &assets.join("hdris/forest.exr"),
            self.size,
            self.spp,
        );
        let start = Instant::now();
        let loaded = scene.load(Path::new(""))?;
        let load_seconds = start.elapsed().as_secs_f64();
        let (mut wall, mut cpu) = (Vec::new(), Vec::new());
        let mut last = None;
        for _ in 0..self.repeats {
            let (c0, t0) = (process_cpu_seconds(), Instant::now());
            let out = pool.install(|| render(&loaded))?;
            wall.push(t0.elapsed().as_secs_f64());
            if let (Some(a), Some(b)) = (c0, process_cpu_seconds()) {
                cpu.push(b - a);
            }
            last = Some(out);
        }
        if let (Some(staged), Some(out)) = (staged, &last) {
            let dir = staged.dir();
            let failed = |e: String| PipelineError::file(dir.display(), e);
            write_scene(dir, &scene, &loaded).map_err(|e| failed(e.to_string()))?;
            let img = matseg_render::tone_map(&out.radiance, out.width, out.height, 0.0);
            img.save(dir.join("image.png"))
                .map_err(|e| failed(e.to_string()))?;
            staged.finish()?;
        }
        let cpu = median(cpu);
        Ok(RenderReport {
            size: self.size,
            spp: self.spp,
            triangles: loaded.mesh.triangles.len(),
            threads: pool.current_num_threads(),
            load_seconds,
            render_seconds: median(wall),
            render_cpu_seconds: cpu,
            images_per_hour_per_core: 3600.0 / cpu,
            peak_rss_mib: peak_rss_mib(),
        })
    }
}

/// The objects of the reference scene: shape, bounding radius, centre.
fn reference_objects() -> [(Primitive, f32, Vec3); 5] {
    [
        (
            Primitive::Blob {
                seed: 7,
                bumps: 8,
                amplitude: 0.25,
            },
            40.0,
            Vec3::new(0.0, 0.0, 0.0),
        ),
        (
            Primitive::Torus { minor: 0.3 },
            25.0,
            Vec3::new(-55.0, -30.0, -10.0),
        ),
        (
            Primitive::Cylinder { height: 1.5 },
            20.0,
            Vec3::new(50.0, -35.0, -15.0),
        ),
        (
            Primitive::Cone { height: 2.0 },
            18.0,
            Vec3::new(-35.0, 50.0, 10.0),
        ),
        (
            Primitive::Box {
                size: [0.8, 0.6, 0.5],
            },
            22.0,
            Vec3::new(45.0, 45.0, 5.0),
        ),
    ]
}

/// The reference scene, from PBR material folders, photos and an HDRI.
pub fn reference_scene(
    materials: &[PathBuf],
    photos: &[PathBuf],
    hdri: &Path,
    size: u32,
    spp: u32,
) -> SceneDescription {
    let mut descriptions = Vec::new();
    let mut maps = Vec::new();
    let mut objects = Vec::new();
    let channels = [Channel::R, Channel::V, Channel::H, Channel::G, Channel::S];
    for (i, (shape, radius, centre)) in reference_objects().into_iter().enumerate() {
        let first = descriptions.len();
        for k in 0..3 {
            let index = 3 * i + k;
            let placement = Placement {
                scale: 0.25 + 0.1 * k as f32,
                rotation_deg: 30.0 * k as f32,
                offset: [0.1, 0.3],
            };
            descriptions.push(match index % 3 {
                0 | 1 => {
                    MaterialDescription::pbr(materials[index % materials.len()].clone(), placement)
                }
                _ => MaterialDescription {
                    pbr: None,
                    base_colour: Vec3::new(0.9, 0.6 + 0.05 * i as f32, 0.3),
                    roughness: 0.25,
                    metallic: (i % 2) as f32,
                    transmission: if i == 2 { 1.0 } else { 0.0 },
                    ior: 1.5,
                    bump: 0.02,
                    placement,
                },
            });
        }
        let mut split = |below: Layout, above: Layout, j: usize| {
            maps.push(MapDescription {
                photo: photos[(2 * i + j) % photos.len()].clone(),
                channel: channels[(2 * i + j) % channels.len()],
                normalise: Normalise::Max,
            });
            Layout::Split {
                map: maps.len() - 1,
                placement: Placement {
                    scale: 0.7,
                    rotation_deg: 45.0 * j as f32,
                    offset: [0.2, 0.1],
                },
                ramp: Ramp {
                    low: 0.45,
                    high: 0.5 + 0.1 * j as f32,
                },
                below: Box::new(below),
                above: Box::new(above),
            }
        };
        let inner = split(Layout::Material(first + 1), Layout::Material(first + 2), 1);
        let surface = split(Layout::Material(first), inner, 0);
        objects.push(ObjectDescription {
            mesh: MeshSource::Primitive(shape),
            uv_projection: None,
            radius: Some(radius),
            transform: TransformDescription {
                scale: 1.0,
                rotation_deg: Vec3::new(20.0 * i as f32, 10.0, 35.0 * i as f32),
                translation: centre,
            },
            surface,
            main: i == 0,
        });
    }
    SceneDescription {
        width: size,
        height: size,
        spp,
        seed: 1,
        max_bounces: 6,
        exposure_ev: 0.0,
        denoise: false,
        camera: Camera {
            position: Vec3::new(0.0, -230.0, 90.0),
            target: Vec3::ZERO,
            roll_deg: 0.0,
            focal_mm: 50.0,
        },
        environment: EnvironmentDescription {
            hdri: Some(hdri.to_path_buf()),
            colour: Vec3::ONE,
            strength: 1.0,
            rotation_deg: 120.0,
        },
        lights: vec![],
        materials: descriptions,
        maps,
        objects,
    }
}

/// Writes the scene description and each object's world-space mesh into
/// the (staged) folder `dir`.
fn write_scene(dir: &Path, scene: &SceneDescription, loaded: &LoadedScene) -> std::io::Result<()> {
    std::fs::write(dir.join("scene.json"), serde_json::to_vec_pretty(scene)?)?;
    for k in 0..scene.objects.len() {
        let mut mesh = Mesh::default();
        for (t, &object) in loaded.mesh.triangles.iter().zip(&loaded.triangle_object) {
            if object as usize == k {
                let base = mesh.positions.len() as u32;
                for &i in t {
                    let i = i as usize;
                    mesh.positions.push(loaded.mesh.positions[i]);
                    mesh.normals.push(loaded.mesh.normals[i]);
                    mesh.uvs.push(loaded.mesh.uvs[i]);
                }
                mesh.triangles.push([base, base + 1, base + 2]);
            }
        }
        std::fs::write(dir.join(format!("object_{k}.obj")), obj_text(&mesh))?;
    }
    Ok(())
}
