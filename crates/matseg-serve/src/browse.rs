//! The browse page's API: the `--data` folders that are datasets (MatSeg
//! sample folders or WebDataset shards, 2D or 3D), a page of their samples
//! at a time, and one sample's image, soft masks, ROI, annotation and
//! sidecar. A dataset is indexed once when the server starts (names and
//! shard offsets, no pixels); samples are read when a page shows them.

use crate::app::{blocking, ApiError, AppState};
use crate::photos::Page;
use axum::extract::{Query, State};
use axum::http::header;
use axum::response::{IntoResponse, Response};
use axum::Json;
use image::RgbImage;
use matseg_data::reader::{Dataset, Sample, TrainingTargets};
use matseg_image::io::{encode_jpeg, encode_png_grey, encode_png_rgb};
use matseg_scene::{blend_annotation_colour, colourise};
use serde::Deserialize;
use std::path::PathBuf;
use std::sync::Arc;

/// Most samples one listing request returns.
const MAX_LISTING: usize = 500;

/// Longer side of a sample's thumbnail, in pixels.
const THUMBNAIL_SIDE: u32 = 192;

/// A `--data` folder that holds a dataset.
pub struct DatasetFolder {
    /// Its root name (`data0`, `data1`...).
    pub root: String,
    /// The folder.
    pub folder: PathBuf,
    /// Its samples.
    pub dataset: Dataset,
}

impl DatasetFolder {
    /// Opens `folder` as a dataset, or `None` when it holds none (a folder
    /// of photos).
    pub fn open(root: &str, folder: PathBuf) -> Option<Self> {
        let dataset = Dataset::open(&folder).ok()?;
        Some(Self {
            root: root.to_string(),
            folder,
            dataset,
        })
    }

    /// Reads sample `index`.
    pub fn read(&self, index: usize) -> Result<Sample, ApiError> {
        if index >= self.dataset.len() {
            return Err(ApiError::not_found(format!(
                "{}: no sample {index} (it has {})",
                self.folder.display(),
                self.dataset.len()
            )));
        }
        self.dataset
            .get(index)
            .map_err(|e| ApiError::bad(e.to_string()))
    }
}

fn dataset<'a>(state: &'a AppState, root: &str) -> Result<&'a DatasetFolder, ApiError> {
    state
        .datasets
        .iter()
        .find(|d| d.root == root)
        .ok_or_else(|| ApiError::not_found(format!("no dataset named {root:?}")))
}

/// `GET /api/datasets`: the dataset folders and their sizes.
pub async fn datasets(State(state): State<Arc<AppState>>) -> Json<serde_json::Value> {
    let list: Vec<_> = state
        .datasets
        .iter()
        .map(|d| {
            serde_json::json!({
                "root": d.root,
                "folder": d.folder,
                "samples": d.dataset.len(),
                "incomplete": d.dataset.incomplete(),
            })
        })
        .collect();
    Json(serde_json::json!({ "datasets": list }))
}

/// A dataset and a page of it.
#[derive(Deserialize)]
pub struct SamplesQuery {
    root: String,
    #[serde(default)]
    offset: usize,
    limit: Option<usize>,
}

/// `GET /api/samples`: a page of a dataset's samples, by index and key.
pub async fn samples(
    State(state): State<Arc<AppState>>,
    Query(query): Query<SamplesQuery>,
) -> Result<Json<serde_json::Value>, ApiError> {
    let folder = dataset(&state, &query.root)?;
    let page = Page {
        offset: query.offset,
        limit: query.limit,
    };
    let range = page.range(folder.dataset.len(), 48, MAX_LISTING);
    let samples: Vec<_> = range
        .clone()
        .map(|i| serde_json::json!({ "index": i, "key": folder.dataset.key(i) }))
        .collect();
    Ok(Json(serde_json::json!({
        "total": folder.dataset.len(),
        "offset": range.start,
        "samples": samples,
    })))
}

/// One sample of a dataset.
#[derive(Deserialize)]
pub struct SampleQuery {
    root: String,
    index: usize,
}

async fn read_sample(state: &Arc<AppState>, root: &str, index: usize) -> Result<Sample, ApiError> {
    let state = state.clone();
    let root = root.to_string();
    blocking(move || dataset(&state, &root)?.read(index)).await
}

/// `GET /api/sample`: a sample's key, size, number of masks and sidecar.
pub async fn sample(
    State(state): State<Arc<AppState>>,
    Query(query): Query<SampleQuery>,
) -> Result<Json<serde_json::Value>, ApiError> {
    let sample = read_sample(&state, &query.root, query.index).await?;
    let (width, height) = sample.image.dimensions();
    Ok(Json(serde_json::json!({
        "index": query.index,
        "key": sample.key,
        "width": width,
        "height": height,
        "masks": sample.masks.len(),
        "roi": sample.roi.is_some(),
        "meta": sample.meta,
    })))
}

/// One picture of a sample.
#[derive(Deserialize)]
pub struct PartQuery {
    root: String,
    index: usize,
    /// `image`, `thumbnail`, `mask` (with `mask=K`), `roi`, `annotation`
    /// (the soft masks in palette colours) or `overlay` (the annotation
    /// over the image).
    part: String,
    mask: Option<usize>,
}

/// `GET /api/sample/image`: one picture of a sample, PNG (the thumbnail
/// JPEG).
pub async fn sample_image(
    State(state): State<Arc<AppState>>,
    Query(query): Query<PartQuery>,
) -> Result<Response, ApiError> {
    let sample = read_sample(&state, &query.root, query.index).await?;
    let (kind, bytes) = blocking(move || draw_part(&sample, &query.part, query.mask)).await?;
    Ok(([(header::CONTENT_TYPE, kind)], bytes).into_response())
}

/// The picture `part` of `sample`: content type and bytes.
fn draw_part(
    sample: &Sample,
    part: &str,
    mask: Option<usize>,
) -> Result<(&'static str, Vec<u8>), ApiError> {
    let (w, h) = sample.image.dimensions();
    let png = |bytes| Ok(("image/png", bytes));
    match part {
        "image" => png(encode_png_rgb(&sample.image)),
        "thumbnail" => {
            let scale = THUMBNAIL_SIDE as f32 / w.max(h) as f32;
            let (tw, th) = if scale < 1.0 {
                (
                    ((w as f32 * scale).round() as u32).max(1),
                    ((h as f32 * scale).round() as u32).max(1),
                )
            } else {
                (w, h)
            };
            let small = image::imageops::thumbnail(&sample.image, tw, th);
            Ok(("image/jpeg", encode_jpeg(&small, 85)))
        }
        "mask" => {
            let k = mask.unwrap_or(0);
            let m = sample.masks.get(k).ok_or_else(|| {
                ApiError::not_found(format!(
                    "sample {}: no mask {k} (it has {})",
                    sample.key,
                    sample.masks.len()
                ))
            })?;
            png(encode_png_grey(w, h, m.as_raw()))
        }
        "roi" => {
            let roi = sample.roi.as_ref().ok_or_else(|| {
                ApiError::not_found(format!("sample {}: no ROI stored", sample.key))
            })?;
            png(encode_png_grey(w, h, roi.as_raw()))
        }
        "annotation" => png(encode_png_rgb(&annotation(sample, &sample.targets()))),
        "overlay" => png(encode_png_rgb(&overlay(sample, &sample.targets()))),
        other => Err(ApiError::bad(format!(
            "part {other:?}: expected image, thumbnail, mask, roi, annotation or overlay"
        ))),
    }
}

/// The soft masks as the training reads them, each material in its palette
/// colour (mixtures mixed), outside the ROI black.
fn annotation(sample: &Sample, targets: &TrainingTargets) -> RgbImage {
    let (w, h) = sample.image.dimensions();
    let weights: Vec<&[f32]> = targets.weights.iter().map(|p| p.data.as_slice()).collect();
    colourise(w as usize, h as usize, &weights)
}

/// The annotation blended over the image inside the ROI (two parts colour
/// to one part image).
fn overlay(sample: &Sample, targets: &TrainingTargets) -> RgbImage {
    let colours = annotation(sample, targets);
    let mut out = sample.image.clone();
    for ((p, c), &inside) in out
        .pixels_mut()
        .zip(colours.pixels())
        .zip(&targets.roi.data)
    {
        if inside > 0.0 {
            blend_annotation_colour(&mut p.0, c.0);
        }
    }
    out
}
