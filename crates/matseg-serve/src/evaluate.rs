//! The evaluate page's API: `matseg eval points` on a `--bench` folder for
//! the served model and the baselines the page picks, run on a thread of
//! its own; the page polls for the report (All / Soft / top-1 scores per
//! model and per image).

use crate::annotate::bench;
use crate::app::{ApiError, AppState};
use axum::extract::{Query, State};
use axum::http::StatusCode;
use axum::Json;
use matseg_eval::evaluate::DEFAULT_MAX_SIDE;
use matseg_pipeline::models::{known_baselines, models, ModelChoice};
use matseg_pipeline::point_bench::score_point_benchmark;
use serde::Deserialize;
use std::collections::HashMap;
use std::sync::{Arc, Mutex};
use std::time::Instant;

/// Where an evaluation of one benchmark stands.
pub enum Evaluation {
    /// Running since then.
    Running(Instant),
    /// Finished: the report.
    Done(serde_json::Value),
    /// Failed: why.
    Failed(String),
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
    {
        let mut evaluations = state.evaluations.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(Evaluation::Running(_)) = evaluations.get(&query.root) {
            return Err(ApiError::new(
                StatusCode::CONFLICT,
                format!("{}: an evaluation is already running", folder.display()),
            ));
        }
        evaluations.insert(query.root.clone(), Evaluation::Running(Instant::now()));
    }
    let choice = ModelChoice {
        baselines,
        nets: vec![state.model_path.clone()],
        net_sides: Vec::new(),
        device: state.device,
    };
    let root = query.root.clone();
    let worker = state.clone();
    std::thread::spawn(move || {
        let outcome = run(&folder, &choice);
        let done = match outcome {
            Ok(report) => Evaluation::Done(report),
            Err(message) => Evaluation::Failed(message),
        };
        worker
            .evaluations
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .insert(root, done);
    });
    Ok(Json(serde_json::json!({ "state": "running" })))
}

/// Scores the chosen models on the benchmark in `folder`: the report as
/// `matseg eval points --json` prints it.
fn run(folder: &std::path::Path, choice: &ModelChoice) -> Result<serde_json::Value, String> {
    let models = models(choice).map_err(|e| e.to_string())?;
    let evaluation = score_point_benchmark(folder, &models, true, DEFAULT_MAX_SIDE)
        .map_err(|e| e.to_string())?;
    if evaluation.models[0].counts.images == 0 {
        return Err(format!(
            "{}: no annotated image to evaluate",
            folder.display()
        ));
    }
    Ok(serde_json::to_value(evaluation).expect("plain JSON values"))
}

/// A benchmark.
#[derive(Deserialize)]
pub struct StatusQuery {
    root: String,
}

/// `GET /api/evaluate`: where the benchmark's evaluation stands: `idle`,
/// `running` (with the seconds so far), `done` (with the report) or
/// `failed` (with the error).
pub async fn status(
    State(state): State<Arc<AppState>>,
    Query(query): Query<StatusQuery>,
) -> Result<Json<serde_json::Value>, ApiError> {
    bench(&state, &query.root)?;
    let evaluations = state.evaluations.lock().unwrap_or_else(|e| e.into_inner());
    Ok(Json(match evaluations.get(&query.root) {
        None => serde_json::json!({ "state": "idle" }),
        Some(Evaluation::Running(since)) => serde_json::json!({
            "state": "running",
            "seconds": since.elapsed().as_secs_f64(),
        }),
        Some(Evaluation::Done(report)) => serde_json::json!({ "state": "done", "report": report }),
        Some(Evaluation::Failed(error)) => serde_json::json!({ "state": "failed", "error": error }),
    }))
}
