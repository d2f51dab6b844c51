//! Mask benchmarks (pipeline.md §9.3): photos with ground-truth masks, queried from
//! points sampled inside each mask and scored by IoU at the best threshold.
//!
//! Layout, one image per name in one folder:
//!
//! ```text
//! DATA_DIR/NAME.jpg (or .png)     the photo
//! DATA_DIR/NAME.mask0.png, ...    one 8-bit mask per material (>= 128 is inside)
//! DATA_DIR/NAME.roi.png           optional: only pixels >= 128 are scored
//! ```

use crate::points::BenchError;
use rand::{Rng, SeedableRng};
use std::path::{Path, PathBuf};

/// One photo of a mask benchmark and its mask files.
#[derive(Clone, Debug, PartialEq)]
pub struct MaskImage {
    /// The photo's name.
    pub name: String,
    /// The photo.
    pub image_path: PathBuf,
    /// Its masks, in index order.
    pub mask_paths: Vec<PathBuf>,
    /// Its region of interest, if given.
    pub roi_path: Option<PathBuf>,
}

/// Finds the photos of a mask benchmark and their masks (sorted by name).
/// A photo without `NAME.mask0.png` is an error, as is a gap in the mask
/// numbers.
pub fn scan_mask_benchmark(dir: &Path) -> Result<Vec<MaskImage>, BenchError> {
    let fail = |m: String| BenchError {
        path: dir.to_path_buf(),
        line: None,
        message: m,
    };
    let mut files: Vec<String> = std::fs::read_dir(dir)
        .map_err(|e| fail(format!("cannot list: {e}")))?
        .filter_map(|e| e.ok())
        .filter_map(|e| e.file_name().to_str().map(str::to_string))
        .collect();
    files.sort();
    let is_photo = |f: &String| {
        let lower = f.to_lowercase();
        (lower.ends_with(".jpg") || lower.ends_with(".jpeg") || lower.ends_with(".png"))
            && !f.contains(".mask")
            && !f.contains(".roi.")
    };
    let mut images = Vec::new();
    for photo in files.iter().filter(|f| is_photo(f)) {
        let name = photo
            .rsplit_once('.')
            .map_or(photo.as_str(), |(n, _)| n)
            .to_string();
        let mut mask_paths = Vec::new();
        while files.contains(&format!("{name}.mask{}.png", mask_paths.len())) {
            mask_paths.push(dir.join(format!("{name}.mask{}.png", mask_paths.len())));
        }
        let prefix = format!("{name}.mask");
        let listed = files.iter().filter(|f| f.starts_with(&prefix)).count();
        if mask_paths.is_empty() || listed != mask_paths.len() {
            return Err(BenchError {
                path: dir.join(photo),
                line: None,
                message: format!(
                    "expected masks {name}.mask0.png, {name}.mask1.png, ... numbered without gaps"
                ),
            });
        }
        let roi = format!("{name}.roi.png");
        images.push(MaskImage {
            image_path: dir.join(photo),
            roi_path: files.contains(&roi).then(|| dir.join(&roi)),
            name,
            mask_paths,
        });
    }
    if images.is_empty() {
        return Err(fail("no photos (NAME.jpg with NAME.mask0.png)".into()));
    }
    Ok(images)
}

/// How query points are drawn from a mask.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct QueryOptions {
    /// Points per mask (10 in the original).
    pub points_per_mask: usize,
    /// The mask is eroded by this many pixels (square neighbourhood) first.
    pub erosion: usize,
    /// Masks whose eroded area is below this many pixels are skipped.
    pub min_area: usize,
    /// Seed of the point draws.
    pub seed: u64,
}

impl Default for QueryOptions {
    fn default() -> Self {
        Self {
            points_per_mask: 10,
            erosion: 20,
            min_area: 400,
            seed: 0,
        }
    }
}

/// `mask` (row-major, `w x h`) eroded by `r`: a pixel stays when every
/// pixel within `r` in both directions is inside the mask and the image.
pub fn erode(mask: &[bool], w: usize, h: usize, r: usize) -> Vec<bool> {
    // Rows, then columns: a run of 2r + 1 inside pixels centred on the pixel.
    let pass = |src: &[bool], len: usize, lines: usize, at: &dyn Fn(usize, usize) -> usize| {
        let mut out = vec![false; src.len()];
        for line in 0..lines {
            let mut run = 0usize;
            for i in 0..len {
                run = if src[at(line, i)] { run + 1 } else { 0 };
                // Pixel i - r has r inside pixels on each side once the run
                // reaches 2r + 1 (pixels beyond the edge count as outside).
                if run > 2 * r {
                    out[at(line, i - r)] = true;
                }
            }
        }
        out
    };
    let rows = pass(mask, w, h, &|y, x| y * w + x);
    pass(&rows, h, w, &|x, y| y * w + x)
}

/// Up to `points_per_mask` query pixels `(x, y)` drawn uniformly from the
/// eroded mask, or nothing when it is smaller than `min_area`. The draw
/// depends only on the seed and the `(image, mask)` indices.
pub fn draw_mask_points(
    mask: &[bool],
    w: usize,
    h: usize,
    options: &QueryOptions,
    image: usize,
    mask_index: usize,
) -> Vec<(usize, usize)> {
    let inside: Vec<usize> = erode(mask, w, h, options.erosion)
        .iter()
        .enumerate()
        .filter_map(|(i, &m)| m.then_some(i))
        .collect();
    if inside.len() < options.min_area.max(1) {
        return Vec::new();
    }
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(options.seed);
    rng.set_stream(((image as u64) << 20) | mask_index as u64);
    (0..options.points_per_mask)
        .map(|_| {
            let i = inside[rng.random_range(0..inside.len())];
            (i % w, i / w)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn erosion_keeps_pixels_whose_neighbourhood_is_inside() {
        // A 6x5 block inside a 10x9 image.
        let (w, h) = (10, 9);
        let mask: Vec<bool> = (0..w * h)
            .map(|i| (2..8).contains(&(i % w)) && (2..7).contains(&(i / w)))
            .collect();
        let e = erode(&mask, w, h, 1);
        let kept: Vec<(usize, usize)> = (0..w * h)
            .filter(|&i| e[i])
            .map(|i| (i % w, i / w))
            .collect();
        let want: Vec<(usize, usize)> = (3..6).flat_map(|y| (3..7).map(move |x| (x, y))).collect();
        assert_eq!(kept, want);
        assert_eq!(erode(&mask, w, h, 0), mask);
        // Touching the border counts as outside.
        assert!(erode(&[true; 9], 3, 3, 1)[4]);
        assert!(!erode(&[true; 9], 3, 3, 1)[0]);
    }

    #[test]
    fn drawn_mask_points_lie_in_the_eroded_mask_and_are_seeded() {
        let (w, h) = (60, 50);
        let mask: Vec<bool> = (0..w * h).map(|i| i % w < 40).collect();
        let options = QueryOptions {
            erosion: 5,
            min_area: 100,
            ..QueryOptions::default()
        };
        let points = draw_mask_points(&mask, w, h, &options, 3, 1);
        assert_eq!(points.len(), 10);
        assert!(points
            .iter()
            .all(|&(x, y)| (5..35).contains(&x) && (5..45).contains(&y)));
        assert_eq!(points, draw_mask_points(&mask, w, h, &options, 3, 1));
        assert_ne!(points, draw_mask_points(&mask, w, h, &options, 3, 2));
        let strict = QueryOptions {
            min_area: 2000,
            ..options
        };
        assert!(draw_mask_points(&mask, w, h, &strict, 3, 1).is_empty());
    }
}
