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
use matseg_eval::{Described, ScoredModel};
use matseg_image::progress::Progress;
use matseg_pipeline::models::{baselines, known_baselines, ModelChoice};
use matseg_pipeline::point_bench::score_point_benchmark;
use matseg_query::descriptor::{Comparison, DescriptorMap, DescriptorModel};
use serde::Deserialize;
use std::collections::HashMap;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Instant;

/// Where an evaluation of one benchmark stands.
pub enum Evaluation {
    /// Running since then, with its progress (images done, of all models)
    /// and each model's.
    Running(Instant, Arc<JobProgress>, Arc<ModelTally>),
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
    let tally = Arc::new(ModelTally::default());
    let root = query.root.clone();
    let worker = state.clone();
    let job_progress = progress.clone();
    let job_tally = tally.clone();
    state
        .workers
        .spawn(&format!("evaluate {root}"), progress.clone(), move || {
            let mut done = finished(&folder, || {
                run_in_background(|| {
                    let progress = TalliedProgress {
                        job: job_progress.as_ref(),
                        tally: &job_tally,
                    };
                    run(&folder, &choice, worker.clone(), &progress, &job_tally)
                })
                .unwrap_or_else(|e| Err(EvaluationError::Background(e.to_string())))
            });
            if matches!(done, Evaluation::Failed(_)) && job_progress.cancelled() {
                done = Evaluation::Cancelled;
            }
            release_freed_memory();
            matseg_image::sync::lock(&worker.evaluations).insert(root, done);
        })
        .map_err(|e| ApiError::internal(format!("cannot start the evaluation: {e}")))?;
    evaluations.insert(
        query.root,
        Evaluation::Running(Instant::now(), progress, tally),
    );
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
        Some(Evaluation::Running(_, progress, _)) => {
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

/// Each model's images scored so far in an evaluation, for the page: the
/// models are scored one after the other, each told apart by
/// [`Counted`], and an image is a step of the progress once scored.
#[derive(Default)]
pub struct ModelTally {
    /// The models' names, in the order they are scored.
    models: Mutex<Vec<String>>,
    /// The benchmark's images, in the order each model scores them.
    images: Mutex<Vec<String>>,
    /// The model being scored (its place in `models`).
    current: AtomicUsize,
    /// The images each model has scored.
    done: Mutex<Vec<u64>>,
}

impl ModelTally {
    /// Each model's name, images scored and images to score; and the
    /// names of the images the model being scored has finished (the
    /// first of the benchmark's: the evaluation scores a model's images
    /// in their order, one at a time on its pool of one thread).
    fn report(&self) -> (serde_json::Value, Vec<String>) {
        let models = matseg_image::sync::lock(&self.models).clone();
        let images = matseg_image::sync::lock(&self.images).clone();
        let done = matseg_image::sync::lock(&self.done).clone();
        let listed = models
            .iter()
            .zip(&done)
            .map(|(model, done)| {
                serde_json::json!({ "model": model, "done": done, "total": images.len() })
            })
            .collect();
        let current = done
            .get(self.current.load(Ordering::Relaxed))
            .copied()
            .unwrap_or(0);
        let scored = images.into_iter().take(current as usize).collect();
        (serde_json::Value::Array(listed), scored)
    }
}

/// A model of an evaluation that tells the tally it is the one scored
/// when it describes an image.
struct Counted {
    model: Box<dyn DescriptorModel>,
    index: usize,
    tally: Arc<ModelTally>,
}

impl DescriptorModel for Counted {
    fn name(&self) -> &str {
        self.model.name()
    }

    fn comparison(&self) -> Comparison {
        self.model.comparison()
    }

    fn describe(&self, image: &image::RgbImage) -> DescriptorMap {
        self.tally.current.store(self.index, Ordering::Relaxed);
        self.model.describe(image)
    }
}

/// The job's progress, each image scored also counted to the model being
/// scored.
struct TalliedProgress<'a> {
    job: &'a JobProgress,
    tally: &'a ModelTally,
}

impl Progress for TalliedProgress<'_> {
    fn start(&self, total: u64, what: &str) {
        self.job.start(total, what);
    }
    fn advance(&self) {
        self.advance_by(1);
    }
    fn advance_by(&self, steps: u64) {
        let current = self.tally.current.load(Ordering::Relaxed);
        if let Some(done) = matseg_image::sync::lock(&self.tally.done).get_mut(current) {
            *done += steps;
        }
        self.job.advance_by(steps);
    }
    fn status(&self, message: &str) {
        self.job.status(message);
    }
    fn finish(&self) {
        self.job.finish();
    }
    fn warn(&self, message: &str) {
        self.job.warn(message);
    }
    fn cancelled(&self) -> bool {
        self.job.cancelled()
    }
}

/// Scores the chosen baselines and the served model on the benchmark in
/// `folder`: the report as `matseg eval points --json` prints it.
fn run(
    folder: &std::path::Path,
    choice: &ModelChoice,
    state: Arc<AppState>,
    progress: &dyn Progress,
    tally: &Arc<ModelTally>,
) -> Result<serde_json::Value, EvaluationError> {
    let mut models = baselines(choice)?;
    models.push(Box::new(Served(state)));
    let images = matseg_eval::load_point_benchmark(folder, true)
        .map(|bench| bench.images.into_iter().map(|image| image.name).collect())
        .unwrap_or_default();
    *matseg_image::sync::lock(&tally.images) = images;
    *matseg_image::sync::lock(&tally.models) =
        models.iter().map(|m| m.name().to_string()).collect();
    *matseg_image::sync::lock(&tally.done) = vec![0; models.len()];
    let models: Vec<Box<dyn ScoredModel>> = models
        .into_iter()
        .enumerate()
        .map(|(index, model)| {
            Box::new(Described(Box::new(Counted {
                model,
                index,
                tally: tally.clone(),
            }))) as Box<dyn ScoredModel>
        })
        .collect();
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
/// `running` (with the seconds so far, the model being scored, the images
/// done of the total, every model's images counted, each model's images
/// done, and the names of those the model being scored has finished),
/// `done` (with the report), `failed` (with the error) or `cancelled`.
pub async fn status(
    State(state): State<Arc<AppState>>,
    Query(query): Query<StatusQuery>,
) -> Result<Json<serde_json::Value>, ApiError> {
    bench(&state, &query.root)?;
    let evaluations = matseg_image::sync::lock(&state.evaluations);
    Ok(Json(match evaluations.get(&query.root) {
        None => serde_json::json!({ "state": "idle" }),
        Some(Evaluation::Running(since, progress, tally)) => {
            let (done, total) = progress.counts();
            let (models, scored) = tally.report();
            serde_json::json!({
                "state": "running",
                "seconds": since.elapsed().as_secs_f64(),
                "model": progress.doing(),
                "done": done,
                "total": total,
                "models": models,
                "scored": scored,
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

    /// A model that describes every image as one grey pixel.
    struct Flat(&'static str);

    impl DescriptorModel for Flat {
        fn name(&self) -> &str {
            self.0
        }
        fn comparison(&self) -> Comparison {
            Comparison::NegativeEuclidean
        }
        fn describe(&self, _image: &image::RgbImage) -> DescriptorMap {
            DescriptorMap {
                width: 1,
                height: 1,
                dim: 1,
                data: vec![0.5],
            }
        }
    }

    #[test]
    fn each_models_images_are_counted_apart_and_the_scored_named() {
        let tally = Arc::new(ModelTally::default());
        *tally.models.lock().unwrap() = vec!["rgb".into(), "default".into()];
        *tally.images.lock().unwrap() = vec!["a".into(), "b".into(), "c".into()];
        *tally.done.lock().unwrap() = vec![0, 0];
        let job = JobProgress::default();
        let progress = TalliedProgress {
            job: &job,
            tally: &tally,
        };
        let models: Vec<Counted> = ["rgb", "default"]
            .into_iter()
            .enumerate()
            .map(|(index, name)| Counted {
                model: Box::new(Flat(name)),
                index,
                tally: tally.clone(),
            })
            .collect();
        progress.start(6, "images");
        let image = image::RgbImage::new(1, 1);
        // Each image described, then counted, as the evaluation does.
        for model in &models {
            let images = if model.name() == "rgb" { 3 } else { 2 };
            for _ in 0..images {
                model.describe(&image);
                progress.advance();
            }
        }
        let (models, scored) = tally.report();
        assert_eq!(
            models,
            serde_json::json!([
                { "model": "rgb", "done": 3, "total": 3 },
                { "model": "default", "done": 2, "total": 3 },
            ])
        );
        assert_eq!(scored, ["a", "b"], "the images the model has scored");
        assert_eq!(job.counts(), (5, 6), "every model's images in the job's");
    }
}
