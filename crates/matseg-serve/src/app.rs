//! The HTTP side: the pages' static files (built into the binary), the
//! error type every handler answers with, and the router that puts the API
//! of each page under `/api/`, behind the guard (docs/serve.md).

use crate::annotate::BenchFolder;
use crate::browse::DatasetFolder;
use crate::described::{DescribedCache, PhotoWork};
use crate::evaluate::Evaluations;
use crate::guard::Access;
use crate::jobs::Workers;
use crate::model::ServedModel;
use crate::roots::{PathError, Roots};
use crate::uploads::UploadFolder;
use crate::video::Videos;
use crate::{annotate, browse, evaluate, guard, photos, select, video};
use axum::extract::{DefaultBodyLimit, Path, Request, State};
use axum::http::{header, StatusCode};
use axum::middleware::{self, Next};
use axum::response::{IntoResponse, Response};
use axum::routing::{get, post};
use axum::{Json, Router};
use matseg_image::MemoryBudget;
use std::path::PathBuf;
use std::sync::Arc;

/// What the handlers share.
pub struct AppState {
    /// The model photos are described and benchmarks are scored with,
    /// named after its run folder (`default` for the shipped model);
    /// clicks go first.
    pub model: ServedModel,
    /// The device the model runs on.
    pub device: matseg_image::device::ComputeDevice,
    /// The folders photos come from.
    pub roots: Roots,
    /// Photos described so far.
    pub described: DescribedCache,
    /// Turns at the work on photos' full pixels (decoding, describing).
    pub photo_work: PhotoWork,
    /// The bound on the described photos kept in memory.
    pub budget: Arc<MemoryBudget>,
    /// The server's own temporary folder (uploads, tracks), removed when
    /// it stops.
    pub folder: tempfile::TempDir,
    /// Photos and videos the pages uploaded, on disk in [`Self::folder`].
    pub uploads: UploadFolder,
    /// The photos under the photo roots, as root name and path inside.
    pub photos: Vec<(String, PathBuf)>,
    /// The `--data` folders that are datasets.
    pub datasets: Vec<DatasetFolder>,
    /// The `--bench` folders.
    pub benches: Vec<BenchFolder>,
    /// Evaluations run or running, by bench root.
    pub evaluations: Evaluations,
    /// Videos: listed and tracked.
    pub videos: Videos,
    /// The background jobs (tracks, evaluations), stopped with the server.
    pub workers: Workers,
    /// Who may talk to the server.
    pub access: Arc<Access>,
}

/// The pages and the files they load: name, content type, body.
const STATIC_FILES: [(&str, &str, &str); 13] = [
    ("index.html", HTML, include_str!("static/index.html")),
    ("browse.html", HTML, include_str!("static/browse.html")),
    ("annotate.html", HTML, include_str!("static/annotate.html")),
    ("evaluate.html", HTML, include_str!("static/evaluate.html")),
    ("video.html", HTML, include_str!("static/video.html")),
    ("common.js", JS, include_str!("static/common.js")),
    ("segment.js", JS, include_str!("static/segment.js")),
    ("browse.js", JS, include_str!("static/browse.js")),
    ("annotate.js", JS, include_str!("static/annotate.js")),
    ("evaluate.js", JS, include_str!("static/evaluate.js")),
    ("video.js", JS, include_str!("static/video.js")),
    ("style.css", CSS, include_str!("static/style.css")),
    ("favicon.svg", SVG, include_str!("static/favicon.svg")),
];
const HTML: &str = "text/html; charset=utf-8";
const JS: &str = "text/javascript; charset=utf-8";
const CSS: &str = "text/css; charset=utf-8";
const SVG: &str = "image/svg+xml";

/// The static file `name` (`/browse` stands for `browse.html`).
fn static_file(name: &str) -> Response {
    let name = if name.is_empty() { "index.html" } else { name };
    let page = format!("{name}.html");
    match STATIC_FILES
        .iter()
        .find(|(file, _, _)| *file == name || *file == page)
    {
        Some((_, kind, body)) => ([(header::CONTENT_TYPE, *kind)], *body).into_response(),
        None => {
            ApiError::new(StatusCode::NOT_FOUND, format!("{name:?}: no such page")).into_response()
        }
    }
}

/// The router of the app over `state`.
pub fn router(state: Arc<AppState>) -> Router {
    let api = Router::new()
        .route("/api/status", get(status))
        .route("/api/photos", get(photos::list))
        .route("/api/photo", get(photos::photo))
        .route(
            "/api/upload",
            post(photos::upload).layer(DefaultBodyLimit::disable()),
        )
        .route("/api/similarity", get(photos::similarity))
        .route("/api/segment", get(photos::segment))
        .route("/api/auto", get(photos::auto))
        .route("/api/select", get(select::selection))
        .route("/api/select/save", get(select::save))
        .route("/api/datasets", get(browse::datasets))
        .route("/api/samples", get(browse::samples))
        .route("/api/sample", get(browse::sample))
        .route("/api/sample/image", get(browse::sample_image))
        .route("/api/benches", get(annotate::benches))
        .route("/api/annotation", get(annotate::load).post(annotate::save))
        .route(
            "/api/evaluate",
            get(evaluate::status)
                .post(evaluate::start)
                .delete(evaluate::cancel),
        )
        .route("/api/videos", get(video::list))
        .route("/api/video", get(video::video))
        .route(
            "/api/video/upload",
            post(video::upload).layer(DefaultBodyLimit::disable()),
        )
        .route("/api/video/frame", get(video::frame))
        .route(
            "/api/track",
            get(video::status).post(video::start).delete(video::cancel),
        )
        .route("/api/track/frame", get(video::job_frame))
        .route("/api/track/overlay", get(video::job_overlay))
        .route("/api/track/download", get(video::download))
        .route_layer(middleware::from_fn(server_timing));
    let access = state.access.clone();
    Router::new()
        .route("/", get(|| async { static_file("") }))
        .route(
            "/{file}",
            get(|Path(file): Path<String>| async move { static_file(&file) }),
        )
        .merge(api)
        .with_state(state)
        .layer(middleware::from_fn(json_errors))
        .layer(middleware::from_fn_with_state(access, guard::check))
}

/// Makes every error answer the API's own kind, `{"error": "one line"}`:
/// the framework's refusals (a query that does not parse, a body past its
/// limit, an unknown route or method) come as plain text or nothing.
async fn json_errors(request: Request, next: Next) -> Response {
    let response = next.run(request).await;
    let status = response.status();
    let is_json = response
        .headers()
        .get(header::CONTENT_TYPE)
        .is_some_and(|kind| kind.as_bytes().starts_with(b"application/json"));
    if !(status.is_client_error() || status.is_server_error()) || is_json {
        return response;
    }
    let text = axum::body::to_bytes(response.into_body(), 64 << 10)
        .await
        .map(|body| String::from_utf8_lossy(&body).into_owned())
        .unwrap_or_default();
    let message = text.split_whitespace().collect::<Vec<_>>().join(" ");
    let message = if message.is_empty() {
        status.canonical_reason().unwrap_or("refused").to_string()
    } else {
        message
    };
    ApiError::new(status, message).into_response()
}

/// `GET /api/status`: what the server holds in memory against its bound,
/// in MiB.
async fn status(State(state): State<Arc<AppState>>) -> Json<serde_json::Value> {
    let mib = |bytes: usize| bytes as f64 / (1 << 20) as f64;
    Json(serde_json::json!({
        "described_mib": mib(state.described.bytes()),
        "bound_mib": mib(state.budget.limit()),
        "uploads_mib": mib(state.uploads.bytes() as usize),
        "uploads_bound_mib": mib(state.uploads.limit() as usize),
    }))
}

/// An API error: a status and a one-line message, sent as `{"error": ...}`.
#[derive(Debug)]
pub struct ApiError {
    status: StatusCode,
    message: String,
}

impl ApiError {
    /// An error with `status` and a one-line `message`.
    pub fn new(status: StatusCode, message: impl Into<String>) -> Self {
        Self {
            status,
            message: message.into(),
        }
    }

    /// The status it is answered with.
    pub fn status(&self) -> StatusCode {
        self.status
    }

    /// Its one-line message.
    pub fn message(&self) -> &str {
        &self.message
    }

    /// A 400: the request is wrong.
    pub fn bad(message: impl Into<String>) -> Self {
        Self::new(StatusCode::BAD_REQUEST, message)
    }

    /// A 404: nothing by that name.
    pub fn not_found(message: impl Into<String>) -> Self {
        Self::new(StatusCode::NOT_FOUND, message)
    }

    /// A 500: the server failed (a worker stopped, a file could not be
    /// written).
    pub fn internal(message: impl Into<String>) -> Self {
        Self::new(StatusCode::INTERNAL_SERVER_ERROR, message)
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

/// The name an upload asks for (`?name=FILE`; empty when none).
#[derive(serde::Deserialize)]
pub struct UploadName {
    /// The file name the page gave.
    #[serde(default)]
    pub name: String,
}

/// Runs `work` on a blocking thread (decoding, describing, reading
/// samples), off the async workers.
pub async fn blocking<T: Send + 'static>(
    work: impl FnOnce() -> Result<T, ApiError> + Send + 'static,
) -> Result<T, ApiError> {
    tokio::task::spawn_blocking(work)
        .await
        .map_err(|e| ApiError::internal(e.to_string()))?
}

/// Adds the time the server spent on an API call to its answer, as the
/// standard `Server-Timing: app;dur=MILLISECONDS` header (browsers' network
/// panels and `matseg bench-serve` read it).
async fn server_timing(request: Request, next: Next) -> Response {
    let started = std::time::Instant::now();
    let mut response = next.run(request).await;
    let timing = format!("app;dur={:.3}", started.elapsed().as_secs_f64() * 1e3);
    if let Ok(value) = header::HeaderValue::from_str(&timing) {
        response.headers_mut().insert("server-timing", value);
    }
    response
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_pages_draw_labels_in_the_command_lines_palette() {
        let common = STATIC_FILES[5].2;
        let start = common.find("PALETTE = [").unwrap();
        let end = start + common[start..].find("];").unwrap();
        let numbers: Vec<u8> = common[start + 11..end]
            .split(|c: char| !c.is_ascii_digit())
            .filter(|n| !n.is_empty())
            .map(|n| n.parse().unwrap())
            .collect();
        assert_eq!(numbers, matseg_scene::PALETTE.concat());
    }

    #[test]
    fn pages_are_found_with_or_without_their_extension() {
        for (name, kind) in [
            ("", HTML),
            ("browse", HTML),
            ("annotate.html", HTML),
            ("common.js", JS),
            ("favicon.svg", SVG),
        ] {
            let response = static_file(name);
            assert_eq!(response.status(), StatusCode::OK, "{name}");
            assert_eq!(response.headers()[header::CONTENT_TYPE], kind, "{name}");
        }
        assert_eq!(static_file("secret").status(), StatusCode::NOT_FOUND);
    }
}
