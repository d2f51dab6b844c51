//! The 3D scene builder (pipeline.md §3): draws a complete scene
//! description (main object(s) with a binary tree of natural-photo splits
//! deciding where each material is, PBR or principled materials, HDRI,
//! ground, distractors, lights, camera) from one seeded RNG. Rendering it
//! is `matseg_render`'s job; the description is the sample's recipe.

use crate::recipe3d::Recipe3d;
use matseg_extract::OutOfRange;
use matseg_image::{Channel, Ramp};
use matseg_render::camera::Camera;
use matseg_render::environment::Light;
use matseg_render::mesh::UvProjection;
use matseg_render::primitives::Primitive;
use matseg_render::scene::{
    EnvironmentDescription, Layout, MapDescription, MaterialDescription, MeshSource, Normalise,
    ObjectDescription, SceneDescription, TransformDescription,
};
use matseg_render::texture::Placement;
use matseg_render::Vec3;
use rand::seq::IndexedRandom;
use rand::Rng;
use std::path::PathBuf;

/// The files 3D scenes draw from.
#[derive(Clone, Copy, Debug)]
pub struct Sources3d<'a> {
    /// Natural photos: the channels that split surfaces into materials.
    pub photos: &'a [PathBuf],
    /// PBR material folders (may be empty: principled materials only).
    pub materials: &'a [PathBuf],
    /// Mesh files (may be empty: procedural primitives only).
    pub meshes: &'a [PathBuf],
    /// Equirectangular HDRIs (may be empty: a uniform sky of random colour).
    pub hdris: &'a [PathBuf],
}

fn uniform<R: Rng + ?Sized>(rng: &mut R, [lo, hi]: [f32; 2]) -> f32 {
    if hi > lo {
        rng.random_range(lo..hi)
    } else {
        lo
    }
}

fn count<R: Rng + ?Sized>(rng: &mut R, [lo, hi]: [u32; 2]) -> u32 {
    rng.random_range(lo..=hi)
}

/// A random procedural shape.
fn primitive<R: Rng + ?Sized>(rng: &mut R) -> Primitive {
    match rng.random_range(0..7) {
        0 => Primitive::Sphere,
        1 => Primitive::Torus {
            minor: rng.random_range(0.15..0.5),
        },
        2 => Primitive::Box {
            size: [
                rng.random_range(0.3..1.0),
                rng.random_range(0.3..1.0),
                rng.random_range(0.3..1.0),
            ],
        },
        3 => Primitive::Cylinder {
            height: rng.random_range(0.5..3.0),
        },
        4 => Primitive::Cone {
            height: rng.random_range(0.5..3.0),
        },
        5 => Primitive::Superquadric {
            e1: rng.random_range(0.2..2.0),
            e2: rng.random_range(0.2..2.0),
        },
        _ => Primitive::Blob {
            seed: rng.random(),
            bumps: rng.random_range(3..12),
            amplitude: rng.random_range(0.1..0.4),
        },
    }
}

/// With probability `p_mesh` (when there are mesh files) a mesh file, with
/// its own texture coordinates or a box or sphere projection (a third each),
/// else a procedural primitive with its own.
fn mesh_source<R: Rng + ?Sized>(
    rng: &mut R,
    recipe: &Recipe3d,
    sources: Sources3d,
) -> (MeshSource, Option<UvProjection>) {
    if !sources.meshes.is_empty() && rng.random_bool(recipe.p_mesh) {
        let file = sources.meshes.choose(rng).expect("not empty").clone();
        let projection = match rng.random_range(0..3) {
            0 => None,
            1 => Some(UvProjection::Box),
            _ => Some(UvProjection::Sphere),
        };
        (MeshSource::File(file), projection)
    } else {
        (MeshSource::Primitive(primitive(rng)), None)
    }
}

/// An object of bounding radius `radius` at `translation`, its mesh and
/// rotation drawn.
fn random_object<R: Rng + ?Sized>(
    rng: &mut R,
    recipe: &Recipe3d,
    sources: Sources3d,
    radius: f32,
    translation: Vec3,
    surface: Layout,
    main: bool,
) -> ObjectDescription {
    let (mesh, uv_projection) = mesh_source(rng, recipe, sources);
    ObjectDescription {
        mesh,
        uv_projection,
        radius: Some(radius),
        transform: TransformDescription {
            scale: 1.0,
            rotation_deg: random_rotation(rng),
            translation,
        },
        surface,
        main,
    }
}

fn random_rotation<R: Rng + ?Sized>(rng: &mut R) -> Vec3 {
    Vec3::new(
        rng.random_range(0.0..360.0),
        rng.random_range(0.0..360.0),
        rng.random_range(0.0..360.0),
    )
}

/// A material: a PBR from the library (none of `taken`, while others are
/// left) with a random placement, or a random principled one.
fn material<R: Rng + ?Sized>(
    rng: &mut R,
    recipe: &Recipe3d,
    sources: Sources3d,
    taken: &[MaterialDescription],
) -> MaterialDescription {
    let placement = Placement {
        scale: 10f32.powf(uniform(rng, recipe.pbr_scale_log10)),
        rotation_deg: rng.random_range(0.0..360.0),
        offset: [rng.random(), rng.random()],
    };
    if !sources.materials.is_empty() && rng.random_bool(recipe.p_pbr) {
        let free: Vec<&PathBuf> = sources
            .materials
            .iter()
            .filter(|dir| !taken.iter().any(|m| m.pbr.as_ref() == Some(*dir)))
            .collect();
        let dir = if free.is_empty() {
            sources.materials.choose(rng)
        } else {
            free.choose(rng).copied()
        };
        return MaterialDescription::pbr(dir.expect("not empty").clone(), placement);
    }
    let metal = rng.random_bool(recipe.p_metal);
    let transmissive = !metal && rng.random_bool(recipe.p_transmissive);
    MaterialDescription {
        pbr: None,
        base_colour: Vec3::new(rng.random(), rng.random(), rng.random()),
        roughness: rng.random(),
        metallic: if metal { 1.0 } else { 0.0 },
        transmission: if transmissive {
            rng.random_range(0.7..1.0)
        } else {
            0.0
        },
        ior: uniform(rng, recipe.ior),
        bump: 0.02,
        placement,
    }
}

/// A balanced binary tree of splits over `materials`, adding one photo
/// channel map per split.
fn split_tree<R: Rng + ?Sized>(
    rng: &mut R,
    recipe: &Recipe3d,
    sources: Sources3d,
    materials: &[usize],
    maps: &mut Vec<MapDescription>,
) -> Layout {
    if materials.len() == 1 {
        return Layout::Material(materials[0]);
    }
    let channel = if rng.random_bool(recipe.p_rgb_channel) {
        *Channel::RGB.choose(rng).expect("three")
    } else {
        *Channel::HSV.choose(rng).expect("three")
    };
    let normalise = if rng.random_bool(recipe.p_normalise_by_max) {
        Normalise::Max
    } else {
        Normalise::Range
    };
    maps.push(MapDescription {
        photo: sources
            .photos
            .choose(rng)
            .expect("build_scene_3d checks there are photos")
            .clone(),
        channel,
        normalise,
    });
    let map = maps.len() - 1;
    let placement = Placement {
        scale: 10f32.powf(uniform(rng, recipe.map_scale_log10)),
        rotation_deg: rng.random_range(0.0..360.0),
        offset: [rng.random(), rng.random()],
    };
    let ramp = if rng.random_bool(recipe.p_hard_split) {
        let t = uniform(rng, recipe.hard_threshold);
        Ramp { low: t, high: t }
    } else {
        let start = uniform(rng, recipe.soft_start);
        let width = rng.random_range(0.0..=recipe.soft_width_max) * start;
        Ramp {
            low: start,
            high: start + width,
        }
    };
    let (left, right) = materials.split_at(materials.len() / 2);
    let below = split_tree(rng, recipe, sources, left, maps);
    let above = split_tree(rng, recipe, sources, right, maps);
    Layout::Split {
        map,
        placement,
        ramp,
        below: Box::new(below),
        above: Box::new(above),
    }
}

/// Why a 3D scene cannot be drawn.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum Scene3dError {
    /// No natural photos, which split the surfaces into materials.
    #[error("3D scenes need natural photos to split surfaces into materials; none given")]
    NoPhotos,
    /// A recipe value out of its range.
    #[error("3D recipe: {0}")]
    Recipe(#[from] OutOfRange),
}

/// Draws one 3D scene: an error when `sources.photos` is empty or the
/// recipe is out of range.
pub fn build_scene_3d<R: Rng + ?Sized>(
    rng: &mut R,
    recipe: &Recipe3d,
    sources: Sources3d,
    seed: u64,
) -> Result<SceneDescription, Scene3dError> {
    recipe.validate()?;
    if sources.photos.is_empty() {
        return Err(Scene3dError::NoPhotos);
    }
    // Materials of the main object, then its layout.
    let k = if rng.random_bool(recipe.p_many_materials) {
        rng.random_range(recipe.materials_min..=recipe.materials_max)
    } else {
        2
    };
    let mut materials: Vec<MaterialDescription> = Vec::new();
    for _ in 0..k {
        let taken = if recipe.distinct_materials {
            materials.as_slice()
        } else {
            &[]
        };
        let m = material(rng, recipe, sources, taken);
        materials.push(m);
    }
    let mut maps = Vec::new();
    let indices: Vec<usize> = (0..k).collect();
    let layout = split_tree(rng, recipe, sources, &indices, &mut maps);

    // The main object: one, several merged, or several small ones; all
    // share the layout and are annotated together.
    let (parts, radius_range) = if rng.random_bool(recipe.p_single_object) {
        (1, recipe.single_radius)
    } else if rng.random_bool(recipe.p_merged_objects) {
        (count(rng, recipe.merged_count), recipe.merged_radius)
    } else {
        (count(rng, recipe.small_count), recipe.small_radius)
    };
    let mut objects = Vec::new();
    let mut extent = 0f32;
    for i in 0..parts {
        let radius = uniform(rng, radius_range);
        let offset = if i == 0 && parts == 1 {
            Vec3::ZERO
        } else {
            let d = rng.random_range(0.0..recipe.group_spread);
            let a: f32 = rng.random_range(0.0..std::f32::consts::TAU);
            Vec3::new(
                d * a.cos(),
                d * a.sin(),
                rng.random_range(-0.5..0.5) * recipe.group_spread,
            )
        };
        extent = extent.max(offset.length() + radius);
        objects.push(random_object(
            rng,
            recipe,
            sources,
            radius,
            offset,
            layout.clone(),
            true,
        ));
    }

    // The world: ground, distractors, lights, environment.
    let ground = rng.random_bool(recipe.p_ground) && !sources.materials.is_empty();
    if ground {
        let mut m = material(rng, recipe, sources, &[]);
        m.placement.scale = 10f32.powf(rng.random_range(-2.0..-0.5));
        materials.push(m);
        objects.push(ObjectDescription {
            mesh: MeshSource::Plane,
            uv_projection: None,
            radius: None,
            transform: TransformDescription {
                scale: 20.0 * extent,
                rotation_deg: Vec3::new(0.0, 0.0, rng.random_range(0.0..360.0)),
                translation: Vec3::new(0.0, 0.0, -extent),
            },
            surface: Layout::Material(materials.len() - 1),
            main: false,
        });
    }
    if rng.random_bool(recipe.p_distractors) {
        for _ in 0..count(rng, recipe.distractor_count) {
            let radius = uniform(rng, recipe.distractor_radius);
            materials.push(material(rng, recipe, sources, &[]));
            let d = extent + radius + rng.random_range(0.0..60.0);
            let a: f32 = rng.random_range(0.0..std::f32::consts::TAU);
            let z = if ground {
                -extent + radius
            } else {
                rng.random_range(-extent..extent)
            };
            let translation = Vec3::new(d * a.cos(), d * a.sin(), z);
            let surface = Layout::Material(materials.len() - 1);
            objects.push(random_object(
                rng,
                recipe,
                sources,
                radius,
                translation,
                surface,
                false,
            ));
        }
    }
    let mut lights = Vec::new();
    if rng.random_bool(recipe.p_extra_lights) {
        for _ in 0..count(rng, recipe.extra_light_count) {
            let d = extent * rng.random_range(2.5..5.0);
            let a: f32 = rng.random_range(0.0..std::f32::consts::TAU);
            let e: f32 = rng.random_range(0.3..1.4);
            let position = Vec3::new(d * e.cos() * a.cos(), d * e.cos() * a.sin(), d * e.sin());
            // Irradiance at the object of 0.5 to 3 (a bright sky gives ~3).
            let colour = Vec3::new(
                rng.random_range(0.7..1.0),
                rng.random_range(0.7..1.0),
                rng.random_range(0.7..1.0),
            );
            let intensity = colour * (rng.random_range(0.5..3.0) * d * d);
            lights.push(if rng.random_bool(0.5) {
                Light::Point {
                    position,
                    intensity,
                }
            } else {
                Light::Spot {
                    position,
                    target: Vec3::ZERO,
                    intensity,
                    angle_deg: rng.random_range(20.0..70.0),
                    blend: rng.random_range(0.0..0.5),
                }
            });
        }
    }
    let strength = if rng.random_bool(recipe.p_unit_strength) {
        1.0
    } else {
        uniform(rng, recipe.strength)
    };
    let environment = match sources.hdris.choose(rng) {
        Some(hdri) => EnvironmentDescription {
            hdri: Some(hdri.clone()),
            colour: Vec3::ONE,
            strength,
            rotation_deg: rng.random_range(0.0..360.0),
        },
        None => EnvironmentDescription {
            hdri: None,
            colour: Vec3::new(
                rng.random_range(0.3..1.0),
                rng.random_range(0.3..1.0),
                rng.random_range(0.3..1.0),
            ),
            strength,
            rotation_deg: 0.0,
        },
    };

    // The camera, outside the main object's bounding sphere, looking at it.
    let distance = extent + recipe.distance_unit * (2.0 + 3.0 * rng.random::<f32>());
    let u: f32 = rng.random();
    let mut elevation = (1.0 - recipe.elevation_drop * u * u) * 90.0;
    if ground {
        elevation = elevation.max(recipe.min_elevation_over_ground_deg);
    }
    let azimuth: f32 = rng.random_range(0.0..360.0);
    let (e, a) = (elevation.to_radians(), azimuth.to_radians());
    let position = Vec3::new(e.cos() * a.cos(), e.cos() * a.sin(), e.sin()) * distance;
    let camera = Camera {
        position,
        target: Vec3::ZERO,
        roll_deg: rng.random_range(-recipe.max_roll_deg..=recipe.max_roll_deg),
        focal_mm: recipe.focal_mm,
    };
    Ok(SceneDescription {
        width: recipe.size,
        height: recipe.size,
        spp: recipe.spp,
        seed,
        max_bounces: recipe.max_bounces,
        exposure_ev: 0.0,
        denoise: recipe.denoise,
        camera,
        environment,
        lights,
        materials,
        maps,
        objects,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;
    use std::path::Path;

    fn assets(sub: &str) -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../assets")
            .join(sub)
    }

    fn photos() -> Vec<PathBuf> {
        ["coffee.jpg", "chelsea.jpg", "astronaut.jpg"]
            .iter()
            .map(|f| assets("photos").join(f))
            .collect()
    }

    #[test]
    fn scenes_follow_the_recipe_and_are_reproducible() {
        let photos = photos();
        let hdris = vec![assets("hdris/forest.exr")];
        let sources = Sources3d {
            photos: &photos,
            materials: &[],
            meshes: &[],
            hdris: &hdris,
        };
        let recipe = Recipe3d::default();
        recipe.validate().unwrap();
        let mut many = 0;
        for seed in 0..200u64 {
            let draw = || {
                build_scene_3d(&mut ChaCha8Rng::seed_from_u64(seed), &recipe, sources, seed)
                    .unwrap()
            };
            let scene = draw();
            assert_eq!(scene, draw(), "seed {seed}");
            scene
                .validate()
                .unwrap_or_else(|e| panic!("seed {seed}: {e}"));
            let main: Vec<&ObjectDescription> = scene.objects.iter().filter(|o| o.main).collect();
            assert!(!main.is_empty());
            let mut used = Vec::new();
            main[0].surface.materials(&mut used);
            let k = used.len();
            assert!(k == 2 || (recipe.materials_min..=recipe.materials_max).contains(&k));
            many += (k > 2) as usize;
            assert_eq!(
                used,
                (0..k).collect::<Vec<_>>(),
                "main materials come first"
            );
            assert_eq!(scene.maps.len(), k - 1, "one photo split per tree node");
            assert!(main.iter().all(|o| o.surface == main[0].surface));
            // The camera is outside every main object's bounding sphere.
            for o in &main {
                let r = o.radius.unwrap();
                assert!((scene.camera.position - o.transform.translation).length() > r);
            }
        }
        assert!(
            (100..200).contains(&many),
            "K > 2 in about 85% x 6/7 of scenes: {many}"
        );
    }

    #[test]
    fn distinct_materials_never_repeat_a_pbr_on_the_main_object_and_off_change_nothing() {
        let photos = photos();
        let materials: Vec<PathBuf> = (0..4).map(|i| PathBuf::from(format!("pbr{i}"))).collect();
        let sources = Sources3d {
            photos: &photos,
            materials: &materials,
            meshes: &[],
            hdris: &[],
        };
        let plain = Recipe3d {
            p_pbr: 1.0,
            ..Recipe3d::default()
        };
        let distinct = Recipe3d {
            distinct_materials: true,
            ..plain.clone()
        };
        let main_pbrs = |scene: &SceneDescription| -> Vec<PathBuf> {
            let mut used = Vec::new();
            scene
                .objects
                .iter()
                .find(|o| o.main)
                .unwrap()
                .surface
                .materials(&mut used);
            used.iter()
                .filter_map(|&m| scene.materials[m].pbr.clone())
                .collect()
        };
        let mut repeats = 0;
        for seed in 0..100u64 {
            let draw = |recipe: &Recipe3d| {
                build_scene_3d(&mut ChaCha8Rng::seed_from_u64(seed), recipe, sources, seed).unwrap()
            };
            let pbrs = main_pbrs(&draw(&distinct));
            let mut unique = pbrs.clone();
            unique.sort();
            unique.dedup();
            // With more materials than PBR files some must repeat.
            assert_eq!(unique.len(), pbrs.len().min(materials.len()), "seed {seed}");
            let plain_pbrs = main_pbrs(&draw(&plain));
            let mut plain_unique = plain_pbrs.clone();
            plain_unique.sort();
            plain_unique.dedup();
            repeats += (plain_unique.len() < plain_pbrs.len().min(materials.len())) as usize;
        }
        assert!(repeats > 10, "without the option PBRs repeat: {repeats}");
        // Off, the recipe's JSON is as before the option existed.
        let json = serde_json::to_value(&plain).unwrap();
        assert!(json.get("distinct_materials").is_none());
        assert_eq!(
            serde_json::to_value(&distinct).unwrap()["distinct_materials"],
            true
        );
    }

    #[test]
    fn a_drawn_scene_renders_with_a_full_annotation() {
        let photos = photos();
        let sources = Sources3d {
            photos: &photos,
            materials: &[],
            meshes: &[],
            hdris: &[],
        };
        let mut recipe = Recipe3d {
            size: 24,
            spp: 2,
            ..Recipe3d::default()
        };
        recipe.p_single_object = 1.0;
        let scene = build_scene_3d(&mut ChaCha8Rng::seed_from_u64(5), &recipe, sources, 5).unwrap();
        let out = matseg_render::render(&scene.load(Path::new(".")).unwrap()).unwrap();
        assert!(out.roi.contains(&1.0), "the main object is in view");
        for i in 0..out.roi.len() {
            let sum: f32 = out.fractions.iter().map(|f| f[i]).sum();
            assert!((sum - out.roi[i]).abs() < 1e-5);
        }
    }

    #[test]
    fn no_photos_or_a_bad_recipe_is_an_error_not_a_panic() {
        let none = Sources3d {
            photos: &[],
            materials: &[],
            meshes: &[],
            hdris: &[],
        };
        let draw = |recipe: &Recipe3d, sources| {
            build_scene_3d(&mut ChaCha8Rng::seed_from_u64(1), recipe, sources, 1)
        };
        let recipe = Recipe3d::default();
        assert_eq!(draw(&recipe, none).unwrap_err(), Scene3dError::NoPhotos);
        let photos = photos();
        let some = Sources3d {
            photos: &photos,
            ..none
        };
        let bad = Recipe3d {
            p_mesh: 1.5,
            ..Recipe3d::default()
        };
        assert!(matches!(draw(&bad, some), Err(Scene3dError::Recipe(_))));
        assert!(draw(&recipe, some).is_ok());
    }
}
