//! Point benchmarks in the MatSeg format (pipeline.md §9.1):
//!
//! ```text
//! BENCH_DIR/images/NAME.jpg                 (or .jpeg, .png)
//! BENCH_DIR/data/NAME/data.json             {"1": {"pt_im": [[x, y, r], ...]}, "2": ...}
//! BENCH_DIR/data/NAME/group_relations.txt   optional: "[1, 2]" (0.6) or "(1, 3)" (0.3) per line
//! ```
//!
//! Points of one material id are the same material (weight 1); a relation
//! line gives every pair of its ids a partial weight; other pairs weigh 0.

use crate::annotation::{find_image, Annotation, DATA_FILE};
use std::path::{Path, PathBuf};

/// Weight of a `[...]` relation.
pub const SQUARE_RELATION: f64 = 0.6;
/// Weight of a `(...)` relation.
pub const ROUND_RELATION: f64 = 0.3;

/// A benchmark problem: a one-line message naming the file (and line).
#[derive(Debug, thiserror::Error)]
#[error("{}{}: {message}", path.display(), line.map(|l| format!(":{l}")).unwrap_or_default())]
pub struct BenchError {
    /// The file at fault.
    pub path: PathBuf,
    /// Its line, for text files.
    pub line: Option<usize>,
    /// What is wrong.
    pub message: String,
}

impl BenchError {
    /// A problem of the file `path` (at `line`, for text files).
    pub fn new(path: &Path, line: Option<usize>, message: impl Into<String>) -> Self {
        Self {
            path: path.to_path_buf(),
            line,
            message: message.into(),
        }
    }
}

impl From<matseg_image::ImageIoError> for BenchError {
    fn from(e: matseg_image::ImageIoError) -> Self {
        Self {
            path: e.path,
            line: None,
            message: e.message,
        }
    }
}

/// One annotated point: centre and radius in image pixels.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BenchPoint {
    /// Column.
    pub x: f32,
    /// Row.
    pub y: f32,
    /// Radius of the disc the point stands for.
    pub r: f32,
}

/// One image of a point benchmark.
#[derive(Clone, Debug, PartialEq)]
pub struct BenchImage {
    /// The image's name (its data folder).
    pub name: String,
    /// The image file.
    pub image_path: PathBuf,
    /// Material ids, in the order of `points` and `weights`.
    pub material_ids: Vec<String>,
    /// The points of each material.
    pub points: Vec<Vec<BenchPoint>>,
    /// Weight between materials `i` and `j` (1 on the diagonal).
    pub weights: Vec<Vec<f64>>,
    /// Whether the image has relations (it takes part in the Soft subset).
    pub has_relations: bool,
}

/// A loaded benchmark, and the images left out with `skip_bad`.
#[derive(Clone, Debug, Default)]
pub struct PointBenchmark {
    /// The images, sorted by name.
    pub images: Vec<BenchImage>,
    /// Images left out, with the problem that excluded each.
    pub skipped: Vec<String>,
}

/// Whether `dir` is laid out as a point benchmark (`images/` and `data/`)
/// rather than a mask benchmark, for commands that take either.
pub fn is_point_benchmark(dir: &Path) -> bool {
    dir.join("images").is_dir() && dir.join("data").is_dir()
}

/// Loads the benchmark in `dir`. A malformed image (unreadable or missing
/// file, bad JSON, a point outside the image, a bad relation line, an
/// unknown material id) is an error, or with `skip_bad` a skipped image.
pub fn load_point_benchmark(dir: &Path, skip_bad: bool) -> Result<PointBenchmark, BenchError> {
    let data = dir.join("data");
    let mut names: Vec<String> = std::fs::read_dir(&data)
        .map_err(|e| BenchError::new(&data, None, format!("cannot list benchmark data: {e}")))?
        .filter_map(|e| e.ok())
        .filter(|e| e.path().is_dir())
        .filter_map(|e| e.file_name().to_str().map(str::to_string))
        .collect();
    names.sort();
    if names.is_empty() {
        return Err(BenchError::new(&data, None, "no image folders"));
    }
    let mut bench = PointBenchmark::default();
    for name in names {
        match load_image(dir, &name) {
            Ok(image) => bench.images.push(image),
            Err(e) if skip_bad => bench.skipped.push(e.to_string()),
            Err(e) => return Err(e),
        }
    }
    Ok(bench)
}

fn load_image(dir: &Path, name: &str) -> Result<BenchImage, BenchError> {
    let folder = dir.join("data").join(name);
    let image_path = find_image(dir, name)
        .ok_or_else(|| BenchError::new(&folder, None, format!("no image images/{name}.jpg")))?;
    let (width, height) = matseg_image::io::read_dimensions(&image_path)?;
    let json_path = folder.join(DATA_FILE);
    let annotation =
        Annotation::read(&folder)?.ok_or_else(|| BenchError::new(&json_path, None, "missing"))?;
    annotation.check(width, height).map_err(|problem| {
        BenchError::new(&folder.join(problem.file()), None, problem.to_string())
    })?;
    if annotation.groups.is_empty() {
        return Err(BenchError::new(&json_path, None, "no materials"));
    }
    let material_ids: Vec<String> = annotation.groups.iter().map(|g| g.id.clone()).collect();
    let points = annotation
        .groups
        .iter()
        .map(|g| {
            g.points
                .iter()
                .map(|&[x, y, r]| BenchPoint {
                    x: x as f32,
                    y: y as f32,
                    r: r as f32,
                })
                .collect()
        })
        .collect();
    let n = material_ids.len();
    let mut weights: Vec<Vec<f64>> = (0..n)
        .map(|i| (0..n).map(|j| if i == j { 1.0 } else { 0.0 }).collect())
        .collect();
    let index_of = |id: &String| {
        material_ids
            .iter()
            .position(|m| m == id)
            .expect("checked: relations name known groups")
    };
    for relation in &annotation.relations {
        let index: Vec<usize> = relation.ids.iter().map(index_of).collect();
        for &i in &index {
            for &j in &index {
                if i != j {
                    weights[i][j] = weights[i][j].max(relation.weight);
                }
            }
        }
    }
    Ok(BenchImage {
        name: name.to_string(),
        image_path,
        material_ids,
        points,
        weights,
        has_relations: !annotation.relations.is_empty(),
    })
}

/// The points of all materials of one image, flattened, with their
/// material index; the order the metric scores them in.
pub fn flatten(image: &BenchImage) -> (Vec<BenchPoint>, Vec<usize>) {
    let mut points = Vec::new();
    let mut material = Vec::new();
    for (m, list) in image.points.iter().enumerate() {
        points.extend(list.iter().copied());
        material.extend(std::iter::repeat_n(m, list.len()));
    }
    (points, material)
}
