//! The annotate page's API: the `--bench` folders (point benchmarks in the
//! MatSeg layout, `images/NAME.jpg` and `data/NAME/data.json` with
//! `group_relations.txt`), one image's annotation read back, and an edited
//! annotation checked and saved, each file written whole or not at all.
//! `matseg eval points` and the evaluate page read what this saves.

use crate::app::{blocking, ApiError, AppState};
use axum::body::Bytes;
use axum::extract::{Query, State};
use axum::Json;
use matseg_eval::points::{format_relation, parse_relation, ROUND_RELATION, SQUARE_RELATION};
use matseg_image::io::write_atomic;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

/// Image extensions a benchmark's `images/` folder may use, as the
/// evaluation reader looks for them.
const IMAGE_EXTENSIONS: [&str; 5] = ["jpg", "jpeg", "png", "JPG", "PNG"];

/// A `--bench` folder.
pub struct BenchFolder {
    /// Its root name (`bench0`, `bench1`...).
    pub root: String,
    /// The folder.
    pub folder: PathBuf,
    /// Held while an annotation of this benchmark is written.
    pub saving: Mutex<()>,
}

impl BenchFolder {
    /// The benchmark in `folder` under the root name `root`.
    pub fn new(root: &str, folder: PathBuf) -> Self {
        Self {
            root: root.to_string(),
            folder,
            saving: Mutex::new(()),
        }
    }

    /// The benchmark's images (names without extension and files), sorted
    /// by name.
    pub fn images(&self) -> Result<Vec<(String, PathBuf)>, ApiError> {
        let dir = self.folder.join("images");
        let listing = std::fs::read_dir(&dir)
            .map_err(|e| ApiError::not_found(format!("{}: {e}", dir.display())))?;
        let mut images: Vec<(String, PathBuf)> = listing
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| {
                p.is_file()
                    && p.extension()
                        .and_then(|e| e.to_str())
                        .is_some_and(|e| IMAGE_EXTENSIONS.contains(&e))
            })
            .filter_map(|p| Some((p.file_stem()?.to_str()?.to_string(), p)))
            .collect();
        images.sort();
        Ok(images)
    }

    /// The folder of `name`'s annotation.
    fn data_dir(&self, name: &str) -> PathBuf {
        self.folder.join("data").join(name)
    }
}

/// The benchmark folder named `root`.
pub fn bench<'a>(state: &'a AppState, root: &str) -> Result<&'a BenchFolder, ApiError> {
    state
        .benches
        .iter()
        .find(|b| b.root == root)
        .ok_or_else(|| ApiError::not_found(format!("no benchmark named {root:?}")))
}

/// A material group: its id (`1`, `2`...), an optional name and its points
/// `[x, y, r]` in image pixels.
#[derive(Clone, Debug, Default, Deserialize, Serialize, PartialEq)]
pub struct Group {
    /// The material id.
    pub id: String,
    /// What the annotator called it.
    #[serde(default)]
    pub name: String,
    /// The points, `[x, y, r]`.
    pub points: Vec<[f64; 3]>,
}

/// Groups that are partly the same material: weight 0.6 (`[...]` in
/// `group_relations.txt`) or 0.3 (`(...)`).
#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
pub struct Relation {
    /// The groups' ids.
    pub ids: Vec<String>,
    /// 0.6 or 0.3.
    pub weight: f64,
}

/// One image's annotation.
#[derive(Clone, Debug, Default, Deserialize, Serialize, PartialEq)]
pub struct Annotation {
    /// The material groups.
    pub groups: Vec<Group>,
    /// The partial similarities between groups.
    #[serde(default)]
    pub relations: Vec<Relation>,
}

/// `GET /api/benches`: the benchmark folders and their images, each with
/// the number of groups annotated on it, and the baselines an evaluation
/// can score.
pub async fn benches(
    State(state): State<Arc<AppState>>,
) -> Result<Json<serde_json::Value>, ApiError> {
    blocking(move || {
        let mut list = Vec::new();
        for bench in &state.benches {
            let images: Vec<_> = bench
                .images()?
                .into_iter()
                .map(|(name, file)| {
                    let groups = read_annotation(&bench.data_dir(&name))
                        .map(|a| a.groups.len())
                        .unwrap_or(0);
                    let path = file
                        .strip_prefix(&bench.folder)
                        .unwrap_or(&file)
                        .to_path_buf();
                    serde_json::json!({ "name": name, "path": path, "groups": groups })
                })
                .collect();
            list.push(serde_json::json!({
                "root": bench.root,
                "folder": bench.folder,
                "images": images,
            }));
        }
        Ok(Json(serde_json::json!({
            "benches": list,
            "baselines": matseg_pipeline::models::known_baselines(),
        })))
    })
    .await
}

/// An image of a benchmark.
#[derive(Deserialize)]
pub struct ImageQuery {
    root: String,
    name: String,
}

/// The image file of `name` in `bench` (checked to be inside it) and its
/// size.
fn image_of(
    state: &AppState,
    bench: &BenchFolder,
    name: &str,
) -> Result<(PathBuf, u32, u32), ApiError> {
    let file = IMAGE_EXTENSIONS
        .iter()
        .find_map(|ext| {
            state
                .roots
                .resolve(&bench.root, &format!("images/{name}.{ext}"))
                .ok()
        })
        .ok_or_else(|| {
            ApiError::not_found(format!(
                "{name:?}: no such image in {}/images",
                bench.folder.display()
            ))
        })?;
    let (w, h) =
        matseg_image::io::read_dimensions(&file).map_err(|e| ApiError::bad(e.to_string()))?;
    Ok((file, w, h))
}

/// `GET /api/annotation`: an image's annotation as saved (no groups when
/// it has none yet).
pub async fn load(
    State(state): State<Arc<AppState>>,
    Query(query): Query<ImageQuery>,
) -> Result<Json<serde_json::Value>, ApiError> {
    blocking(move || {
        let bench = bench(&state, &query.root)?;
        let (file, width, height) = image_of(&state, bench, &query.name)?;
        let annotation = read_annotation(&bench.data_dir(&query.name))?;
        let path = file
            .strip_prefix(&bench.folder)
            .unwrap_or(&file)
            .to_path_buf();
        Ok(Json(serde_json::json!({
            "name": query.name,
            "path": path,
            "width": width,
            "height": height,
            "groups": annotation.groups,
            "relations": annotation.relations,
        })))
    })
    .await
}

/// `POST /api/annotation`: saves the annotation in the body (JSON, as
/// [`Annotation`]) for an image, after checking it; no groups removes it.
pub async fn save(
    State(state): State<Arc<AppState>>,
    Query(query): Query<ImageQuery>,
    body: Bytes,
) -> Result<Json<serde_json::Value>, ApiError> {
    let annotation: Annotation = serde_json::from_slice(&body).map_err(|e| {
        ApiError::bad(format!(
            "annotation of {:?}: malformed JSON: {e}",
            query.name
        ))
    })?;
    blocking(move || {
        let bench = bench(&state, &query.root)?;
        let (_, width, height) = image_of(&state, bench, &query.name)?;
        check_annotation(&annotation, width, height)
            .map_err(|m| ApiError::bad(format!("annotation of {:?}: {m}", query.name)))?;
        let _saving = bench.saving.lock().unwrap_or_else(|e| e.into_inner());
        write_annotation(&bench.data_dir(&query.name), &annotation)
            .map_err(|e| ApiError::internal(e.to_string()))?;
        Ok(Json(serde_json::json!({
            "saved": query.name,
            "groups": annotation.groups.len(),
            "relations": annotation.relations.len(),
        })))
    })
    .await
}

/// The first problem of `annotation` on a `width x height` image.
fn check_annotation(annotation: &Annotation, width: u32, height: u32) -> Result<(), String> {
    let mut ids: Vec<&str> = Vec::new();
    for group in &annotation.groups {
        let id = group.id.as_str();
        if id.is_empty() || !id.bytes().all(|b| b.is_ascii_digit()) {
            return Err(format!("group id {id:?}: expected a number"));
        }
        if ids.contains(&id) {
            return Err(format!("group {id} appears twice"));
        }
        ids.push(id);
        if group.points.is_empty() {
            return Err(format!("group {id} has no points"));
        }
        for &[x, y, r] in &group.points {
            let inside = (0.0..width as f64).contains(&x) && (0.0..height as f64).contains(&y);
            if !(inside && r.is_finite() && r >= 0.0) {
                return Err(format!(
                    "group {id}: point ({x}, {y}, r {r}) is outside the {width}x{height} image"
                ));
            }
        }
    }
    for relation in &annotation.relations {
        if relation.weight != SQUARE_RELATION && relation.weight != ROUND_RELATION {
            return Err(format!(
                "relation {:?}: weight {} is neither {SQUARE_RELATION} nor {ROUND_RELATION}",
                relation.ids, relation.weight
            ));
        }
        if relation.ids.len() < 2 {
            return Err(format!(
                "relation {:?}: needs two groups or more",
                relation.ids
            ));
        }
        for (i, id) in relation.ids.iter().enumerate() {
            if !ids.contains(&id.as_str()) || relation.ids[..i].contains(id) {
                return Err(format!(
                    "relation {:?}: group {id} unknown or repeated",
                    relation.ids
                ));
            }
        }
    }
    Ok(())
}

/// Writes `annotation` into `dir` (`data.json`, and `group_relations.txt`
/// when it has relations); with no groups, removes what was there.
fn write_annotation(dir: &Path, annotation: &Annotation) -> std::io::Result<()> {
    let relations_file = dir.join("group_relations.txt");
    if annotation.groups.is_empty() {
        for file in [dir.join("data.json"), relations_file] {
            if file.exists() {
                std::fs::remove_file(file)?;
            }
        }
        if dir.is_dir() {
            std::fs::remove_dir(dir)?;
        }
        return Ok(());
    }
    std::fs::create_dir_all(dir)?;
    let data: serde_json::Map<String, serde_json::Value> = annotation
        .groups
        .iter()
        .map(|g| {
            (
                g.id.clone(),
                serde_json::json!({ "name": g.name, "pt_im": g.points }),
            )
        })
        .collect();
    let json = serde_json::to_string_pretty(&data).expect("plain JSON values");
    write_atomic(&dir.join("data.json"), json.as_bytes())?;
    if annotation.relations.is_empty() {
        if relations_file.exists() {
            std::fs::remove_file(relations_file)?;
        }
        return Ok(());
    }
    let text: String = annotation
        .relations
        .iter()
        .map(|r| format_relation(&r.ids, r.weight) + "\n")
        .collect();
    write_atomic(&relations_file, text.as_bytes())
}

/// The annotation saved in `dir` (none when nothing is there).
fn read_annotation(dir: &Path) -> Result<Annotation, ApiError> {
    let data_file = dir.join("data.json");
    if !data_file.is_file() {
        return Ok(Annotation::default());
    }
    let problem = |file: &Path, m: String| ApiError::bad(format!("{}: {m}", file.display()));
    let text =
        std::fs::read_to_string(&data_file).map_err(|e| problem(&data_file, e.to_string()))?;
    let object: serde_json::Map<String, serde_json::Value> =
        serde_json::from_str(&text).map_err(|e| problem(&data_file, format!("bad JSON: {e}")))?;
    let mut groups = Vec::new();
    for (id, entry) in object {
        let points: Vec<[f64; 3]> = serde_json::from_value(entry["pt_im"].clone())
            .map_err(|e| problem(&data_file, format!("material {id:?}: {e}")))?;
        let name = entry["name"].as_str().unwrap_or_default().to_string();
        groups.push(Group { id, name, points });
    }
    groups.sort_by_key(|g| (g.id.parse::<u64>().unwrap_or(u64::MAX), g.id.clone()));
    let relations_file = dir.join("group_relations.txt");
    let mut relations = Vec::new();
    if relations_file.is_file() {
        let text = std::fs::read_to_string(&relations_file)
            .map_err(|e| problem(&relations_file, e.to_string()))?;
        for (number, line) in text.lines().enumerate() {
            let relation = parse_relation(line)
                .map_err(|m| problem(&relations_file, format!("line {}: {m}", number + 1)))?;
            if let Some((ids, weight)) = relation {
                relations.push(Relation { ids, weight });
            }
        }
    }
    Ok(Annotation { groups, relations })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn annotation() -> Annotation {
        Annotation {
            groups: vec![
                Group {
                    id: "1".into(),
                    name: "rust".into(),
                    points: vec![[10.0, 5.0, 3.0], [20.0, 8.0, 3.0]],
                },
                Group {
                    id: "2".into(),
                    name: String::new(),
                    points: vec![[1.0, 1.0, 0.0]],
                },
                Group {
                    id: "3".into(),
                    name: "paint".into(),
                    points: vec![[30.0, 9.0, 5.0]],
                },
            ],
            relations: vec![
                Relation {
                    ids: vec!["1".into(), "2".into()],
                    weight: SQUARE_RELATION,
                },
                Relation {
                    ids: vec!["2".into(), "3".into()],
                    weight: ROUND_RELATION,
                },
            ],
        }
    }

    #[test]
    fn an_annotation_reads_back_as_written() {
        let dir = tempfile::tempdir().unwrap();
        let data = dir.path().join("data/a");
        write_annotation(&data, &annotation()).unwrap();
        assert_eq!(read_annotation(&data).unwrap(), annotation());
        assert_eq!(
            std::fs::read_to_string(data.join("group_relations.txt")).unwrap(),
            "[1, 2]\n(2, 3)\n"
        );
        let mut fewer = annotation();
        fewer.relations.clear();
        write_annotation(&data, &fewer).unwrap();
        assert!(!data.join("group_relations.txt").exists());
        assert_eq!(read_annotation(&data).unwrap(), fewer);
        write_annotation(&data, &Annotation::default()).unwrap();
        assert!(!data.exists(), "no groups: nothing left");
    }

    #[test]
    fn bad_annotations_are_named() {
        assert_eq!(check_annotation(&annotation(), 40, 10), Ok(()));
        let mut outside = annotation();
        outside.groups[0].points[0] = [40.0, 5.0, 3.0];
        assert!(check_annotation(&outside, 40, 10)
            .unwrap_err()
            .contains("outside the 40x10 image"));
        let mut empty = annotation();
        empty.groups[1].points.clear();
        assert_eq!(
            check_annotation(&empty, 40, 10).unwrap_err(),
            "group 2 has no points"
        );
        let mut twice = annotation();
        twice.groups[2].id = "1".into();
        assert_eq!(
            check_annotation(&twice, 40, 10).unwrap_err(),
            "group 1 appears twice"
        );
        let mut unknown = annotation();
        unknown.relations[0].ids[1] = "7".into();
        assert!(check_annotation(&unknown, 40, 10)
            .unwrap_err()
            .contains("group 7 unknown"));
        let mut weight = annotation();
        weight.relations[0].weight = 0.5;
        assert!(check_annotation(&weight, 40, 10)
            .unwrap_err()
            .contains("weight 0.5"));
        let mut named = annotation();
        named.groups[0].id = "a".into();
        assert!(check_annotation(&named, 40, 10)
            .unwrap_err()
            .contains("expected a number"));
    }
}
