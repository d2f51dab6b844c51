//! The video page's API: the videos under the served folders and uploaded
//! ones, a frame to click on, and tracking jobs (`matseg track` on a thread
//! of its own, the served model locked one frame at a time so clicks on
//! other pages are answered meanwhile) whose frames, labels, overlay and
//! label archive the page then shows and downloads.
//!
//! Jobs write into the server's own temporary folder, removed when the
//! server stops; the newest [`KEPT_TRACKS`] finished jobs are kept.

use crate::app::{blocking, ApiError, AppState, UploadName};
use crate::jobs::JobProgress;
use crate::uploads::Upload;
use axum::body::Body;
use axum::extract::{Query, State};
use axum::http::{header, StatusCode};
use axum::response::{IntoResponse, Response};
use axum::Json;
use matseg_image::io::encode_jpeg;
use matseg_pipeline::frames::FrameSource;
use matseg_pipeline::track::{
    track_to_folder, TrackFiles, TrackReport, TrackSettings, FRAME_JPEG_QUALITY, MAX_TRACK_POINTS,
};
use serde::Deserialize;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};

/// Video file extensions the video list shows.
pub const VIDEO_EXTENSIONS: [&str; 6] = ["mp4", "m4v", "mov", "webm", "mkv", "avi"];

/// The largest video upload accepted, in bytes.
pub const MAX_VIDEO_UPLOAD_BYTES: u64 = 512 << 20;

/// Finished tracking jobs kept on disk (older ones are removed).
pub const KEPT_TRACKS: usize = 2;

/// The most frames a track of the web app follows (5 minutes at 30 frames
/// a second): its folder keeps every frame as a JPEG, so this bounds the
/// disk a track takes (a few GB at 1080p).
pub const MAX_TRACK_FRAMES: u64 = 9000;

/// The root name of uploaded videos.
pub const VIDEO_UPLOAD_ROOT: &str = "upload";

/// Where a tracking job stands.
enum JobState {
    /// Running (its progress counts the frames).
    Running,
    /// Finished: what `track.json` holds.
    Done(Box<TrackReport>),
    /// Failed: the one-line reason.
    Failed(String),
}

/// One tracking job: its folder and progress.
struct Job {
    id: u64,
    dir: PathBuf,
    /// The video's file stem, which its downloads are named after.
    stem: String,
    progress: Arc<JobProgress>,
    state: JobState,
}

/// The server's videos: those listed at start, and the tracking jobs
/// (uploaded videos are kept in [`crate::uploads::UploadFolder`]).
pub struct Videos {
    /// The videos under the photo folders, listed at start.
    pub listed: Vec<(String, PathBuf)>,
    /// Where the jobs write (a folder in the server's temporary folder).
    tracks: PathBuf,
    jobs: Mutex<Vec<Job>>,
    next_id: AtomicU64,
}

impl Videos {
    /// The listed videos; jobs will write into `tracks`.
    pub fn new(listed: Vec<(String, PathBuf)>, tracks: PathBuf) -> Self {
        Videos {
            listed,
            tracks,
            jobs: Mutex::default(),
            next_id: AtomicU64::new(1),
        }
    }
}

/// A video named by root and path (`upload` and the name an upload was
/// given, or a served folder and a file in it).
#[derive(Clone, Deserialize)]
pub struct VideoRef {
    /// The root.
    pub root: String,
    /// The path inside it.
    pub path: String,
}

impl VideoRef {
    /// The video's file (an upload in use while it is held), and the name
    /// errors give it.
    fn file(&self, state: &AppState) -> Result<(PathBuf, Option<Upload>, String), ApiError> {
        if self.root == VIDEO_UPLOAD_ROOT {
            let upload = state
                .uploads
                .get(crate::roots::plain_name(&self.path)?)
                .filter(|_| is_video_name(&self.path))
                .ok_or_else(|| {
                    ApiError::not_found(format!(
                        "upload {:?}: not kept; upload it again",
                        self.path
                    ))
                })?;
            return Ok((upload.file.clone(), Some(upload), self.path.clone()));
        }
        let file = state.roots.resolve(&self.root, &self.path)?;
        if !is_video_name(&self.path) {
            return Err(ApiError::bad(format!("{}: not a video file", self.path)));
        }
        Ok((file, None, self.path.clone()))
    }

    /// The video opened (probed by ffprobe), with its upload in use while
    /// held; errors name it as the page does, not by the server's path.
    fn open(&self, state: &AppState) -> Result<(FrameSource, Option<Upload>, String), ApiError> {
        let (file, upload, name) = self.file(state)?;
        let source = FrameSource::open(&file).map_err(|e| renamed(&e.to_string(), &file, &name))?;
        Ok((source, upload, name))
    }
}

/// Whether `name` has a video file's extension.
fn is_video_name(name: &str) -> bool {
    matseg_image::io::has_extension(Path::new(name), &VIDEO_EXTENSIONS)
}

/// A 400 with `message`, the file's path in it replaced by `name`.
fn renamed(message: &str, file: &Path, name: &str) -> ApiError {
    ApiError::bad(message.replace(&file.display().to_string(), name))
}

/// What the page needs of a video.
fn info(source: &FrameSource) -> serde_json::Value {
    serde_json::json!({
        "width": source.width,
        "height": source.height,
        "fps": source.fps,
        "frames": source.frame_count(),
    })
}

/// `GET /api/videos`: the videos listed at start and those uploaded.
pub async fn list(State(state): State<Arc<AppState>>) -> Json<serde_json::Value> {
    let mut videos: Vec<_> = state
        .videos
        .listed
        .iter()
        .map(|(root, path)| serde_json::json!({ "root": root, "path": path }))
        .collect();
    videos.extend(
        state
            .uploads
            .names(is_video_name)
            .into_iter()
            .map(|name| serde_json::json!({ "root": VIDEO_UPLOAD_ROOT, "path": name })),
    );
    Json(serde_json::json!({ "videos": videos }))
}

/// `GET /api/video`: a video's size, frame rate and frame count.
pub async fn video(
    State(state): State<Arc<AppState>>,
    Query(video): Query<VideoRef>,
) -> Result<Json<serde_json::Value>, ApiError> {
    blocking(move || Ok(Json(info(&video.open(&state)?.0)))).await
}

/// `POST /api/video/upload?name=FILE`: a video as the body, written to the
/// uploads folder as it arrives and kept under its name (a later upload of
/// that name replaces it); answers its reference and [`info`]. Too large:
/// 413; no room: 507; not a readable video, or one with no frames: 400,
/// and nothing kept.
pub async fn upload(
    State(state): State<Arc<AppState>>,
    Query(name): Query<UploadName>,
    body: Body,
) -> Result<Json<serde_json::Value>, ApiError> {
    let name = upload_name(&name.name)?;
    let arrived = state
        .uploads
        .receive(body, MAX_VIDEO_UPLOAD_BYTES, "video upload")
        .await?;
    let source = blocking({
        let (file, name) = (arrived.file.clone(), name.clone());
        move || FrameSource::open(&file).map_err(|e| renamed(&e.to_string(), &file, &name))
    })
    .await?;
    arrived.keep(&name)?;
    let mut answer = info(&source);
    answer["root"] = VIDEO_UPLOAD_ROOT.into();
    answer["path"] = name.into();
    Ok(Json(answer))
}

/// The file name an upload is kept under: its own name's last part, with
/// a video extension.
fn upload_name(asked: &str) -> Result<String, ApiError> {
    let name = asked.rsplit(['/', '\\']).next().unwrap_or_default().trim();
    let ok = !name.is_empty()
        && !name.starts_with('.')
        && name
            .chars()
            .all(|c| c.is_alphanumeric() || matches!(c, '.' | '-' | '_' | ' '))
        && is_video_name(name);
    if ok {
        Ok(name.to_string())
    } else {
        Err(ApiError::bad(format!(
            "upload name {asked:?}: give the video's file name ({})",
            VIDEO_EXTENSIONS.join(", ")
        )))
    }
}

/// A frame of a video.
#[derive(Deserialize)]
pub struct FrameQuery {
    root: String,
    path: String,
    #[serde(default)]
    frame: u64,
}

/// `GET /api/video/frame`: frame `frame` as JPEG (the frames before it are
/// decoded on the way, so a frame far into a long video takes a while).
pub async fn frame(
    State(state): State<Arc<AppState>>,
    Query(query): Query<FrameQuery>,
) -> Result<Response, ApiError> {
    let bytes = blocking(move || {
        let video = VideoRef {
            root: query.root,
            path: query.path,
        };
        let (source, _upload, name) = video.open(&state)?;
        let frame = source
            .frame(query.frame)
            .map_err(|e| renamed(&e.to_string(), &source.path, &name))?;
        Ok(encode_jpeg(&frame, FRAME_JPEG_QUALITY))
    })
    .await?;
    Ok(([(header::CONTENT_TYPE, "image/jpeg")], bytes).into_response())
}

/// What to follow: a video, the frame clicked and the points on it.
#[derive(Deserialize)]
pub struct TrackQuery {
    root: String,
    path: String,
    #[serde(default)]
    frame: u64,
    points: String,
    /// Negative clicks, `x,y;x,y...`: materials no point's may take.
    #[serde(default)]
    negative: String,
    radius: Option<f32>,
}

/// `POST /api/track`: starts following the materials under `points`
/// (`x,y;x,y...`, clicked on `frame`) through the video, none of them
/// taking the materials under the `negative` clicks; answers the job's
/// id. One job runs at a time (409 while one does).
pub async fn start(
    State(state): State<Arc<AppState>>,
    Query(query): Query<TrackQuery>,
) -> Result<Json<serde_json::Value>, ApiError> {
    let points = crate::photos::parse_points(&query.points, MAX_TRACK_POINTS)?;
    let negatives = crate::select::parse_clicks("negative", &query.negative)?;
    if points.len() + negatives.len() > MAX_TRACK_POINTS {
        return Err(ApiError::bad(format!(
            "points, negative: {} clicks; at most {MAX_TRACK_POINTS} in all",
            points.len() + negatives.len()
        )));
    }
    let radius = crate::photos::checked_radius(query.radius)?;
    let video = VideoRef {
        root: query.root,
        path: query.path,
    };
    let (source, upload, name) = {
        let state = state.clone();
        blocking(move || video.open(&state)).await?
    };
    check_points("point", &points, (source.width, source.height), &name)?;
    check_points("negative", &negatives, (source.width, source.height), &name)?;
    let frames = source.frame_count();
    if frames > MAX_TRACK_FRAMES {
        return Err(ApiError::bad(format!(
            "{name}: {frames} frames; the web app tracks videos of up to {MAX_TRACK_FRAMES} frames (`matseg track` has no limit)"
        )));
    }
    if query.frame >= frames {
        return Err(ApiError::bad(format!(
            "frame {}: past the end: {name} has {frames} frames",
            query.frame
        )));
    }
    let mut settings = TrackSettings::new(points);
    settings.negatives = negatives;
    settings.frame = query.frame;
    settings.radius = radius;
    let mut jobs = matseg_image::sync::lock(&state.videos.jobs);
    if jobs.iter().any(|j| matches!(j.state, JobState::Running)) {
        return Err(ApiError::new(
            StatusCode::CONFLICT,
            "a video is being tracked already; wait for it, or cancel it",
        ));
    }
    forget_old_jobs(&mut jobs);
    let id = state.videos.next_id.fetch_add(1, Ordering::Relaxed);
    let dir = state.videos.tracks.join(format!("track-{id}"));
    let progress = Arc::new(JobProgress::default());
    let worker = state.clone();
    let job_progress = progress.clone();
    let shown = name.clone();
    state
        .workers
        .spawn(&format!("track {id}"), progress.clone(), move || {
            // The upload stays while it is tracked.
            let _upload = upload;
            let outcome = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                let files = TrackFiles {
                    mp4: true,
                    frames: true,
                };
                track_to_folder(
                    &worker.model,
                    &source,
                    &settings,
                    &dir,
                    files,
                    job_progress.as_ref(),
                )
            }));
            let done = match outcome {
                Ok(Ok(report)) => JobState::Done(Box::new(report)),
                Ok(Err(e)) => JobState::Failed(
                    e.to_string()
                        .replace(&source.path.display().to_string(), &shown),
                ),
                Err(_) => {
                    JobState::Failed(format!("{shown}: tracking stopped on an internal error"))
                }
            };
            let mut jobs = matseg_image::sync::lock(&worker.videos.jobs);
            if let Some(job) = jobs.iter_mut().find(|j| j.id == id) {
                job.state = done;
            }
        })
        .map_err(|e| ApiError::internal(format!("cannot start tracking: {e}")))?;
    jobs.push(Job {
        id,
        dir: state.videos.tracks.join(format!("track-{id}")),
        stem: download_stem(&name),
        progress,
        state: JobState::Running,
    });
    Ok(Json(serde_json::json!({ "job": id })))
}

/// Points (`what`: the argument's name) checked against frames of `name`
/// of `width` x `height`: each inside.
fn check_points(
    what: &str,
    points: &[(f32, f32)],
    (width, height): (u32, u32),
    name: &str,
) -> Result<(), ApiError> {
    if let Some((x, y)) = points
        .iter()
        .find(|(x, y)| !(0.0..width as f32).contains(x) || !(0.0..height as f32).contains(y))
    {
        return Err(ApiError::bad(format!(
            "{what} {x},{y}: outside the {width}x{height} frames of {name}"
        )));
    }
    Ok(())
}

/// `DELETE /api/track?job=ID`: stops a running job (it ends as failed,
/// "cancelled"); a finished one is left as it is.
pub async fn cancel(
    State(state): State<Arc<AppState>>,
    Query(query): Query<JobQuery>,
) -> Result<Json<serde_json::Value>, ApiError> {
    let jobs = matseg_image::sync::lock(&state.videos.jobs);
    let job = find_job(&jobs, query.job)?;
    job.progress.cancel();
    Ok(Json(
        serde_json::json!({ "job": query.job, "cancelling": matches!(job.state, JobState::Running) }),
    ))
}

/// Removes the finished jobs beyond the newest [`KEPT_TRACKS`] - 1 (a new
/// one is about to start), and their folders.
fn forget_old_jobs(jobs: &mut Vec<Job>) {
    while jobs.len() >= KEPT_TRACKS {
        let old = jobs.remove(0);
        let _ = std::fs::remove_dir_all(&old.dir);
    }
}

/// A job.
#[derive(Deserialize)]
pub struct JobQuery {
    job: u64,
}

/// `GET /api/track?job=ID`: where the job stands: `running` (frames done
/// of the total), `done` (with what `track.json` holds) or `failed` (with
/// the reason).
pub async fn status(
    State(state): State<Arc<AppState>>,
    Query(query): Query<JobQuery>,
) -> Result<Json<serde_json::Value>, ApiError> {
    let jobs = matseg_image::sync::lock(&state.videos.jobs);
    let job = find_job(&jobs, query.job)?;
    let (done, total) = job.progress.counts();
    Ok(Json(match &job.state {
        JobState::Running => {
            serde_json::json!({ "state": "running", "done": done, "total": total })
        }
        JobState::Done(report) => {
            serde_json::json!({ "state": "done", "done": done, "total": total, "report": report })
        }
        JobState::Failed(error) => serde_json::json!({ "state": "failed", "error": error }),
    }))
}

fn find_job(jobs: &[Job], id: u64) -> Result<&Job, ApiError> {
    jobs.iter().find(|j| j.id == id).ok_or_else(|| {
        ApiError::not_found(format!(
            "track job {id}: no such job (or an old one, removed)"
        ))
    })
}

/// The file stem of `name` with anything but letters, digits, `.`, `-`
/// and `_` as `_`: what a job's downloads are named after.
fn download_stem(name: &str) -> String {
    let stem = Path::new(name)
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    stem.chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || matches!(c, '.' | '-' | '_') {
                c
            } else {
                '_'
            }
        })
        .collect()
}

/// A finished job's folder, and the stem its downloads are named after.
fn finished_dir(state: &AppState, id: u64) -> Result<(PathBuf, String), ApiError> {
    let jobs = matseg_image::sync::lock(&state.videos.jobs);
    let job = find_job(&jobs, id)?;
    match &job.state {
        JobState::Done(_) => Ok((job.dir.clone(), job.stem.clone())),
        JobState::Running => Err(ApiError::new(
            StatusCode::CONFLICT,
            format!("track job {id}: still running"),
        )),
        JobState::Failed(e) => Err(ApiError::bad(format!("track job {id} failed: {e}"))),
    }
}

/// A frame of a finished job, and which part of it.
#[derive(Deserialize)]
pub struct JobFrameQuery {
    job: u64,
    frame: u64,
    /// `image` (the default) or `labels`.
    #[serde(default)]
    part: FramePart,
}

/// What of a tracked frame to answer.
#[derive(Clone, Copy, Default, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum FramePart {
    /// The frame as the job decoded it (JPEG).
    #[default]
    Image,
    /// Its labels (8-bit grey PNG: 0 none, k the k-th point's material).
    Labels,
}

/// `GET /api/track/frame?job&frame[&part=labels]`: a tracked frame, or its
/// labels.
pub async fn job_frame(
    State(state): State<Arc<AppState>>,
    Query(query): Query<JobFrameQuery>,
) -> Result<Response, ApiError> {
    let (file, kind) = match query.part {
        FramePart::Image => (format!("frames/{:06}.jpg", query.frame), "image/jpeg"),
        FramePart::Labels => (format!("labels/{:06}.png", query.frame), "image/png"),
    };
    job_file(&state, query.job, &file, kind).await
}

/// `GET /api/track/overlay?job`: the overlay video (MP4, or the animated
/// PNG preview where ffmpeg could not encode one).
pub async fn job_overlay(
    State(state): State<Arc<AppState>>,
    Query(query): Query<JobQuery>,
) -> Result<Response, ApiError> {
    let (dir, stem) = finished_dir(&state, query.job)?;
    let (name, kind) = if dir.join("overlay.mp4").is_file() {
        ("overlay.mp4", "video/mp4")
    } else {
        ("overlay.png", "image/apng")
    };
    let mut response = job_file(&state, query.job, name, kind).await?;
    attach(&mut response, &format!("{stem}-{name}"));
    Ok(response)
}

/// A finished job's file `name` with content type `kind`.
async fn job_file(
    state: &Arc<AppState>,
    id: u64,
    name: &str,
    kind: &'static str,
) -> Result<Response, ApiError> {
    let file = finished_dir(state, id)?.0.join(name);
    let shown = name.to_string();
    let bytes = blocking(move || {
        std::fs::read(&file).map_err(|_| ApiError::not_found(format!("track job {id}: no {shown}")))
    })
    .await?;
    Ok(([(header::CONTENT_TYPE, kind)], bytes).into_response())
}

/// Marks `response` as a download named `name`.
fn attach(response: &mut Response, name: &str) {
    if let Ok(value) = header::HeaderValue::from_str(&format!("attachment; filename=\"{name}\"")) {
        response
            .headers_mut()
            .insert(header::CONTENT_DISPOSITION, value);
    }
}

/// `GET /api/track/download?job`: `STEM-labels.tar` with the job's
/// `labels/NNNNNN.png` and `track.json`, as `matseg track` writes them.
pub async fn download(
    State(state): State<Arc<AppState>>,
    Query(query): Query<JobQuery>,
) -> Result<Response, ApiError> {
    let (dir, stem) = finished_dir(&state, query.job)?;
    let bytes =
        blocking(move || labels_tar(&dir).map_err(|e| ApiError::internal(e.to_string()))).await?;
    let mut response = ([(header::CONTENT_TYPE, "application/x-tar")], bytes).into_response();
    attach(&mut response, &format!("{stem}-labels.tar"));
    Ok(response)
}

/// A tar of `dir`'s `track.json` and label PNGs.
fn labels_tar(dir: &Path) -> std::io::Result<Vec<u8>> {
    let mut names: Vec<PathBuf> = std::fs::read_dir(dir.join("labels"))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .collect();
    names.sort();
    let mut tar = tar::Builder::new(Vec::new());
    matseg_data::wds::append_member(
        &mut tar,
        "track.json",
        &std::fs::read(dir.join("track.json"))?,
    )?;
    for file in names {
        let name = format!(
            "labels/{}",
            file.file_name().unwrap_or_default().to_string_lossy()
        );
        matseg_data::wds::append_member(&mut tar, &name, &std::fs::read(&file)?)?;
    }
    tar.into_inner()
}
