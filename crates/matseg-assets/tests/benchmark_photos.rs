//! The built-in table of benchmark photos is the benchmark's: one line per
//! image of `benchmarks/real-dev/images`, with its fingerprint
//! (`MATSEG_BLESS=1 cargo test -p matseg-assets --test benchmark_photos`
//! rewrites it after the benchmark changes); and the bundled photos are
//! none of them.

use matseg_assets::benchmark_photos::{benchmark_photo_of, benchmark_photos};
use matseg_image::fingerprint::Fingerprint;
use std::path::{Path, PathBuf};

fn repository() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// (file name, fingerprint) of the images in `dir`, sorted by name.
fn fingerprints(dir: &Path) -> Vec<(String, Fingerprint)> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".jpg") || n.ends_with(".png"))
        .collect();
    names.sort();
    names
        .into_iter()
        .map(|n| {
            let img = image::open(dir.join(&n)).unwrap().into_rgb8();
            (n, Fingerprint::of(&img))
        })
        .collect()
}

#[test]
fn the_table_holds_every_benchmark_photo() {
    let images = fingerprints(&repository().join("benchmarks/real-dev/images"));
    assert!(images.len() >= 40, "{} benchmark images", images.len());
    if std::env::var_os("MATSEG_BLESS").is_some() {
        let mut text = String::from(
            "# benchmarks/real-dev/images: NAME FINGERPRINT (matseg_image::fingerprint)\n",
        );
        for (name, print) in &images {
            text += &format!("{name} {}\n", print.to_hex());
        }
        std::fs::write(
            Path::new(env!("CARGO_MANIFEST_DIR")).join("benchmark-photos.txt"),
            text,
        )
        .unwrap();
        return;
    }
    let table: Vec<(String, String)> = benchmark_photos()
        .iter()
        .map(|(n, p)| (n.to_string(), p.to_hex()))
        .collect();
    let expected: Vec<(String, String)> = images
        .iter()
        .map(|(n, p)| (n.clone(), p.to_hex()))
        .collect();
    assert_eq!(
        table, expected,
        "benchmark-photos.txt is out of date: MATSEG_BLESS=1 cargo test -p matseg-assets --test benchmark_photos"
    );
    // Each benchmark photo is told apart from every other one.
    for (name, print) in &images {
        assert_eq!(benchmark_photo_of(print), Some(name.as_str()));
    }
}

#[test]
fn no_bundled_photo_is_a_benchmark_photo() {
    for dir in ["assets/photos", "assets/textures"] {
        for (name, print) in fingerprints(&repository().join(dir)) {
            assert_eq!(benchmark_photo_of(&print), None, "{dir}/{name}");
        }
    }
}
