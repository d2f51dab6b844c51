//! The photos the built-in manifest brings into the corpus, as
//! `corpus-photos.tsv` lists them (`matseg assets list --files photos`
//! after `matseg assets fetch`, rewritten when the manifest's photos
//! change): at least 150, each with a known licence, from a photo package
//! of the manifest, none of them a photo of the benchmark, none twice.

use matseg_assets::benchmark_photos::benchmark_photo_of;
use matseg_assets::{Kind, Manifest};
use matseg_image::fingerprint::Fingerprint;

const LIST: &str = include_str!("../corpus-photos.tsv");

#[test]
fn the_corpus_photos_are_licensed_and_none_is_a_benchmark_photo() {
    let manifest = Manifest::builtin();
    let photo_packages: Vec<&str> = manifest
        .select(&[Kind::Photos])
        .iter()
        .map(|p| p.name.as_str())
        .collect();
    let mut prints: Vec<(&str, Fingerprint)> = Vec::new();
    for line in LIST.lines().skip(1) {
        let fields: Vec<&str> = line.split('\t').collect();
        let [path, package, _version, licence, family, print] = fields[..] else {
            panic!("six fields: {line}");
        };
        assert!(path.starts_with("photos/"), "{path}");
        assert!(photo_packages.contains(&package), "{path}: {package}");
        assert!(
            !licence.is_empty() && family != "unknown",
            "{path}: {licence}"
        );
        assert_eq!(matseg_image::licence_family(licence), family, "{path}");
        let print = Fingerprint::from_hex(print).unwrap_or_else(|| panic!("{path}: fingerprint"));
        assert_eq!(
            benchmark_photo_of(&print),
            None,
            "{path} is a benchmark photo"
        );
        if let Some((first, _)) = prints.iter().find(|(_, p)| p.same_photo(&print)) {
            panic!("{path} is the same photo as {first}");
        }
        prints.push((path, print));
    }
    assert!(prints.len() >= 150, "{} photos", prints.len());
    // Every photo package of the manifest gives photos.
    for package in photo_packages {
        assert!(
            LIST.lines().any(|l| l.split('\t').nth(1) == Some(package)),
            "{package} gives no photo"
        );
    }
}
