//! The segment page's API: the photo list, a photo's bytes, uploads, and
//! the answers to clicks (a similarity map, a segmentation by points, an
//! automatic segmentation), each from the photo's cached descriptors.
//!
//! A photo is named by a root and a path: a file under a photo or bench
//! folder, `upload` and the name an upload was given, or a dataset root
//! and `sample/INDEX`.

use crate::app::{blocking, ApiError, AppState, UploadName};
use crate::described::{described_size, release_freed_memory, Described, Turn};
use crate::roots::plain_name;
use crate::uploads::Upload;
use axum::body::Body;
use axum::extract::{Query, State};
use axum::http::{header, StatusCode};
use axum::response::{IntoResponse, Response};
use axum::Json;
use image::RgbImage;
use matseg_image::io::{encode_png_grey, encode_png_rgb, read_rgb};
use matseg_pipeline::segment::{
    check_points, cluster, query_points, similarity_grey, DEFAULT_RADIUS, MAX_POINTS,
};
use matseg_query::cluster::ClusterOptions;
use matseg_query::descriptor::check_radius;
use serde::Deserialize;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// Image extensions the photo list shows.
pub const PHOTO_EXTENSIONS: [&str; 3] = ["jpg", "jpeg", "png"];

/// Most photos one listing request returns.
const MAX_LISTING: usize = 1000;

/// The largest upload accepted, in bytes.
pub const MAX_UPLOAD_BYTES: u64 = 32 << 20;

/// The largest uploaded photo accepted, in pixels.
pub const MAX_UPLOAD_PIXELS: u64 = 40_000_000;

/// The root name of uploaded photos.
pub const UPLOAD_ROOT: &str = "upload";

/// The most clusters an automatic segmentation makes (the palette's size).
pub const MAX_CLUSTERS: usize = matseg_scene::PALETTE.len();

/// A page of a listing.
#[derive(Deserialize)]
pub struct Page {
    /// The first item's index.
    #[serde(default)]
    pub offset: usize,
    /// How many items at most (a default when absent).
    pub limit: Option<usize>,
}

impl Page {
    /// The range of `total` items the page asks for, with `default` items
    /// when it names no limit and `most` at most.
    pub fn range(&self, total: usize, default: usize, most: usize) -> std::ops::Range<usize> {
        let start = self.offset.min(total);
        start..(start + self.limit.unwrap_or(default).min(most)).min(total)
    }
}

/// `GET /api/photos`: a page of the photos listed at start.
pub async fn list(
    State(state): State<Arc<AppState>>,
    Query(page): Query<Page>,
) -> Json<serde_json::Value> {
    let range = page.range(state.photos.len(), 200, MAX_LISTING);
    let items: Vec<_> = state.photos[range.clone()]
        .iter()
        .map(|(root, path)| serde_json::json!({ "root": root, "path": path }))
        .collect();
    Json(serde_json::json!({
        "total": state.photos.len(),
        "offset": range.start,
        "photos": items
    }))
}

/// A photo named by root and path.
#[derive(Clone, Deserialize)]
pub struct PhotoRef {
    /// The root.
    pub root: String,
    /// The path inside it.
    pub path: String,
}

/// Where a photo's pixels come from: found without reading the photo.
enum Source {
    File(PathBuf),
    Upload(Upload),
    Sample(usize),
}

impl Source {
    /// The photo a reference names, and the key it is cached under.
    fn find(state: &AppState, photo: &PhotoRef) -> Result<(String, Self), ApiError> {
        if photo.root == UPLOAD_ROOT {
            let upload = state
                .uploads
                .get(plain_name(&photo.path)?)
                .filter(|_| is_photo_upload(&photo.path))
                .ok_or_else(|| {
                    ApiError::not_found(format!(
                        "upload {:?}: not kept any more; upload it again",
                        photo.path
                    ))
                })?;
            return Ok((
                format!("{UPLOAD_ROOT}/{}", photo.path),
                Source::Upload(upload),
            ));
        }
        if state.datasets.iter().any(|d| d.root == photo.root) {
            let index = photo
                .path
                .strip_prefix("sample/")
                .and_then(|i| i.parse().ok())
                .ok_or_else(|| ApiError::bad(format!("{:?}: expected sample/INDEX", photo.path)))?;
            return Ok((format!("{}/{index}", photo.root), Source::Sample(index)));
        }
        let file = state.roots.resolve(&photo.root, &photo.path)?;
        if !matseg_image::io::has_extension(&file, &PHOTO_EXTENSIONS) {
            return Err(ApiError::bad(format!(
                "{}: not a photo ({})",
                photo.path,
                PHOTO_EXTENSIONS.join(", ")
            )));
        }
        Ok((
            format!("{}/{}", photo.root, file.display()),
            Source::File(file),
        ))
    }

    /// The photo's size from its file's header, without decoding it;
    /// `None` for a dataset's sample, or a header that cannot be read
    /// (decoding it says why).
    fn header_size(&self) -> Option<(u32, u32)> {
        match self {
            Source::File(file) => matseg_image::io::read_dimensions(file).ok(),
            Source::Upload(upload) => matseg_image::io::read_dimensions(&upload.file).ok(),
            Source::Sample(_) => None,
        }
    }

    /// The photo's pixels.
    fn pixels(&self, state: &AppState, photo: &PhotoRef) -> Result<RgbImage, ApiError> {
        match self {
            Source::File(file) => read_rgb(file),
            Source::Upload(upload) => read_rgb(&upload.file).map_err(|e| e.renamed(&photo.path)),
            Source::Sample(index) => return Ok(sample(state, photo, *index)?.image),
        }
        .map_err(|e| ApiError::bad(e.to_string()))
    }

    /// The photo's bytes: the file's or the upload's, a sample's image as
    /// PNG.
    fn bytes(self, state: &AppState, photo: &PhotoRef) -> Result<Vec<u8>, ApiError> {
        let read = |file: &Path| {
            std::fs::read(file).map_err(|e| ApiError::not_found(format!("{}: {e}", photo.path)))
        };
        match self {
            Source::File(file) => read(&file),
            Source::Upload(upload) => read(&upload.file),
            Source::Sample(index) => Ok(encode_png_rgb(&sample(state, photo, index)?.image)),
        }
    }
}

/// Sample `index` of the dataset root `photo` names.
fn sample(
    state: &AppState,
    photo: &PhotoRef,
    index: usize,
) -> Result<matseg_data::reader::Sample, ApiError> {
    let dataset = state
        .datasets
        .iter()
        .find(|d| d.root == photo.root)
        .expect("found as a dataset root");
    dataset.read(index)
}

/// The content type of PNG or JPEG bytes.
fn image_type(bytes: &[u8]) -> &'static str {
    if bytes.starts_with(b"\x89PNG") {
        "image/png"
    } else {
        "image/jpeg"
    }
}

/// `GET /api/photo`: the photo's bytes (a sample's image as PNG).
pub async fn photo(
    State(state): State<Arc<AppState>>,
    Query(photo): Query<PhotoRef>,
) -> Result<Response, ApiError> {
    let bytes = blocking(move || {
        let (_, source) = Source::find(&state, &photo)?;
        source.bytes(&state, &photo)
    })
    .await?;
    Ok(([(header::CONTENT_TYPE, image_type(&bytes))], bytes).into_response())
}

/// `POST /api/upload[?name=FILE]`: a PNG or JPEG photo as the body,
/// written to the uploads folder as it arrives and kept there under a name
/// made from its bytes; answers its reference and size. Too large: 413;
/// not an image or a truncated one: 400, and nothing kept.
pub async fn upload(
    State(state): State<Arc<AppState>>,
    Query(name): Query<UploadName>,
    body: Body,
) -> Result<Json<serde_json::Value>, ApiError> {
    let shown = if name.name.is_empty() {
        "upload".to_string()
    } else {
        name.name.clone()
    };
    let arrived = state
        .uploads
        .receive(body, MAX_UPLOAD_BYTES, "upload")
        .await?;
    // Checking it decodes it whole: a turn at the work on full pixels.
    let turn = state.photo_work.turn(&shown).await?;
    let (width, height, extension) = blocking({
        let file = arrived.file.clone();
        let shown = shown.clone();
        move || {
            let _turn = turn;
            check_upload(&file, &shown)
        }
    })
    .await?;
    let key = format!("{:016x}.{extension}", arrived.hash);
    arrived.keep(&key)?;
    Ok(Json(serde_json::json!({
        "root": UPLOAD_ROOT,
        "path": key,
        "name": shown,
        "width": width,
        "height": height,
    })))
}

/// Whether an upload's name is a photo's (the names [`upload`] gives).
fn is_photo_upload(name: &str) -> bool {
    name.ends_with(".png") || name.ends_with(".jpeg")
}

/// The size and extension of an uploaded photo, checked: PNG or JPEG,
/// within the pixel cap, decodable to the end.
fn check_upload(file: &Path, name: &str) -> Result<(u32, u32, &'static str), ApiError> {
    let shown = |e: matseg_image::io::ImageIoError| ApiError::bad(e.renamed(name).to_string());
    let mut head = [0u8; 8];
    let read = std::fs::File::open(file).and_then(|mut f| {
        use std::io::Read;
        f.read(&mut head)
    });
    let read = read.map_err(|e| ApiError::internal(format!("{name}: {e}")))?;
    let extension = match image_type(&head[..read]) {
        "image/png" => "png",
        "image/jpeg" if head.starts_with(&[0xFF, 0xD8]) => "jpeg",
        _ => return Err(ApiError::bad(format!("{name}: not a PNG or JPEG image"))),
    };
    let (width, height) = matseg_image::io::read_dimensions(file).map_err(shown)?;
    let pixels = width as u64 * height as u64;
    if pixels > MAX_UPLOAD_PIXELS {
        return Err(ApiError::new(
            StatusCode::PAYLOAD_TOO_LARGE,
            format!(
                "{name}: {width} x {height} is {:.1} megapixels; the limit is {}",
                pixels as f64 / 1e6,
                MAX_UPLOAD_PIXELS / 1_000_000
            ),
        ));
    }
    read_rgb(file).map_err(shown)?;
    Ok((width, height, extension))
}

/// The photo described, from the cache or now: in a turn at the work on
/// full pixels ([`crate::described::PhotoWork`]), off the async threads,
/// counted against the cache's budget before it is made, and shrunk to
/// [`described_size`] when it has more pixels than that (the memory the
/// description freed is given back after it). A photo described now comes
/// with its turn, for the answer to be made in it too: the request's
/// whole working set is then one turn's, and the next description waits
/// until this answer is made.
pub async fn described(
    state: &Arc<AppState>,
    photo: &PhotoRef,
) -> Result<(Arc<Described>, Option<Turn>), ApiError> {
    let (key, source) = Source::find(state, photo)?;
    if let Some(d) = state.described.get(&key) {
        return Ok((d, None));
    }
    let turn = state.photo_work.turn(&photo.path).await?;
    let state = state.clone();
    let photo = photo.clone();
    // The turn goes with the work, which ends even if the request does
    // not wait for it.
    let (described, turn) = blocking(move || {
        // Described by another request while this one waited.
        if let Some(d) = state.described.get(&key) {
            return Ok((d, turn));
        }
        let counted = |(w, h): (u32, u32)| state.model.described_bytes(described_size(w, h));
        let early = source
            .header_size()
            .map(|size| (size, state.described.reserve(counted(size))));
        let full = source.pixels(&state, &photo)?;
        let size = full.dimensions();
        let reservation = match early {
            Some((header, reservation)) if header == size => reservation,
            _ => state.described.reserve(counted(size)),
        };
        let image = as_described(full);
        let map = state.model.describe_click(&image);
        let described = Arc::new(Described::new(image, map, size));
        reservation.keep(key, described.clone());
        Ok((described, turn))
    })
    .await?;
    tokio::task::spawn_blocking(release_freed_memory);
    Ok((described, Some(turn)))
}

/// A photo's pixels as they are described: shrunk by area averaging to
/// [`described_size`] when it has more pixels than that, else as they are.
fn as_described(full: RgbImage) -> RgbImage {
    let (w, h) = full.dimensions();
    let size = described_size(w, h);
    if size == (w, h) {
        return full;
    }
    image::imageops::thumbnail(&full, size.0, size.1)
}

/// The PNG answer `make` makes of a described photo, at the photo's own
/// size, in `turn` (the request's, when it described the photo) or, for a
/// photo described shrunk, whose answer is as large as the photo, in a
/// turn of its own, off the async threads. Any other answer is made off
/// them when `off_async` says so, else here.
pub(crate) async fn photo_answer(
    state: &Arc<AppState>,
    (described, turn): (Arc<Described>, Option<Turn>),
    what: &str,
    off_async: bool,
    make: impl FnOnce(&Described) -> Result<Vec<u8>, ApiError> + Send + 'static,
) -> Result<Response, ApiError> {
    let turn = match turn {
        None if described.shrunk() => Some(state.photo_work.turn(what).await?),
        turn => turn,
    };
    let bytes = if turn.is_some() || off_async {
        blocking(move || {
            let _turn = turn;
            make(&described)
        })
        .await?
    } else {
        make(&described)?
    };
    Ok(png(bytes))
}

/// Points `x,y;x,y...` in photo pixels: one at least, at most `most`.
pub(crate) fn parse_points(text: &str, most: usize) -> Result<Vec<(f32, f32)>, ApiError> {
    let points = text
        .split(';')
        .filter(|p| !p.trim().is_empty())
        .map(|p| {
            let (x, y) = p.split_once(',')?;
            Some((x.trim().parse().ok()?, y.trim().parse().ok()?))
        })
        .collect::<Option<Vec<_>>>()
        .ok_or_else(|| ApiError::bad(format!("points {text:?}: expected X,Y;X,Y...")))?;
    if points.is_empty() || points.len() > most {
        return Err(ApiError::bad(format!(
            "points: give 1 to {most} points (got {})",
            points.len()
        )));
    }
    Ok(points)
}

/// The radius a request asks for ([`DEFAULT_RADIUS`] when none), checked
/// as every front end checks it.
pub(crate) fn checked_radius(radius: Option<f32>) -> Result<f32, ApiError> {
    check_radius(radius.unwrap_or(DEFAULT_RADIUS)).map_err(|e| ApiError::bad(e.to_string()))
}

/// A photo and points on it.
#[derive(Deserialize)]
pub struct PointsQuery {
    root: String,
    path: String,
    points: String,
    radius: Option<f32>,
}

/// The photo described (with the turn it was described in, if it was
/// now), the points checked against it and the radius, both where they
/// lie on the photo as described.
async fn described_with_points(
    state: &Arc<AppState>,
    query: &PointsQuery,
) -> Result<((Arc<Described>, Option<Turn>), Vec<(f32, f32)>, f32), ApiError> {
    let points = parse_points(&query.points, MAX_POINTS)?;
    let radius = checked_radius(query.radius)?;
    let photo = PhotoRef {
        root: query.root.clone(),
        path: query.path.clone(),
    };
    let (described, turn) = described(state, &photo).await?;
    let points = check_points_on(&described, &points, &query.path)?;
    let radius = described.radius(radius);
    Ok(((described, turn), points, radius))
}

/// Checks `points` (at most [`MAX_POINTS`], each inside the photo in its
/// own pixels) as `matseg segment` checks them, and answers them where
/// they lie on the photo as described.
fn check_points_on(
    described: &Described,
    points: &[(f32, f32)],
    label: &str,
) -> Result<Vec<(f32, f32)>, ApiError> {
    if !described.shrunk() {
        check_points(&described.photo, points, label).map_err(|e| ApiError::bad(e.to_string()))?;
        return Ok(points.to_vec());
    }
    let (w, h) = (described.width as f32, described.height as f32);
    if let Some((x, y)) = points
        .iter()
        .find(|(x, y)| !(0.0..w).contains(x) || !(0.0..h).contains(y))
    {
        return Err(ApiError::bad(format!(
            "point {x},{y}: outside {label} ({w}x{h})"
        )));
    }
    Ok(points.iter().map(|&(x, y)| described.point(x, y)).collect())
}

fn png(bytes: Vec<u8>) -> Response {
    ([(header::CONTENT_TYPE, "image/png")], bytes).into_response()
}

/// A label map of a described photo as an RGB PNG at the photo's own
/// size: red = label, green = how strongly the pixel belongs to it
/// (0..255), blue = 0.
fn label_png(described: &Described, labels: &[u32], strength: impl Fn(usize) -> u8) -> Vec<u8> {
    let raw = labels
        .iter()
        .enumerate()
        .flat_map(|(i, &l)| [l as u8, strength(i), 0])
        .collect();
    let raw = described.at_photo_size(raw, 3);
    encode_png_rgb(
        &RgbImage::from_raw(described.width, described.height, raw).expect("one label per pixel"),
    )
}

/// `GET /api/similarity`: the similarity map of the first point, cosine in
/// [0, 1] as a grey PNG.
pub async fn similarity(
    State(state): State<Arc<AppState>>,
    Query(query): Query<PointsQuery>,
) -> Result<Response, ApiError> {
    let (described, points, radius) = described_with_points(&state, &query).await?;
    let first = *points
        .first()
        .ok_or_else(|| ApiError::bad("points: give one point"))?;
    photo_answer(&state, described, &query.path, false, move |described| {
        let maps = query_points(&described.map, &[first], radius);
        let grey = similarity_grey(&maps.similarity[0]);
        let grey = described.at_photo_size(grey, 1);
        Ok(encode_png_grey(described.width, described.height, &grey))
    })
    .await
}

/// `GET /api/segment`: the segmentation by two points or more, each pixel
/// labelled with its most similar point (see [`label_png`]; green is the
/// cosine to that point, so the page can cut weak matches).
pub async fn segment(
    State(state): State<Arc<AppState>>,
    Query(query): Query<PointsQuery>,
) -> Result<Response, ApiError> {
    let (described, points, radius) = described_with_points(&state, &query).await?;
    if points.len() < 2 {
        return Err(ApiError::bad("points: give two points or more"));
    }
    photo_answer(&state, described, &query.path, false, move |described| {
        let maps = query_points(&described.map, &points, radius);
        let labels = maps.labels.expect("two points or more");
        let grey = |i: usize| {
            (maps.similarity[labels[i] as usize][i].clamp(0.0, 1.0) * 255.0).round() as u8
        };
        Ok(label_png(described, &labels, grey))
    })
    .await
}

/// A photo and a number of clusters.
#[derive(Deserialize)]
pub struct AutoQuery {
    root: String,
    path: String,
    k: usize,
}

/// `GET /api/auto`: the photo split into `k` clusters of its descriptors
/// (as `matseg segment --auto K`), as [`label_png`] with full strength.
pub async fn auto(
    State(state): State<Arc<AppState>>,
    Query(query): Query<AutoQuery>,
) -> Result<Response, ApiError> {
    if !(1..=MAX_CLUSTERS).contains(&query.k) {
        return Err(ApiError::bad(format!(
            "k {}: give 1 to {MAX_CLUSTERS} clusters",
            query.k
        )));
    }
    let photo = PhotoRef {
        root: query.root,
        path: query.path,
    };
    let described = described(&state, &photo).await?;
    let k = query.k;
    photo_answer(&state, described, &photo.path, true, move |described| {
        let (labels, _) = cluster(&described.map, &ClusterOptions::new(k));
        Ok(label_png(described, &labels, |_| 255))
    })
    .await
}
