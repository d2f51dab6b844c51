//! The annotate page's API: the `--bench` folders (point benchmarks in the
//! MatSeg layout, `images/NAME.jpg` and `data/NAME/data.json` with
//! `group_relations.txt`), one image's annotation read back, and an edited
//! annotation checked and saved, each file written whole or not at all.
//! `matseg eval points` and the evaluate page read what this saves.

use crate::app::{blocking, ApiError, AppState};
use axum::body::Bytes;
use axum::extract::{Query, State};
use axum::Json;
use matseg_eval::annotation::{find_image, list_images, Annotation};
use serde::Deserialize;
use std::path::PathBuf;
use std::sync::{Arc, Mutex};

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
    /// by name, as `matseg eval points` finds them.
    pub fn images(&self) -> Result<Vec<(String, PathBuf)>, ApiError> {
        list_images(&self.folder).map_err(|e| ApiError::not_found(e.to_string()))
    }

    /// The folder of `name`'s annotation.
    fn data_dir(&self, name: &str) -> PathBuf {
        self.folder.join("data").join(name)
    }

    /// The annotation saved for `name` (no groups when there is none).
    fn annotation(&self, name: &str) -> Result<Annotation, ApiError> {
        Annotation::read(&self.data_dir(name))
            .map(Option::unwrap_or_default)
            .map_err(|e| ApiError::bad(e.to_string()))
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
                    let groups = bench.annotation(&name).map(|a| a.groups.len()).unwrap_or(0);
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
    let file = find_image(&bench.folder, name)
        .and_then(|file| {
            let file_name = file.file_name()?.to_str()?;
            state
                .roots
                .resolve(&bench.root, &format!("images/{file_name}"))
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
        let annotation = bench.annotation(&query.name)?;
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
        annotation
            .check(width, height)
            .map_err(|m| ApiError::bad(format!("annotation of {:?}: {m}", query.name)))?;
        let _saving = matseg_image::sync::lock(&bench.saving);
        annotation
            .write(&bench.data_dir(&query.name))
            .map_err(|e| ApiError::internal(e.to_string()))?;
        Ok(Json(serde_json::json!({
            "saved": query.name,
            "groups": annotation.groups.len(),
            "relations": annotation.relations.len(),
        })))
    })
    .await
}
