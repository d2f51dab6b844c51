//! `matseg.evaluate`'s native half: matseg's benchmarks and protocols run
//! on a model written in Python. The evaluation runs on the calling thread
//! and asks the model photo by photo, so Ctrl-C stops it between (or
//! inside) the model's calls, and what the model raises reaches the caller
//! with the photo named.

use crate::buffer::{contiguous, Buffer};
use crate::errors::matseg_error;
use matseg_eval::clicks::{evaluate_clicks, evaluate_point_clicks, ClickOptions, Targets};
use matseg_eval::external::{answer_from_array, MapKind};
use matseg_eval::points::BenchError;
use matseg_eval::{
    evaluate_masks, load_point_benchmark, scan_mask_benchmark, Answer, MaskEvalOptions,
    QueryOptions, Question, ScoredModel,
};
use matseg_image::progress::Silent;
use pyo3::exceptions::{PyKeyboardInterrupt, PyValueError};
use pyo3::prelude::*;
use serde::Deserialize;
use serde_json::json;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

/// A Python model: `ask(image, height, width, name, points)` returns its
/// float32 array for the photo (descriptors or similarity maps, as `kind`
/// says).
struct PythonModel {
    name: String,
    kind: MapKind,
    ask: Py<PyAny>,
    /// What the model raised, handed back to the caller as it was.
    raised: Mutex<Option<PyErr>>,
}

impl ScoredModel for PythonModel {
    fn name(&self) -> &str {
        &self.name
    }

    fn answer(&self, question: &Question) -> Result<Answer, BenchError> {
        let asked = Python::attach(|py| -> PyResult<(Vec<usize>, Vec<f32>)> {
            py.check_signals()?;
            let (w, h) = question.pixels.dimensions();
            let pixels = Buffer::new(question.pixels.as_raw().clone());
            let array = self
                .ask
                .call1(py, (pixels, h, w, question.name, question.points.to_vec()))?;
            let array = array.bind(py);
            let shape: Vec<usize> = array.getattr("shape")?.extract()?;
            let values = contiguous::<f32>(
                py,
                array,
                shape.iter().product(),
                &format!("the model's answer for photo {}", question.name),
            )?;
            Ok((shape, values))
        });
        match asked {
            Ok((shape, values)) => {
                answer_from_array(values, &shape, self.kind, question, Path::new(&self.name))
            }
            Err(e) => {
                let message = format!("photo {}: the model raised {e}", question.name);
                *matseg_image::sync::lock(&self.raised) = Some(e);
                Err(BenchError::new(question.path, None, message))
            }
        }
    }

    fn parallel(&self) -> bool {
        false
    }
}

/// Options of every protocol, as `matseg.evaluate` passes them.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Options {
    max_side: u32,
    points: usize,
    erode: usize,
    min_area: usize,
    radius: f32,
    seed: u64,
    grid: Option<usize>,
    max_clicks: usize,
    unions: bool,
}

/// Scores the model `ask` answers for (named `name`; `kind` `descriptors`
/// or `similarity`, `comparison` `cosine` or `euclidean`) on the
/// benchmark `bench` by `protocol` (`points`, `masks` or `clicks`), with
/// `options` (JSON). Returns the JSON `matseg eval PROTOCOL --json`
/// prints. What the model raised is the cause of a `MatsegError` naming
/// the photo (a `KeyboardInterrupt` is raised again as it is); a wrong
/// shape or a NaN is a `MatsegError` naming the photo.
#[pyfunction]
#[allow(clippy::too_many_arguments)]
#[pyo3(signature = (protocol, bench, ask, name, kind, comparison, options))]
pub fn evaluate(
    py: Python<'_>,
    protocol: &str,
    bench: PathBuf,
    ask: Py<PyAny>,
    name: String,
    kind: &str,
    comparison: Option<&str>,
    options: &str,
) -> PyResult<String> {
    let options: Options = serde_json::from_str(options)
        .map_err(|e| PyValueError::new_err(format!("options: {e}")))?;
    let kind =
        MapKind::parse(Some(kind), comparison).map_err(|e| PyValueError::new_err(e.to_string()))?;
    let model = PythonModel {
        name,
        kind,
        ask,
        raised: Mutex::new(None),
    };
    let scored = score(protocol, &bench, &model, &options);
    let raised = matseg_image::sync::lock(&model.raised).take();
    match (scored, raised) {
        (Ok(json), _) => Ok(json),
        (Err(_), Some(error)) if error.is_instance_of::<PyKeyboardInterrupt>(py) => Err(error),
        (Err(message), Some(error)) => {
            let named = matseg_error(message.to_string());
            named.set_cause(py, Some(error));
            Err(named)
        }
        (Err(message), None) => Err(matseg_error(message)),
    }
}

/// The JSON report of `model` on `bench` by `protocol`.
fn score(
    protocol: &str,
    bench: &Path,
    model: &PythonModel,
    o: &Options,
) -> Result<String, Box<dyn std::error::Error>> {
    let is_point_bench = bench.join("images").is_dir() && bench.join("data").is_dir();
    let report = match protocol {
        "points" => {
            let models: [Box<dyn ScoredModel>; 1] = [Box::new(Borrowed(model))];
            let evaluation = matseg_pipeline::point_bench::score_point_benchmark(
                bench, &models, false, o.max_side, &Silent,
            )?;
            serde_json::to_value(evaluation)?
        }
        "masks" => {
            let images = scan_mask_benchmark(bench)?;
            let options = MaskEvalOptions {
                max_side: o.max_side,
                queries: QueryOptions {
                    points_per_mask: o.points,
                    erosion: o.erode,
                    min_area: o.min_area,
                    seed: o.seed,
                },
                radius: o.radius,
                grid_steps: o.grid,
            };
            let report = evaluate_masks(model, &images, &options, &Silent)?;
            json!({
                "data": bench,
                "max_side": o.max_side,
                "threshold": o.grid.map_or("exact".to_string(), |s| format!("grid of {s} steps")),
                "models": [report],
            })
        }
        "clicks" => {
            let options = ClickOptions {
                max_side: o.max_side,
                max_clicks: o.max_clicks,
                radius: o.radius,
                min_area: o.min_area,
                targets: Targets::Masks,
            };
            let mut out = json!({ "data": bench, "max_side": o.max_side });
            if is_point_bench {
                let points = load_point_benchmark(bench, false)?;
                let report = evaluate_point_clicks(model, &points, &options, &Silent)?;
                out["models"] = json!([report]);
            } else {
                let images = scan_mask_benchmark(bench)?;
                let report = evaluate_clicks(model, &images, &options, &Silent)?;
                out["models"] = json!([report]);
                if o.unions {
                    let unions = ClickOptions {
                        targets: Targets::Unions,
                        ..options
                    };
                    let report = evaluate_clicks(model, &images, &unions, &Silent)?;
                    out["unions"] = json!([report]);
                }
            }
            out
        }
        other => return Err(format!("protocol \"{other}\": give points, masks or clicks").into()),
    };
    Ok(report.to_string())
}

/// A borrowed scored model, where a boxed one is asked for.
struct Borrowed<'a>(&'a PythonModel);

impl ScoredModel for Borrowed<'_> {
    fn name(&self) -> &str {
        self.0.name()
    }
    fn answer(&self, question: &Question) -> Result<Answer, BenchError> {
        self.0.answer(question)
    }
    fn parallel(&self) -> bool {
        false
    }
}
