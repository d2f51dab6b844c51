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
    fn new(path: &Path, line: Option<usize>, message: impl Into<String>) -> Self {
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
    let image_path = ["jpg", "jpeg", "png", "JPG", "PNG"]
        .iter()
        .map(|ext| dir.join("images").join(format!("{name}.{ext}")))
        .find(|p| p.is_file())
        .ok_or_else(|| BenchError::new(&folder, None, format!("no image images/{name}.jpg")))?;
    let (width, height) = image::image_dimensions(&image_path)
        .map_err(|e| BenchError::new(&image_path, None, format!("unreadable image: {e}")))?;

    let json_path = folder.join("data.json");
    let text = std::fs::read_to_string(&json_path)
        .map_err(|e| BenchError::new(&json_path, None, format!("cannot read: {e}")))?;
    let (material_ids, points) = parse_points(&text, width, height)
        .map_err(|message| BenchError::new(&json_path, None, message))?;

    let n = material_ids.len();
    let mut weights: Vec<Vec<f64>> = (0..n)
        .map(|i| (0..n).map(|j| if i == j { 1.0 } else { 0.0 }).collect())
        .collect();
    let relations_path = folder.join("group_relations.txt");
    let mut has_relations = false;
    if relations_path.is_file() {
        let text = std::fs::read_to_string(&relations_path)
            .map_err(|e| BenchError::new(&relations_path, None, format!("cannot read: {e}")))?;
        for (number, line) in text.lines().enumerate() {
            let fail = |m: String| BenchError::new(&relations_path, Some(number + 1), m);
            let Some((ids, weight)) = parse_relation(line).map_err(fail)? else {
                continue;
            };
            let index: Vec<usize> = ids
                .iter()
                .map(|id| {
                    material_ids
                        .iter()
                        .position(|m| m == id)
                        .ok_or_else(|| fail(format!("unknown material id {id:?}")))
                })
                .collect::<Result<_, _>>()?;
            for &i in &index {
                for &j in &index {
                    if i != j {
                        weights[i][j] = weights[i][j].max(weight);
                    }
                }
            }
            has_relations = true;
        }
    }
    Ok(BenchImage {
        name: name.to_string(),
        image_path,
        material_ids,
        points,
        weights,
        has_relations,
    })
}

type ParsedPoints = (Vec<String>, Vec<Vec<BenchPoint>>);

/// Material ids (numeric ids in numeric order) and their points, each
/// checked to lie inside a `width x height` image.
fn parse_points(text: &str, width: u32, height: u32) -> Result<ParsedPoints, String> {
    let value: serde_json::Value =
        serde_json::from_str(text).map_err(|e| format!("bad JSON: {e}"))?;
    let object = value
        .as_object()
        .ok_or("expected an object of material ids")?;
    let mut entries: Vec<(&String, &serde_json::Value)> = object.iter().collect();
    entries.sort_by_key(|(id, _)| (id.parse::<u64>().unwrap_or(u64::MAX), id.to_string()));
    let mut ids = Vec::new();
    let mut points = Vec::new();
    for (id, entry) in entries {
        let list = entry
            .get("pt_im")
            .and_then(|p| p.as_array())
            .ok_or_else(|| format!("material {id:?}: no \"pt_im\" list"))?;
        let mut material = Vec::new();
        for (k, p) in list.iter().enumerate() {
            let coords: Vec<f64> = p
                .as_array()
                .filter(|a| a.len() == 3)
                .and_then(|a| a.iter().map(|v| v.as_f64()).collect())
                .ok_or_else(|| format!("material {id:?}, point {k}: expected [x, y, r]"))?;
            let (x, y, r) = (coords[0], coords[1], coords[2]);
            if !(0.0..width as f64).contains(&x) || !(0.0..height as f64).contains(&y) || r < 0.0 {
                return Err(format!(
                    "material {id:?}, point {k}: ({x}, {y}, r {r}) is outside the {width}x{height} image"
                ));
            }
            material.push(BenchPoint {
                x: x as f32,
                y: y as f32,
                r: r as f32,
            });
        }
        if material.is_empty() {
            return Err(format!("material {id:?} has no points"));
        }
        ids.push(id.clone());
        points.push(material);
    }
    if ids.is_empty() {
        return Err("no materials".into());
    }
    Ok((ids, points))
}

/// The `group_relations.txt` line of ids with `weight`: `[1, 2]` for
/// [`SQUARE_RELATION`], `(1, 2)` otherwise.
pub fn format_relation(ids: &[String], weight: f64) -> String {
    let (open, close) = if weight == SQUARE_RELATION {
        ('[', ']')
    } else {
        ('(', ')')
    };
    format!("{open}{}{close}", ids.join(", "))
}

/// One relation line: its ids and weight, `None` for a blank line.
pub fn parse_relation(line: &str) -> Result<Option<(Vec<String>, f64)>, String> {
    let line = line.trim();
    if line.is_empty() {
        return Ok(None);
    }
    let (inner, weight) =
        if let Some(inner) = line.strip_prefix('[').and_then(|l| l.strip_suffix(']')) {
            (inner, SQUARE_RELATION)
        } else if let Some(inner) = line.strip_prefix('(').and_then(|l| l.strip_suffix(')')) {
            (inner, ROUND_RELATION)
        } else {
            return Err(format!(
                "{line:?}: a relation is a list of ids in [...] or (...)"
            ));
        };
    let ids: Vec<String> = inner
        .split(',')
        .map(|id| {
            id.trim()
                .trim_matches(|c| c == '"' || c == '\'')
                .to_string()
        })
        .filter(|id| !id.is_empty())
        .collect();
    if ids.len() < 2 {
        return Err(format!(
            "{line:?}: a relation needs at least two material ids"
        ));
    }
    Ok(Some((ids, weight)))
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn relations_parse_with_their_weights() {
        assert_eq!(
            parse_relation(" [1, 2,3] ").unwrap(),
            Some((vec!["1".into(), "2".into(), "3".into()], SQUARE_RELATION))
        );
        assert_eq!(
            parse_relation("(\"4\",5)").unwrap(),
            Some((vec!["4".into(), "5".into()], ROUND_RELATION))
        );
        assert_eq!(parse_relation("   ").unwrap(), None);
        assert!(parse_relation("1, 2")
            .unwrap_err()
            .contains("[...] or (...)"));
        assert!(parse_relation("[1]").unwrap_err().contains("at least two"));
        assert!(parse_relation("[1, 2)").is_err());
    }

    #[test]
    fn points_parse_in_numeric_id_order_and_must_lie_inside() {
        let text = r#"{"10": {"pt_im": [[1, 2, 3]]}, "2": {"pt_im": [[4.5, 5, 1], [0, 0, 0]], "other": 1}}"#;
        let (ids, points) = parse_points(text, 10, 10).unwrap();
        assert_eq!(ids, vec!["2", "10"]);
        assert_eq!(points[0].len(), 2);
        assert_eq!(
            points[1][0],
            BenchPoint {
                x: 1.0,
                y: 2.0,
                r: 3.0
            }
        );
        let outside = parse_points(r#"{"1": {"pt_im": [[10, 2, 3]]}}"#, 10, 10).unwrap_err();
        assert!(outside.contains("outside the 10x10 image"), "{outside}");
        assert!(parse_points(r#"{"1": {"pt": []}}"#, 10, 10)
            .unwrap_err()
            .contains("pt_im"));
        assert!(parse_points(r#"{"1": {"pt_im": [[1, 2]]}}"#, 10, 10)
            .unwrap_err()
            .contains("[x, y, r]"));
        assert!(parse_points("[1", 10, 10).unwrap_err().contains("bad JSON"));
    }
}
