//! The HTTP side: the page's static files (built into the binary) and the
//! JSON and image API under `/api/` (docs/serve.md).

use crate::described::{Described, DescribedCache};
use crate::roots::{PathError, Roots};
use axum::extract::{Query, Request, State};
use axum::http::{header, HeaderMap, StatusCode};
use axum::middleware::{self, Next};
use axum::response::{IntoResponse, Response};
use axum::routing::get;
use axum::{Json, Router};
use matseg_image::io::{encode_png_gray, find_files, read_rgb};
use matseg_image::LibraryError;
use matseg_pipeline::segment::{check_points, describe, query_points, Model, DEFAULT_RADIUS};
use serde::Deserialize;
use std::path::PathBuf;
use std::sync::{Arc, Mutex};

/// What the handlers share.
pub struct AppState {
    /// The model photos are described with.
    pub model: Mutex<Model>,
    /// The folders photos come from.
    pub roots: Roots,
    /// Photos described so far.
    pub described: DescribedCache,
    /// The photos under the roots, as root name and path inside.
    pub photos: Vec<(String, PathBuf)>,
    /// The token every API call must carry, when set.
    pub token: Option<String>,
}

/// The page, its script and its style sheet.
const INDEX: &str = include_str!("static/index.html");
const APP_JS: &str = include_str!("static/app.js");
const STYLE: &str = include_str!("static/style.css");

/// Image extensions the photo list shows.
const PHOTO_EXTENSIONS: [&str; 3] = ["jpg", "jpeg", "png"];

/// Most photos one listing request returns.
const MAX_LISTING: usize = 1000;

/// The router of the app over `state`.
pub fn router(state: Arc<AppState>) -> Router {
    let api = Router::new()
        .route("/api/photos", get(photos))
        .route("/api/photo", get(photo))
        .route("/api/similarity", get(similarity))
        .route("/api/segment", get(segment))
        .route_layer(middleware::from_fn_with_state(state.clone(), check_token));
    Router::new()
        .route(
            "/",
            get(|| async { page(INDEX, "text/html; charset=utf-8") }),
        )
        .route(
            "/app.js",
            get(|| async { page(APP_JS, "text/javascript; charset=utf-8") }),
        )
        .route(
            "/style.css",
            get(|| async { page(STYLE, "text/css; charset=utf-8") }),
        )
        .merge(api)
        .with_state(state)
}

fn page(body: &'static str, content_type: &'static str) -> Response {
    ([(header::CONTENT_TYPE, content_type)], body).into_response()
}

/// An API error: a status and a one-line message, sent as `{"error": ...}`.
#[derive(Debug)]
pub struct ApiError {
    status: StatusCode,
    message: String,
}

impl ApiError {
    fn new(status: StatusCode, message: impl Into<String>) -> Self {
        Self {
            status,
            message: message.into(),
        }
    }
}

impl IntoResponse for ApiError {
    fn into_response(self) -> Response {
        (
            self.status,
            Json(serde_json::json!({ "error": self.message })),
        )
            .into_response()
    }
}

impl From<PathError> for ApiError {
    fn from(e: PathError) -> Self {
        let status = match e {
            PathError::Outside(_) => StatusCode::FORBIDDEN,
            PathError::UnknownRoot(_) | PathError::Missing(_) => StatusCode::NOT_FOUND,
        };
        Self::new(status, e.to_string())
    }
}

/// Refuses API calls without the server's token (header `x-matseg-token`
/// or query `token`), when it has one.
async fn check_token(
    State(state): State<Arc<AppState>>,
    headers: HeaderMap,
    request: Request,
    next: Next,
) -> Response {
    if let Some(token) = &state.token {
        let from_header = headers.get("x-matseg-token").and_then(|v| v.to_str().ok());
        let from_query = request
            .uri()
            .query()
            .and_then(|q| q.split('&').find_map(|kv| kv.strip_prefix("token=")));
        if from_header != Some(token.as_str()) && from_query != Some(token.as_str()) {
            return ApiError::new(StatusCode::UNAUTHORIZED, "a valid token is required")
                .into_response();
        }
    }
    next.run(request).await
}

/// A page of the photos under the roots.
#[derive(Deserialize)]
struct Listing {
    #[serde(default)]
    offset: usize,
    limit: Option<usize>,
}

async fn photos(
    State(state): State<Arc<AppState>>,
    Query(listing): Query<Listing>,
) -> Result<Json<serde_json::Value>, ApiError> {
    let limit = listing.limit.unwrap_or(200).min(MAX_LISTING);
    let items: Vec<_> = state
        .photos
        .iter()
        .skip(listing.offset)
        .take(limit)
        .map(|(root, path)| serde_json::json!({ "root": root, "path": path }))
        .collect();
    Ok(Json(serde_json::json!({
        "total": state.photos.len(),
        "offset": listing.offset,
        "photos": items
    })))
}

/// The photos under `roots`, each as its root's name and its path inside,
/// listed once when the server starts.
pub fn list_photos(roots: &Roots) -> Result<Vec<(String, PathBuf)>, LibraryError> {
    let mut photos = Vec::new();
    for (name, dir) in roots.iter() {
        for file in find_files(&[dir.to_path_buf()], &PHOTO_EXTENSIONS)? {
            let path = file.strip_prefix(dir).unwrap_or(&file).to_path_buf();
            photos.push((name.to_string(), path));
        }
    }
    Ok(photos)
}

/// A photo named by root and path.
#[derive(Deserialize)]
struct PhotoRef {
    root: String,
    path: String,
}

async fn photo(
    State(state): State<Arc<AppState>>,
    Query(photo): Query<PhotoRef>,
) -> Result<Response, ApiError> {
    let file = state.roots.resolve(&photo.root, &photo.path)?;
    let bytes = std::fs::read(&file)
        .map_err(|e| ApiError::new(StatusCode::NOT_FOUND, format!("{}: {e}", photo.path)))?;
    let content_type = if file
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("png"))
    {
        "image/png"
    } else {
        "image/jpeg"
    };
    Ok(([(header::CONTENT_TYPE, content_type)], bytes).into_response())
}

/// The photo described, from the cache or now (off the async threads).
async fn described(state: &Arc<AppState>, photo: &PhotoRef) -> Result<Arc<Described>, ApiError> {
    let file = state.roots.resolve(&photo.root, &photo.path)?;
    let key = format!("{}/{}", photo.root, file.display());
    if let Some(d) = state.described.get(&key) {
        return Ok(d);
    }
    let state = state.clone();
    tokio::task::spawn_blocking(move || {
        let image =
            read_rgb(&file).map_err(|e| ApiError::new(StatusCode::BAD_REQUEST, e.to_string()))?;
        let map = {
            let model = state.model.lock().unwrap_or_else(|e| e.into_inner());
            describe(&model, &image)
        };
        let described = Arc::new(Described { photo: image, map });
        state
            .described
            .insert(key, described.clone(), described.bytes());
        Ok(described)
    })
    .await
    .map_err(|e| ApiError::new(StatusCode::INTERNAL_SERVER_ERROR, e.to_string()))?
}

/// Points `x,y;x,y...` in photo pixels.
fn parse_points(text: &str) -> Result<Vec<(f32, f32)>, ApiError> {
    text.split(';')
        .filter(|p| !p.trim().is_empty())
        .map(|p| {
            let (x, y) = p.split_once(',')?;
            Some((x.trim().parse().ok()?, y.trim().parse().ok()?))
        })
        .collect::<Option<Vec<_>>>()
        .ok_or_else(|| {
            ApiError::new(
                StatusCode::BAD_REQUEST,
                format!("points {text:?}: expected X,Y;X,Y..."),
            )
        })
}

/// A photo and points on it.
#[derive(Deserialize)]
struct PointsQuery {
    root: String,
    path: String,
    points: String,
    radius: Option<f32>,
}

impl PointsQuery {
    fn photo(&self) -> PhotoRef {
        PhotoRef {
            root: self.root.clone(),
            path: self.path.clone(),
        }
    }
}

/// The photo described and the points checked against it.
async fn described_with_points(
    state: &Arc<AppState>,
    query: &PointsQuery,
) -> Result<(Arc<Described>, Vec<(f32, f32)>), ApiError> {
    let points = parse_points(&query.points)?;
    let described = described(state, &query.photo()).await?;
    check_points(&described.photo, &points, &query.path)
        .map_err(|e| ApiError::new(StatusCode::BAD_REQUEST, e.to_string()))?;
    Ok((described, points))
}

fn png(width: u32, height: u32, grey: &[u8]) -> Response {
    (
        [(header::CONTENT_TYPE, "image/png")],
        encode_png_gray(width, height, grey),
    )
        .into_response()
}

/// The similarity map of the first point: cosine in [0, 1] as grey.
async fn similarity(
    State(state): State<Arc<AppState>>,
    Query(query): Query<PointsQuery>,
) -> Result<Response, ApiError> {
    let (described, points) = described_with_points(&state, &query).await?;
    let first = points
        .first()
        .ok_or_else(|| ApiError::new(StatusCode::BAD_REQUEST, "points: give one point"))?;
    let maps = query_points(
        &described.map,
        &[*first],
        query.radius.unwrap_or(DEFAULT_RADIUS),
    );
    let grey = matseg_pipeline::segment::similarity_grey(&maps.similarity[0]);
    let (w, h) = described.photo.dimensions();
    Ok(png(w, h, &grey))
}

/// The nearest-point segmentation of two points or more: each pixel's
/// label (the index of its point) as grey.
async fn segment(
    State(state): State<Arc<AppState>>,
    Query(query): Query<PointsQuery>,
) -> Result<Response, ApiError> {
    let (described, points) = described_with_points(&state, &query).await?;
    if points.len() < 2 {
        return Err(ApiError::new(
            StatusCode::BAD_REQUEST,
            "points: give two points or more",
        ));
    }
    let maps = query_points(
        &described.map,
        &points,
        query.radius.unwrap_or(DEFAULT_RADIUS),
    );
    let labels: Vec<u8> = maps
        .labels
        .expect("two points or more")
        .iter()
        .map(|&l| l as u8)
        .collect();
    let (w, h) = described.photo.dimensions();
    Ok(png(w, h, &labels))
}
