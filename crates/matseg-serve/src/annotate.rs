//! The annotate page's API: the `--bench` folders (point benchmarks in the
//! MatSeg layout, `images/NAME.jpg` and `data/NAME/data.json` with
//! `group_relations.txt`), one image's annotation read back, and an edited
//! annotation checked and saved, each file written whole or not at all.
//! `matseg eval points` and the evaluate page read what this saves.

use crate::app::{blocking, ApiError, AppState};
use crate::roots::{inside, plain_name, Roots};
use axum::body::Bytes;
use axum::extract::{Query, State};
use axum::Json;
use matseg_eval::annotation::{find_image, list_images, Annotation, DATA_FILE, RELATIONS_FILE};
use serde::Deserialize;
use std::path::PathBuf;
use std::sync::{Arc, Mutex};

/// The optional file of an image's data folder that names its materials.
const LABELS_FILE: &str = "labels.json";

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
    /// by name, as `matseg eval points` finds them; names that are not
    /// plain file names ([`plain_name`]) are left out.
    pub fn images(&self) -> Result<Vec<(String, PathBuf)>, ApiError> {
        let listed = list_images(&self.folder).map_err(|e| ApiError::not_found(e.to_string()))?;
        Ok(listed
            .into_iter()
            .filter(|(name, _)| plain_name(name).is_ok())
            .collect())
    }

    /// The image `name` of this benchmark: the one way the annotate routes
    /// turn a name into files. `name` must be a plain file name (403
    /// otherwise: no folder, no `..`) of an image the benchmark lists
    /// (`images/NAME.EXT`; 404 otherwise); its file, its annotation's
    /// folder `data/NAME` and the files in it must lie under the benchmark
    /// once symlinks are followed (403 otherwise).
    pub fn image(&self, roots: &Roots, name: &str) -> Result<BenchImage, ApiError> {
        if name.is_empty() {
            return Err(ApiError::bad(
                "name: give the name of one of the benchmark's images",
            ));
        }
        let name = plain_name(name)?;
        let missing = || {
            ApiError::not_found(format!(
                "{name:?}: no such image in {}/images",
                self.folder.display()
            ))
        };
        let found = find_image(&self.folder, name).ok_or_else(missing)?;
        let file_name = found
            .file_name()
            .and_then(|f| f.to_str())
            .ok_or_else(missing)?;
        let file = roots.resolve(&self.root, &format!("images/{file_name}"))?;
        let data_dir = inside(&self.folder, &self.folder.join("data").join(name), name)?;
        for part in [DATA_FILE, RELATIONS_FILE] {
            inside(&self.folder, &data_dir.join(part), name)?;
        }
        Ok(BenchImage {
            name: name.to_string(),
            file,
            data_dir,
        })
    }

    /// The material names the image's `data/NAME/labels.json` gives its
    /// groups by id (`{"1": "rusty iron", ...}`, as the real-photo
    /// benchmarks carry); none when it has no such file, one that is not
    /// such an object, or one outside the benchmark. Only shown: the
    /// annotation saved is data.json's.
    fn labels(&self, image: &BenchImage) -> serde_json::Map<String, serde_json::Value> {
        inside(&self.folder, &image.data_dir.join(LABELS_FILE), &image.name)
            .ok()
            .and_then(|file| std::fs::read(file).ok())
            .and_then(|bytes| {
                serde_json::from_slice::<std::collections::BTreeMap<String, String>>(&bytes).ok()
            })
            .map(|names| {
                names
                    .into_iter()
                    .map(|(id, name)| (id, name.into()))
                    .collect()
            })
            .unwrap_or_default()
    }

    /// The annotation saved for `image` (no groups when there is none).
    fn annotation(&self, image: &BenchImage) -> Result<Annotation, ApiError> {
        Annotation::read(&image.data_dir)
            .map(Option::unwrap_or_default)
            .map_err(|e| ApiError::bad(e.to_string()))
    }
}

/// An image of a benchmark and its annotation's folder, found and checked
/// by [`BenchFolder::image`].
pub struct BenchImage {
    /// Its name (the file name without its extension).
    pub name: String,
    /// Its file, under the benchmark's `images/`.
    pub file: PathBuf,
    /// The folder its annotation is saved in, `data/NAME` (made when the
    /// first annotation is saved).
    pub data_dir: PathBuf,
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
                    let groups = bench
                        .image(&state.roots, &name)
                        .and_then(|image| bench.annotation(&image))
                        .map_or(0, |a| a.groups.len());
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

/// The image `name` of `bench` ([`BenchFolder::image`]) and its size.
fn image_of(
    state: &AppState,
    bench: &BenchFolder,
    name: &str,
) -> Result<(BenchImage, u32, u32), ApiError> {
    let image = bench.image(&state.roots, name)?;
    let (w, h) =
        matseg_image::io::read_dimensions(&image.file).map_err(|e| ApiError::bad(e.to_string()))?;
    Ok((image, w, h))
}

/// `GET /api/annotation`: an image's annotation as saved (no groups when
/// it has none yet), with the material names of its `labels.json`.
pub async fn load(
    State(state): State<Arc<AppState>>,
    Query(query): Query<ImageQuery>,
) -> Result<Json<serde_json::Value>, ApiError> {
    blocking(move || {
        let bench = bench(&state, &query.root)?;
        let (image, width, height) = image_of(&state, bench, &query.name)?;
        let annotation = bench.annotation(&image)?;
        let labels = bench.labels(&image);
        let path = image
            .file
            .strip_prefix(&bench.folder)
            .unwrap_or(&image.file)
            .to_path_buf();
        Ok(Json(serde_json::json!({
            "name": query.name,
            "path": path,
            "width": width,
            "height": height,
            "groups": annotation.groups,
            "relations": annotation.relations,
            "labels": labels,
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
        let (image, width, height) = image_of(&state, bench, &query.name)?;
        annotation
            .check(width, height)
            .map_err(|m| ApiError::bad(format!("annotation of {:?}: {m}", query.name)))?;
        let _saving = matseg_image::sync::lock(&bench.saving);
        annotation
            .write(&image.data_dir)
            .map_err(|e| ApiError::internal(e.to_string()))?;
        Ok(Json(serde_json::json!({
            "saved": query.name,
            "groups": annotation.groups.len(),
            "relations": annotation.relations.len(),
        })))
    })
    .await
}
