//! The repository's real-photo development benchmark (`benchmarks/real-dev`)
//! parses, every point lies inside its image (the loader checks), and it
//! keeps the shape it is documented to have: at least 40 photos and 600
//! points, 3-5 materials a photo, relations on at least a third of the
//! photos, a name for every material and a source line for every photo.

use matseg_eval::load_point_benchmark;
use std::collections::BTreeMap;
use std::path::Path;

fn bench_dir() -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../benchmarks/real-dev")
}

#[test]
fn real_dev_parses_with_its_documented_shape() {
    let bench = load_point_benchmark(&bench_dir(), false).unwrap();
    assert!(bench.skipped.is_empty());
    let images = bench.images.len();
    let points: usize = bench
        .images
        .iter()
        .flat_map(|i| &i.points)
        .map(Vec::len)
        .sum();
    let related = bench.images.iter().filter(|i| i.has_relations).count();
    assert!(images >= 40, "{images} photos");
    assert!(points >= 600, "{points} points");
    assert!(
        3 * related >= images,
        "{related} of {images} with relations"
    );
    for image in &bench.images {
        let materials = image.material_ids.len();
        assert!(
            (3..=5).contains(&materials),
            "{}: {materials} materials",
            image.name
        );
        assert!(
            image.points.iter().all(|p| p.len() >= 2),
            "{}: a material with fewer than two points",
            image.name
        );
    }
}

#[test]
fn every_material_is_named_and_every_photo_sourced() {
    let dir = bench_dir();
    let bench = load_point_benchmark(&dir, false).unwrap();
    let sources = std::fs::read_to_string(dir.join("SOURCES.md")).unwrap();
    for image in &bench.images {
        let path = dir.join("data").join(&image.name).join("labels.json");
        let labels: BTreeMap<String, String> =
            serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
        let named: Vec<&String> = labels.keys().collect();
        let ids: Vec<&String> = image.material_ids.iter().collect();
        let mut sorted_ids = ids.clone();
        sorted_ids.sort();
        assert_eq!(named, sorted_ids, "{}", path.display());
        assert!(
            sources.contains(&format!("| {} |", image.name)),
            "{}: no line in SOURCES.md",
            image.name
        );
    }
}
