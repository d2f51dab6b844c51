//! The evaluate page's API: `matseg eval points` on a `--bench` folder for
//! the baselines the page picks and the served model, run in the
//! background: on a thread of its own at the lowest priority, one image at
//! a time (the served model locked for one image), so that clicks on the
//! other pages keep their latency. The page polls for the images done and
//! the report (All / Soft / top-1 scores per model and per image), or for
//! why it failed, and can cancel it.

use crate::annotate::bench;
use crate::app::{ApiError, AppState};
use crate::described::release_freed_memory;
use crate::jobs::{run_in_background, JobProgress};
use axum::extract::{Query, State};
use axum::http::StatusCode;
use axum::Json;
use matseg_eval::evaluate::DEFAULT_MAX_SIDE;
use matseg_image::progress::Progress;
use matseg_pipeline::models::{baselines, known_baselines, ModelChoice};
use matseg_pipeline::point_bench::score_point_benchmark;
use matseg_query::descriptor::{Comparison, DescriptorMap, DescriptorModel};
use serde::Deserialize;
use std::collections::HashMap;
use std::sync::{Arc, Mutex};
use std::time::Instant;

/// Where an evaluation of one benchmark stands.
pub enum Evaluation {
    /// Running since then, with its progress (images done, of all models).
    Running(Instant, Arc<JobProgress>),
    /// Finished: the report.
    Done(serde_json::Value),
    /// Failed: why.
    Failed(String),
    /// Stopped at the page's request (or the server's stop).
    Cancelled,
}

/// Evaluations by benchmark root.
pub type Evaluations = Mutex<HashMap<String, Evaluation>>;

/// A benchmark and the baselines to score beside the model.
#[derive(Deserialize)]
pub struct EvaluateQuery {
    root: String,
    /// Comma-separated baseline names (none: the model alone).
    #[serde(default)]
    baselines: String,
}

/// `POST /api/evaluate`: starts evaluating a benchmark (409 while one of it
/// runs).
pub async fn start(
    State(state): State<Arc<AppState>>,
    Query(query): Query<EvaluateQuery>,
) -> Result<Json<serde_json::Value>, ApiError> {
    let folder = bench(&state, &query.root)?.folder.clone();
    let baselines: Vec<String> = query
        .baselines
        .split(',')
        .map(str::trim)
        .filter(|b| !b.is_empty())
        .map(str::to_string)
        .collect();
    let known = known_baselines();
    if let Some(unknown) = baselines.iter().find(|b| !known.contains(&b.as_str())) {
        return Err(ApiError::bad(format!(
            "baseline {unknown:?}: known are {}",
            known.join(", ")
        )));
    }
    let choice = ModelChoice {
        baselines,
        nets: Vec::new(),
        net_sides: Vec::new(),
        device: state.device,
    };
    let mut evaluations = matseg_image::sync::lock(&state.evaluations);
    if let Some(Evaluation::Running(..)) = evaluations.get(&query.root) {
        return Err(ApiError::new(
            StatusCode::CONFLICT,
            format!("{}: an evaluation is already running", folder.display()),
        ));
    }
    let progress = Arc::new(JobProgress::default());
    let root = query.root.clone();
    let worker = state.clone();
    let job_progress = progress.clone();
    state
        .workers
        .spawn(&format!("evaluate {root}"), progress.clone(), move || {
            let mut done = finished(&folder, || {
                run_in_background(|| run(&folder, &choice, worker.clone(), job_progress.as_ref()))
                    .unwrap_or_else(|e| Err(EvaluationError::Background(e.to_string())))
            });
            if matches!(done, Evaluation::Failed(_)) && job_progress.cancelled() {
                done = Evaluation::Cancelled;
            }
            release_freed_memory();
            matseg_image::sync::lock(&worker.evaluations).insert(root, done);
        })
        .map_err(|e| ApiError::internal(format!("cannot start the evaluation: {e}")))?;
    evaluations.insert(query.root, Evaluation::Running(Instant::now(), progress));
    Ok(Json(serde_json::json!({ "state": "running" })))
}

/// `DELETE /api/evaluate?root=R`: stops the benchmark's running
/// evaluation (it ends as `cancelled`).
pub async fn cancel(
    State(state): State<Arc<AppState>>,
    Query(query): Query<StatusQuery>,
) -> Result<Json<serde_json::Value>, ApiError> {
    bench(&state, &query.root)?;
    let evaluations = matseg_image::sync::lock(&state.evaluations);
    let running = match evaluations.get(&query.root) {
        Some(Evaluation::Running(_, progress)) => {
            progress.cancel();
            true
        }
        _ => false,
    };
    Ok(Json(serde_json::json!({ "cancelling": running })))
}

/// How the evaluation `job` of the benchmark in `folder` ended: done with
/// its report, or failed with its error or, when it panicked, with what
/// the panic said.
fn finished(
    folder: &std::path::Path,
    job: impl FnOnce() -> Result<serde_json::Value, EvaluationError>,
) -> Evaluation {
    match std::panic::catch_unwind(std::panic::AssertUnwindSafe(job)) {
        Ok(Ok(report)) => Evaluation::Done(report),
        Ok(Err(e)) => Evaluation::Failed(e.to_string()),
        Err(panic) => Evaluation::Failed(format!(
            "{}: the evaluation stopped on an internal error: {}",
            folder.display(),
            panic_message(panic.as_ref())
        )),
    }
}

/// What a panic said, when it said it with a string.
fn panic_message(panic: &(dyn std::any::Any + Send)) -> &str {
    panic
        .downcast_ref::<&str>()
        .copied()
        .or_else(|| panic.downcast_ref::<String>().map(String::as_str))
        .unwrap_or("no message")
}

/// Why an evaluation found no report.
#[derive(Debug, thiserror::Error)]
pub enum EvaluationError {
    /// The benchmark or a baseline could not be read or scored.
    #[error(transparent)]
    Pipeline(#[from] matseg_pipeline::error::PipelineError),
    /// A benchmark with no annotated image yet.
    #[error("{}: no annotated image to evaluate", .0.display())]
    NothingAnnotated(std::path::PathBuf),
    /// The background thread pool could not be made.
    #[error("cannot run the evaluation in the background: {0}")]
    Background(String),
}

/// The served model as an evaluated one (each image after the clicks).
struct Served(Arc<AppState>);

impl DescriptorModel for Served {
    fn name(&self) -> &str {
        self.0.model.name()
    }

    fn comparison(&self) -> Comparison {
        DescriptorModel::comparison(&self.0.model)
    }

    /// The image's map; the memory of the previous image's map, dropped by
    /// now, is given back to the system first (a map at the evaluation
    /// size is hundreds of MiB), so the server's memory does not keep the
    /// evaluation's peak.
    fn describe(&self, image: &image::RgbImage) -> DescriptorMap {
        release_freed_memory();
        DescriptorModel::describe(&self.0.model, image)
    }
}

/// Scores the chosen baselines and the served model on the benchmark in
/// `folder`: the report as `matseg eval points --json` prints it.
fn run(
    folder: &std::path::Path,
    choice: &ModelChoice,
    state: Arc<AppState>,
    progress: &JobProgress,
) -> Result<serde_json::Value, EvaluationError> {
    let mut models = baselines(choice)?;
    models.push(Box::new(Served(state)));
    let evaluation = score_point_benchmark(folder, &models, true, DEFAULT_MAX_SIDE, progress)?;
    if evaluation.models[0].counts.images == 0 {
        return Err(EvaluationError::NothingAnnotated(folder.to_path_buf()));
    }
    Ok(serde_json::to_value(evaluation).expect("plain JSON values"))
}

/// A benchmark.
#[derive(Deserialize)]
pub struct StatusQuery {
    root: String,
}

/// `GET /api/evaluate`: where the benchmark's evaluation stands: `idle`,
/// `running` (with the seconds so far, the model being scored, and the
/// images done of the total, every model's images counted), `done` (with
/// the report), `failed` (with the error) or `cancelled`.
pub async fn status(
    State(state): State<Arc<AppState>>,
    Query(query): Query<StatusQuery>,
) -> Result<Json<serde_json::Value>, ApiError> {
    bench(&state, &query.root)?;
    let evaluations = matseg_image::sync::lock(&state.evaluations);
    Ok(Json(match evaluations.get(&query.root) {
        None => serde_json::json!({ "state": "idle" }),
        Some(Evaluation::Running(since, progress)) => {
            let (done, total) = progress.counts();
            serde_json::json!({
                "state": "running",
                "seconds": since.elapsed().as_secs_f64(),
                "model": progress.doing(),
                "done": done,
                "total": total,
            })
        }
        Some(Evaluation::Cancelled) => serde_json::json!({ "state": "cancelled" }),
        Some(Evaluation::Done(report)) => serde_json::json!({ "state": "done", "report": report }),
        Some(Evaluation::Failed(error)) => serde_json::json!({ "state": "failed", "error": error }),
    }))
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    #[test]
    fn a_job_that_panics_is_reported_failed_with_why() {
        let folder = Path::new("bench");
        let failed = |e: Evaluation| match e {
            Evaluation::Failed(message) => message,
            _ => panic!("not failed"),
        };
        let panicked = finished(folder, || panic!("decoder gave up on {}", "a.jpg"));
        assert_eq!(
            failed(panicked),
            "bench: the evaluation stopped on an internal error: decoder gave up on a.jpg"
        );
        let refused = finished(folder, || {
            Err(EvaluationError::NothingAnnotated(folder.to_path_buf()))
        });
        assert_eq!(failed(refused), "bench: no annotated image to evaluate");
        let done = finished(folder, || Ok(serde_json::json!({ "models": [] })));
        assert!(matches!(done, Evaluation::Done(report) if report["models"].is_array()));
    }
}
