//! Mask benchmarks (pipeline.md §9.3): photos with ground-truth masks, queried from
//! points sampled inside each mask and scored by IoU at the best threshold.
//!
//! matseg's layout, one image per name in one folder:
//!
//! ```text
//! DATA_DIR/NAME.jpg (or .png)     the photo
//! DATA_DIR/NAME.mask0.png, ...    one 8-bit mask per material (>= 128 is inside)
//! DATA_DIR/NAME.roi.png           optional: only pixels >= 128 are scored
//! ```
//!
//! or the layouts material-mask sets come in, photos and masks in two
//! folders, one mask per material:
//!
//! ```text
//! DATA_DIR/images/NAME.jpg (or .jpeg, .png)
//! DATA_DIR/masks/NAME.png                 one material
//! DATA_DIR/masks/NAME_1.png, NAME_2.png   one per material, numbered from 0 or 1
//! DATA_DIR/masks/NAME/1.png, 2.png        the same, a folder per photo
//! ```
//!
//! A mask of 0 and 1 only is read as 0 and 255.

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

/// Finds the photos of a mask benchmark and their masks (sorted by name),
/// in either layout (the module's doc). A photo without masks is an error,
/// as is a gap in the mask numbers, and a mask of no photo.
pub fn scan_mask_benchmark(dir: &Path) -> Result<Vec<MaskImage>, BenchError> {
    match dir.join(MASKS).is_dir() {
        true => scan_mask_folders(dir),
        false => scan_flat(dir),
    }
}

/// The folder of masks in the two-folder layout.
const MASKS: &str = "masks";

/// The folder of photos in the two-folder layout.
const IMAGES: &str = "images";

/// The names in folder `dir`, sorted, with whether each is a folder.
fn listed(dir: &Path) -> Result<Vec<(String, bool)>, BenchError> {
    let fail = |m: String| BenchError::new(dir, None, m);
    let mut names = Vec::new();
    for entry in std::fs::read_dir(dir).map_err(|e| fail(format!("cannot list: {e}")))? {
        let entry = entry.map_err(|e| fail(format!("cannot list: {e}")))?;
        let name = entry.file_name();
        let name = name
            .to_str()
            .ok_or_else(|| fail(format!("{name:?} is not UTF-8")))?;
        names.push((name.to_string(), entry.path().is_dir()));
    }
    names.sort();
    Ok(names)
}

/// Whether `file` is a photo by its extension.
fn is_photo_file(file: &str) -> bool {
    let lower = file.to_lowercase();
    lower.ends_with(".jpg") || lower.ends_with(".jpeg") || lower.ends_with(".png")
}

/// `file`'s name without its extension.
fn stem(file: &str) -> &str {
    file.rsplit_once('.').map_or(file, |(n, _)| n)
}

/// The paths of masks `(number, path)` in number order, when they are
/// numbered from 0 or 1 without gaps; otherwise an error naming `photo`,
/// whose masks they are.
fn numbered(mut numbers: Vec<(usize, PathBuf)>, photo: &Path) -> Result<Vec<PathBuf>, BenchError> {
    numbers.sort();
    let first = numbers.first().map_or(0, |n| n.0);
    let gapless = numbers
        .iter()
        .enumerate()
        .all(|(i, (k, _))| *k == first + i);
    if first > 1 || !gapless {
        let found: Vec<String> = numbers.iter().map(|n| n.0.to_string()).collect();
        let name = photo.file_stem().unwrap_or_default().to_string_lossy();
        return Err(BenchError::new(
            photo,
            None,
            format!(
                "the masks of {name} are numbered {}: number them from 0 or 1 without gaps",
                found.join(", ")
            ),
        ));
    }
    Ok(numbers.into_iter().map(|n| n.1).collect())
}

/// The masks found for one photo in the two-folder layout.
#[derive(Default)]
struct FoundMasks {
    /// `masks/NAME.png`.
    single: Vec<PathBuf>,
    /// `masks/NAME_K.png` and `masks/NAME/K.png`, with their numbers.
    numbered: Vec<(usize, PathBuf)>,
}

/// The two-folder layout: `images/` and `masks/`.
fn scan_mask_folders(dir: &Path) -> Result<Vec<MaskImage>, BenchError> {
    let (images, masks) = (dir.join(IMAGES), dir.join(MASKS));
    if !images.is_dir() {
        return Err(BenchError::new(
            &images,
            None,
            "missing: a benchmark with masks/ keeps its photos in images/",
        ));
    }
    let photos: Vec<String> = listed(&images)?
        .into_iter()
        .filter(|(f, folder)| !folder && is_photo_file(f))
        .map(|(f, _)| f)
        .collect();
    let names: std::collections::BTreeSet<&str> = photos.iter().map(|f| stem(f)).collect();
    if names.len() != photos.len() {
        return Err(BenchError::new(
            &images,
            None,
            "two photos share a name (NAME.jpg and NAME.png)",
        ));
    }
    // Each mask file, by photo: NAME.png, NAME_K.png, NAME/K.png.
    let mut found: std::collections::BTreeMap<&str, FoundMasks> =
        names.iter().map(|n| (*n, FoundMasks::default())).collect();
    for (file, folder) in listed(&masks)? {
        let path = masks.join(&file);
        let orphan = || {
            BenchError::new(
                &path,
                None,
                format!(
                    "no photo of this mask in {}: masks are NAME.png, NAME_K.png or NAME/K.png for a photo images/NAME.jpg",
                    images.display()
                ),
            )
        };
        if folder {
            let entry = found.get_mut(file.as_str()).ok_or_else(orphan)?;
            for (inner, inner_folder) in listed(&path)? {
                let number = stem(&inner).parse::<usize>().ok();
                match (inner_folder, number, inner.to_lowercase().ends_with(".png")) {
                    (false, Some(k), true) => entry.numbered.push((k, path.join(&inner))),
                    _ => return Err(BenchError::new(
                        &path.join(&inner),
                        None,
                        "not a numbered mask: a photo's folder of masks holds 0.png, 1.png, ...",
                    )),
                }
            }
            continue;
        }
        if !file.to_lowercase().ends_with(".png") {
            return Err(BenchError::new(&path, None, "not a PNG mask"));
        }
        let name = stem(&file);
        if let Some(entry) = found.get_mut(name) {
            entry.single.push(path);
            continue;
        }
        let numbered_of = name
            .rsplit_once('_')
            .and_then(|(photo, k)| Some((photo, k.parse::<usize>().ok()?)));
        match numbered_of.and_then(|(photo, k)| Some((found.get_mut(photo)?, k))) {
            Some((entry, k)) => entry.numbered.push((k, path)),
            None => return Err(orphan()),
        }
    }
    let mut out = Vec::new();
    for photo in &photos {
        let name = stem(photo);
        let image_path = images.join(photo);
        let FoundMasks {
            single,
            numbered: many,
        } = found.remove(name).expect("every photo listed");
        let fail = |m: String| BenchError::new(&image_path, None, m);
        let mask_paths = match (single.len(), many.len()) {
            (0, 0) => {
                return Err(fail(format!(
                    "no mask: expected {MASKS}/{name}.png, {MASKS}/{name}_1.png, ... or {MASKS}/{name}/1.png, ..."
                )))
            }
            (1, 0) => single,
            (0, _) => numbered(many, &image_path)?,
            _ => {
                return Err(fail(format!(
                    "masks in two layouts: {MASKS}/{name}.png beside numbered masks"
                )))
            }
        };
        out.push(MaskImage {
            name: name.to_string(),
            image_path,
            mask_paths,
            roi_path: None,
        });
    }
    if out.is_empty() {
        return Err(BenchError::new(
            &images,
            None,
            "no photos (.jpg, .jpeg or .png)",
        ));
    }
    Ok(out)
}

/// matseg's layout: photos, masks and ROIs side by side.
fn scan_flat(dir: &Path) -> Result<Vec<MaskImage>, BenchError> {
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
    let is_photo = |f: &String| is_photo_file(f) && !f.contains(".mask") && !f.contains(".roi.");
    let mut images = Vec::new();
    for photo in files.iter().filter(|f| is_photo(f)) {
        let name = stem(photo).to_string();
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
