//! End-to-end properties of the path tracer and its annotation.

use matseg_render::camera::Camera;
use matseg_render::primitives::Primitive;
use matseg_render::scene::{
    EnvironmentDescription, Layout, MapDescription, MaterialDescription, MeshSource, Normalise,
    ObjectDescription, SceneDescription, TransformDescription,
};
use matseg_render::texture::Placement;
use matseg_render::{render, tone_map, Vec3};
use std::path::{Path, PathBuf};

fn assets() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../assets")
}

fn material(colour: Vec3) -> MaterialDescription {
    MaterialDescription {
        pbr: None,
        base_colour: colour,
        roughness: 0.5,
        metallic: 0.0,
        transmission: 0.0,
        ior: 1.45,
        bump: 0.02,
        placement: Placement::default(),
    }
}

fn object(mesh: MeshSource, surface: Layout, main: bool) -> ObjectDescription {
    ObjectDescription {
        mesh,
        uv_projection: None,
        radius: None,
        transform: TransformDescription::default(),
        surface,
        main,
    }
}

/// A unit sphere seen from 4 units away, filling most of the image.
fn sphere_scene(size: u32, spp: u32) -> SceneDescription {
    SceneDescription {
        width: size,
        height: size,
        spp,
        seed: 3,
        max_bounces: 6,
        exposure_ev: 0.0,
        denoise: false,
        camera: Camera {
            position: Vec3::new(0.0, -4.0, 0.0),
            target: Vec3::ZERO,
            roll_deg: 0.0,
            focal_mm: 60.0,
        },
        environment: EnvironmentDescription {
            hdri: None,
            colour: Vec3::splat(0.5),
            strength: 1.0,
            rotation_deg: 0.0,
        },
        lights: vec![],
        materials: vec![
            material(Vec3::new(0.8, 0.2, 0.1)),
            material(Vec3::new(0.1, 0.3, 0.9)),
        ],
        maps: vec![MapDescription {
            photo: assets().join("photos/coffee.jpg"),
            channel: matseg_image::Channel::V,
            normalise: Normalise::Max,
        }],
        objects: vec![object(
            MeshSource::Primitive(Primitive::Sphere),
            Layout::Split {
                map: 0,
                placement: Placement {
                    scale: 0.5,
                    rotation_deg: 10.0,
                    offset: [0.1, 0.2],
                },
                ramp: matseg_image::Ramp {
                    low: 0.4,
                    high: 0.6,
                },
                below: Box::new(Layout::Material(0)),
                above: Box::new(Layout::Material(1)),
            },
            true,
        )],
    }
}

#[test]
fn a_white_lambertian_object_vanishes_in_a_white_furnace() {
    // 256 samples: per-pixel noise about 0.02.
    let mut scene = sphere_scene(12, 256);
    scene.max_bounces = 200;
    let mut white = material(Vec3::ONE);
    white.ior = 1.0; // no coating: a perfect Lambertian reflector
    scene.materials = vec![white];
    scene.maps.clear();
    scene.objects[0].surface = Layout::Material(0);
    let loaded = scene.load(Path::new(".")).unwrap();
    let out = render(&loaded).unwrap();
    let on_object: Vec<f32> = out
        .radiance
        .iter()
        .zip(&out.roi)
        .filter(|(_, &r)| r == 1.0)
        .map(|(c, _)| c.y)
        .collect();
    assert!(on_object.len() > 40, "the sphere fills the middle");
    let mean = on_object.iter().sum::<f32>() / on_object.len() as f32;
    assert!(
        (mean - 0.5).abs() < 0.005,
        "mean radiance on the object {mean}, the sky is 0.5"
    );
    for (c, _) in out.radiance.iter().zip(&out.roi) {
        assert!(
            (c.x - 0.5).abs() < 0.08 && (c.x - c.z).abs() < 1e-6,
            "{c:?}"
        );
    }
}

#[test]
fn fractions_sum_to_the_roi_and_are_soft_only_where_they_should_be() {
    let mut scene = sphere_scene(32, 8);
    // A ground plane under the sphere, not annotated.
    scene.objects.push(ObjectDescription {
        transform: TransformDescription {
            scale: 10.0,
            rotation_deg: Vec3::ZERO,
            translation: Vec3::new(0.0, 0.0, -1.0),
        },
        ..object(MeshSource::Plane, Layout::Material(0), false)
    });
    let out = render(&scene.load(Path::new(".")).unwrap()).unwrap();
    assert_eq!(out.annotated, vec![0, 1]);
    let (mut inside, mut outside, mut mixed, mut edge) = (0, 0, 0, 0);
    for i in 0..out.roi.len() {
        let sum: f32 = out.fractions.iter().map(|f| f[i]).sum();
        assert!(
            (sum - out.roi[i]).abs() < 1e-5,
            "pixel {i}: {sum} vs {}",
            out.roi[i]
        );
        match out.roi[i] {
            1.0 => inside += 1,
            0.0 => outside += 1,
            _ => edge += 1,
        }
        if out.fractions[0][i] > 0.05 && out.fractions[1][i] > 0.05 {
            mixed += 1;
        }
    }
    assert!(
        inside > 200 && outside > 200 && edge > 10,
        "{inside} {outside} {edge}"
    );
    assert!(
        mixed > 0,
        "the soft ramp and anti-aliasing mix materials somewhere"
    );
    // Both materials are visible.
    assert!(out.fractions.iter().all(|f| f.iter().sum::<f32>() > 20.0));
}

#[test]
fn one_material_gives_a_one_material_annotation() {
    let mut scene = sphere_scene(16, 4);
    scene.objects[0].surface = Layout::Material(1);
    let out = render(&scene.load(Path::new(".")).unwrap()).unwrap();
    assert_eq!(out.annotated, vec![1]);
    assert_eq!(out.fractions.len(), 1);
    assert_eq!(out.fractions[0], out.roi);
}

#[test]
fn renders_are_identical_whatever_the_thread_count() {
    let scene = sphere_scene(20, 4).load(Path::new(".")).unwrap();
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap()
        .install(|| render(&scene).unwrap());
    let two = rayon::ThreadPoolBuilder::new()
        .num_threads(2)
        .build()
        .unwrap()
        .install(|| render(&scene).unwrap());
    assert_eq!(one, two);
    let mut other = scene.clone();
    other.description.seed += 1;
    assert_ne!(
        render(&other).unwrap().radiance,
        one.radiance,
        "the seed matters"
    );
}

#[test]
fn a_tiny_scene_matches_its_golden_image() {
    let mut scene = sphere_scene(32, 4);
    scene.lights.push(matseg_render::environment::Light::Point {
        position: Vec3::new(-3.0, -3.0, 3.0),
        intensity: Vec3::splat(20.0),
    });
    scene.materials[1].metallic = 1.0;
    scene.materials[1].roughness = 0.3;
    let out = render(&scene.load(Path::new(".")).unwrap()).unwrap();
    let img = tone_map(&out.radiance, out.width, out.height, 0.0);
    let golden_path = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/golden/sphere_split.png");
    let actual_path =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../target/golden-actual/sphere_split.png");
    let golden = image::open(&golden_path).map(|g| g.to_rgb8());
    let matches = golden.as_ref().is_ok_and(|g| {
        g.dimensions() == img.dimensions()
            && g.as_raw()
                .iter()
                .zip(img.as_raw())
                .all(|(a, b)| (*a as i32 - *b as i32).abs() <= 2)
    });
    if !matches {
        std::fs::create_dir_all(actual_path.parent().unwrap()).unwrap();
        img.save(&actual_path).unwrap();
        panic!(
            "render differs from {} (actual: {})",
            golden_path.display(),
            actual_path.display()
        );
    }
}

#[test]
fn bundled_hdris_keep_the_dynamic_range_of_their_sources() {
    let dir = assets().join("hdris");
    let sources: Vec<serde_json::Value> =
        serde_json::from_str(&std::fs::read_to_string(dir.join("sources.json")).unwrap()).unwrap();
    assert!(!sources.is_empty());
    for s in sources {
        let file = s["file"].as_str().unwrap();
        let img = matseg_render::hdr_io::read_hdr(&dir.join(file)).unwrap();
        assert_eq!(
            (img.width as u64, img.height as u64),
            (s["width"].as_u64().unwrap(), s["height"].as_u64().unwrap())
        );
        let env = matseg_render::environment::Environment::new(img, 1.0, 0.0);
        let (max, mean) = env.radiance_stats();
        let (src_max, src_mean) = (
            s["max_luminance"].as_f64().unwrap() as f32,
            s["mean_luminance"].as_f64().unwrap() as f32,
        );
        // Half floats keep 11 bits of mantissa.
        assert!(
            (max - src_max).abs() <= 2e-3 * src_max,
            "{file}: max {max} vs {src_max}"
        );
        assert!(
            (mean - src_mean).abs() <= 2e-3 * src_mean,
            "{file}: mean {mean} vs {src_mean}"
        );
        assert!(src_max / src_mean > 50.0, "{file}: a real HDR range");
    }
}

#[test]
fn denoising_brings_a_noisy_render_closer_to_the_converged_one() {
    // One material: the noise is all in the lighting (the denoiser keeps
    // texture detail by filtering light divided by base colour, so noise in
    // a 2-sample estimate of fine texture stays).
    let mut scene = sphere_scene(32, 2);
    scene.objects[0].surface = Layout::Material(0);
    scene.lights.push(matseg_render::environment::Light::Point {
        position: Vec3::new(-3.0, -3.0, 3.0),
        intensity: Vec3::splat(20.0),
    });
    let noisy = render(&scene.load(Path::new(".")).unwrap()).unwrap();
    scene.spp = 256;
    let reference = render(&scene.load(Path::new(".")).unwrap()).unwrap();
    let denoised = matseg_render::denoise::denoise(&noisy);
    // Inside the object (coverage at edges is sampling, not noise).
    let inside: Vec<usize> = (0..noisy.roi.len())
        .filter(|&i| noisy.roi[i] == 1.0 && reference.roi[i] == 1.0)
        .collect();
    let error = |img: &[Vec3]| -> f32 {
        let d = |i: usize| img[i] - reference.radiance[i];
        inside.iter().map(|&i| d(i).dot(d(i))).sum::<f32>() / inside.len() as f32
    };
    let (before, after) = (error(&noisy.radiance), error(&denoised));
    assert!(
        after < 0.25 * before,
        "mean squared error {before} -> {after}"
    );
    // Pixels that see only the uniform sky keep its radiance: the filter
    // does not bleed the object into them.
    let sky = (0..noisy.roi.len()).filter(|&i| noisy.albedo[i] == Vec3::ZERO);
    let mut count = 0;
    for i in sky {
        assert!(
            (denoised[i] - Vec3::splat(0.5)).length() < 1e-2,
            "pixel {i}: {:?}",
            denoised[i]
        );
        count += 1;
    }
    assert!(count > 100);
}

#[test]
fn bundled_meshes_read_and_are_cc0_or_public_domain() {
    let dir = assets().join("meshes");
    let text = std::fs::read_to_string(dir.join("licenses.json")).unwrap();
    let licences: std::collections::BTreeMap<String, String> = serde_json::from_str(&text).unwrap();
    let paths = matseg_image::io::find_files(
        std::slice::from_ref(&dir),
        &matseg_render::mesh_io::MESH_EXTENSIONS,
    )
    .unwrap();
    let mut found = Vec::new();
    for path in paths {
        let name = path.file_name().unwrap().to_str().unwrap().to_string();
        let mesh = matseg_render::mesh_io::read_mesh(&path).unwrap();
        assert!(
            mesh.triangles.len() >= 100,
            "{name}: {} triangles",
            mesh.triangles.len()
        );
        assert_eq!(mesh.uvs.len(), mesh.positions.len(), "{name}");
        let licence = matseg_image::licence_of(&path);
        assert!(
            ["CC0-1.0", "public-domain"].contains(&licence.as_str()),
            "{name}: {licence}"
        );
        found.push(name);
    }
    found.sort();
    let listed: Vec<String> = licences.keys().cloned().collect();
    assert_eq!(found, listed, "meshes and licenses.json differ");
}
