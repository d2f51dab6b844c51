//! Golden test: a fixed seed and the bundled assets give a fixed image and
//! masks. On mismatch the actual output is written under the target folder;
//! `MATSEG_BLESS=1 cargo test` rewrites the golden files after a deliberate change.

mod common;

use matseg_image::io::{decode_grey, decode_rgb, encode_png_grey, encode_png_rgb};
use matseg_scene::{generate_2d, quantise_weights, Sources};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use std::path::{Path, PathBuf};

fn golden_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/golden")
}

#[test]
fn seed_7_scene_matches_golden_files() {
    let (photos, textures) = common::libraries();
    let sources = Sources {
        photos: &photos,
        textures: &textures,
    };
    let mut recipe = common::small_recipe();
    recipe.scene.materials_min = 3;
    recipe.scene.materials_max = 3;
    let scene = generate_2d(&mut ChaCha8Rng::seed_from_u64(7), &recipe, sources).unwrap();
    let q = quantise_weights(&scene.weights, &scene.background);
    let (w, h) = scene.image.dimensions();

    let mut files: Vec<(String, Vec<u8>)> =
        vec![("seed7.image.png".into(), encode_png_rgb(&scene.image))];
    for (k, m) in q.masks.iter().enumerate() {
        files.push((format!("seed7.mask{k}.png"), encode_png_grey(w, h, m)));
    }

    if std::env::var_os("MATSEG_BLESS").is_some() {
        for (name, bytes) in &files {
            std::fs::write(golden_dir().join(name), bytes).unwrap();
        }
        return;
    }
    let actual_dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("golden-actual");
    let mut mismatches = Vec::new();
    for (name, bytes) in &files {
        let path = golden_dir().join(name);
        let expected = std::fs::read(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        let same = if name.contains("image") {
            decode_rgb(&expected, &path).unwrap().as_raw() == scene.image.as_raw()
        } else {
            let k: usize = name["seed7.mask".len()..name.len() - 4].parse().unwrap();
            decode_grey(&expected, &path).unwrap().as_raw() == &q.masks[k]
        };
        if !same {
            std::fs::create_dir_all(&actual_dir).unwrap();
            std::fs::write(actual_dir.join(name), bytes).unwrap();
            mismatches.push(name.clone());
        }
    }
    assert!(
        mismatches.is_empty(),
        "{mismatches:?} differ from tests/golden; actual output in {}",
        actual_dir.display()
    );
}
