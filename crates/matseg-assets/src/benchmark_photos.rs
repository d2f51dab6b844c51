//! The photos of the project's real-photo benchmark (`benchmarks/real-dev`),
//! by [`Fingerprint`]: a benchmark photo is never a generator source, so the
//! corpus leaves out any photo of a package that is one of them, under
//! whatever name, size or compression it comes.
//!
//! The table (`benchmark-photos.txt`: a benchmark image's name and its
//! fingerprint a line) is checked against the benchmark's images by this
//! crate's tests, which rewrite it under `MATSEG_BLESS=1`.

use matseg_image::fingerprint::Fingerprint;

/// The table as built into matseg.
pub const TABLE: &str = include_str!("../benchmark-photos.txt");

/// (name, fingerprint) of every benchmark photo in [`TABLE`].
pub fn benchmark_photos() -> &'static [(&'static str, Fingerprint)] {
    static PHOTOS: std::sync::OnceLock<Vec<(&'static str, Fingerprint)>> =
        std::sync::OnceLock::new();
    PHOTOS.get_or_init(|| {
        TABLE
            .lines()
            .filter(|l| !l.trim().is_empty() && !l.starts_with('#'))
            .map(|line| {
                let (name, hex) = line.split_once(' ').expect("NAME HEX lines");
                (name, Fingerprint::from_hex(hex).expect("a fingerprint"))
            })
            .collect()
    })
}

/// The benchmark photo `photo` is, if any.
pub fn benchmark_photo_of(photo: &Fingerprint) -> Option<&'static str> {
    benchmark_photos()
        .iter()
        .find(|(_, print)| print.same_photo(photo))
        .map(|(name, _)| *name)
}
