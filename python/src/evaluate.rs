//! `matseg.evaluate`'s native half: matseg's benchmarks and protocols run
//! on a model written in Python. The evaluation runs on the calling thread
//! and asks the model photo by photo, so Ctrl-C stops it between (or
//! inside) the model's calls, and what the model raises reaches the caller
//! with the photo named.

use crate::buffer::{Buffer, HeldArray};
use crate::errors::matseg_error;
use crate::model::PyModel;
use image::RgbImage;
use matseg_eval::clicks::{
    evaluate_clicks, evaluate_point_clicks, ClickEvaluation, ClickOptions, Targets,
};
use matseg_eval::evaluate::resize_longer_side;
use matseg_eval::external::{answer_from_array, descriptor_grid, MapKind};
use matseg_eval::model::Values;
use matseg_eval::points::BenchError;
use matseg_eval::{
    evaluate_masks, is_point_benchmark, load_point_benchmark, scan_mask_benchmark, Answer,
    ClickAnswer, MaskEvalOptions, MaskEvaluation, QueryOptions, Question, ScoredModel,
};
use matseg_image::progress::Silent;
use matseg_pipeline::error::PipelineError;
use matseg_pipeline::track_bench::{eval_track, FrameDescriber, TrackBenchSettings};
use matseg_query::coarse::CoarseDescriptors;
use matseg_query::descriptor::Comparison;
use matseg_query::select::Click;
use pyo3::exceptions::{PyKeyboardInterrupt, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyTuple;
use serde::Deserialize;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

/// A Python model: `ask(image, height, width, name, points)` returns its
/// float32 array for the photo (descriptors or similarity maps, as `kind`
/// says), and `select(image, height, width, name, positives, negatives)`,
/// when it has one, its own selection for the click protocol.
struct PythonModel {
    name: String,
    kind: MapKind,
    ask: Option<Py<PyAny>>,
    select: Option<Py<PyAny>>,
    /// What the model raised, handed back to the caller as it was.
    raised: Mutex<Option<PyErr>>,
}

impl PythonModel {
    /// `function(image, height, width, name, *more)`'s array for
    /// `question`'s photo: its shape and float32 values.
    fn call(
        &self,
        function: &Py<PyAny>,
        question: &Question,
        more: Vec<Vec<(f32, f32)>>,
    ) -> Result<(Vec<usize>, Values), BenchError> {
        let asked = Python::attach(|py| -> PyResult<(Vec<usize>, Values)> {
            py.check_signals()?;
            let (w, h) = question.pixels.dimensions();
            let pixels = Buffer::new(question.pixels.as_raw().clone());
            let mut arguments = vec![
                pixels.into_pyobject(py)?.into_any(),
                h.into_pyobject(py)?.into_any(),
                w.into_pyobject(py)?.into_any(),
                question.name.into_pyobject(py)?.into_any(),
            ];
            for points in more {
                arguments.push(points.into_pyobject(py)?.into_any());
            }
            let array = function.call1(py, PyTuple::new(py, arguments)?)?;
            let array = array.bind(py);
            let shape: Vec<usize> = array.getattr("shape")?.extract()?;
            let values = HeldArray::new(
                array,
                shape.iter().product(),
                &format!("the model's answer for photo {}", question.name),
            )?;
            Ok((shape, Values::Held(Box::new(values))))
        });
        asked.map_err(|e| {
            let message = format!("photo {}: the model raised {e}", question.name);
            *matseg_image::sync::lock(&self.raised) = Some(e);
            BenchError::new(question.path, None, message)
        })
    }
}

impl ScoredModel for PythonModel {
    fn name(&self) -> &str {
        &self.name
    }

    fn answer(&self, question: &Question) -> Result<Answer, BenchError> {
        let Some(ask) = &self.ask else {
            return Err(BenchError::new(
                question.path,
                None,
                format!(
                    "{} only selects from clicks: points and masks need describe(image) or similarity(image, points)",
                    self.name
                ),
            ));
        };
        let (shape, values) = self.call(ask, question, vec![question.points.to_vec()])?;
        answer_from_array(values, &shape, self.kind, question, Path::new(&self.name))
    }

    fn parallel(&self) -> bool {
        false
    }

    fn click_answer(&self) -> ClickAnswer {
        match (&self.select, self.kind) {
            (Some(_), _) => ClickAnswer::Selection,
            (None, MapKind::Similarity) => ClickAnswer::SimilarityMaps,
            (None, MapKind::Descriptors(_)) => ClickAnswer::Descriptors,
        }
    }

    fn select(&self, question: &Question, clicks: &[Click]) -> Result<Vec<f32>, BenchError> {
        let select = self.select.as_ref().ok_or_else(|| {
            BenchError::new(
                question.path,
                None,
                format!("{} does not select", self.name),
            )
        })?;
        let side = |positive: bool| -> Vec<(f32, f32)> {
            clicks
                .iter()
                .filter(|c| c.positive == positive)
                .map(|c| (c.x, c.y))
                .collect()
        };
        let (shape, values) = self.call(select, question, vec![side(true), side(false)])?;
        let (w, h) = question.pixels.dimensions();
        if shape != [h as usize, w as usize] {
            return Err(BenchError::new(
                Path::new(&self.name),
                None,
                format!(
                    "shape {shape:?} for photo {}: select must return its ({h}, {w}) selection",
                    question.name
                ),
            ));
        }
        Ok(values.into_vec())
    }
}

impl FrameDescriber for PythonModel {
    fn name(&self) -> &str {
        &self.name
    }

    fn describe_frame(
        &self,
        frame: &RgbImage,
        side: u32,
        (sequence, index): (u64, usize),
        path: &Path,
    ) -> Result<CoarseDescriptors, PipelineError> {
        let ask = match (&self.ask, self.kind) {
            (Some(ask), MapKind::Descriptors(Comparison::Cosine)) => ask,
            _ => {
                return Err(PipelineError::file(
                    &self.name,
                    "track needs describe(image) with descriptors compared by cosine",
                ))
            }
        };
        let (width, height) = frame.dimensions();
        let pixels = match width.max(height) > side {
            true => resize_longer_side(frame.clone(), side).0,
            false => frame.clone(),
        };
        let name = format!("sequence {sequence} frame {index}");
        let question = Question {
            name: &name,
            path,
            pixels: &pixels,
            points: &[],
        };
        let (shape, values) = self.call(ask, &question, vec![Vec::new()])?;
        let mut grid = descriptor_grid(values, &shape, &question, Path::new(&self.name))?;
        for descriptor in grid.data.chunks_exact_mut(grid.dim) {
            let norm = descriptor.iter().map(|v| v * v).sum::<f32>().sqrt();
            descriptor
                .iter_mut()
                .for_each(|v| *v /= norm.max(f32::EPSILON));
        }
        Ok(CoarseDescriptors {
            grid,
            width: width as usize,
            height: height as usize,
        })
    }
}

/// matseg's own net, handed over from Python as a `matseg.Model`, for the
/// tracking benchmark: it describes frames as `matseg eval track` does.
struct NativeNet<'a> {
    name: String,
    model: &'a PyModel,
    /// Where a Ctrl-C between frames is kept, to be raised again.
    raised: &'a Mutex<Option<PyErr>>,
}

impl FrameDescriber for NativeNet<'_> {
    fn name(&self) -> &str {
        &self.name
    }

    fn describe_frame(
        &self,
        frame: &RgbImage,
        side: u32,
        at: (u64, usize),
        path: &Path,
    ) -> Result<CoarseDescriptors, PipelineError> {
        Python::attach(|py| py.check_signals()).map_err(|e| {
            let message = e.to_string();
            *matseg_image::sync::lock(self.raised) = Some(e);
            PipelineError::file(path.display(), message)
        })?;
        self.model.net.describe_frame(frame, side, at, path)
    }
}

/// `matseg.evaluate.points`' options.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct PointSettings {
    max_side: u32,
}

/// `matseg.evaluate.masks`' options, as `matseg eval masks` names them.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct MaskSettings {
    max_side: u32,
    points: usize,
    erode: usize,
    min_area: usize,
    radius: f32,
    seed: u64,
    grid: Option<usize>,
}

/// `matseg.evaluate.track`'s options, as `matseg eval track` names them.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct TrackSettings {
    side: u32,
}

/// `matseg.evaluate.clicks`' options, as `matseg eval clicks` names them.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ClickSettings {
    max_side: u32,
    max_clicks: usize,
    radius: f32,
    min_area: usize,
    unions: bool,
}

/// Scores the model `ask` answers for (named `name`; `kind` `descriptors`
/// or `similarity`, `comparison` `cosine` or `euclidean`), with its own
/// selection `select` in the click protocol when given, or matseg's own
/// net `native` (track only), on the benchmark `bench` by `protocol`
/// (`points`, `masks`, `clicks` or `track`), with that protocol's
/// `options` (JSON). Returns the JSON `matseg eval PROTOCOL --json`
/// prints. What the model raised is the cause of a `MatsegError` naming
/// the photo (a `KeyboardInterrupt` is raised again as it is); a wrong
/// shape or a NaN is a `MatsegError` naming the photo.
#[pyfunction]
#[allow(clippy::too_many_arguments)]
#[pyo3(signature = (protocol, bench, ask, select, name, kind, comparison, options, native=None))]
pub fn evaluate(
    py: Python<'_>,
    protocol: &str,
    bench: PathBuf,
    ask: Option<Py<PyAny>>,
    select: Option<Py<PyAny>>,
    name: String,
    kind: &str,
    comparison: Option<&str>,
    options: &str,
    native: Option<PyRef<'_, PyModel>>,
) -> PyResult<String> {
    let kind =
        MapKind::parse(Some(kind), comparison).map_err(|e| PyValueError::new_err(e.to_string()))?;
    let model = PythonModel {
        name,
        kind,
        ask,
        select,
        raised: Mutex::new(None),
    };
    let native = native.as_deref().map(|net| NativeNet {
        name: model.name.clone(),
        model: net,
        raised: &model.raised,
    });
    let scored = score(protocol, &bench, &model, native.as_ref(), options);
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

/// The JSON report of `model` on `bench` by `protocol` with `options`.
fn score(
    protocol: &str,
    bench: &Path,
    model: &PythonModel,
    native: Option<&NativeNet>,
    options: &str,
) -> Result<String, Box<dyn std::error::Error>> {
    let json = match protocol {
        "track" => {
            let o: TrackSettings = serde_json::from_str(options)?;
            let settings = TrackBenchSettings {
                side: o.side,
                ..TrackBenchSettings::default()
            };
            let describer: &dyn FrameDescriber = match native {
                Some(net) => net,
                None => model,
            };
            serde_json::to_string(&eval_track(describer, bench, &settings)?)?
        }
        "points" => {
            let o: PointSettings = serde_json::from_str(options)?;
            let models: [Box<dyn ScoredModel + '_>; 1] = [Box::new(model)];
            let evaluation = matseg_pipeline::point_bench::score_point_benchmark(
                bench, &models, false, o.max_side, &Silent,
            )?;
            serde_json::to_string(&evaluation)?
        }
        "masks" => {
            let o: MaskSettings = serde_json::from_str(options)?;
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
            let reports = [evaluate_masks(model, &images, &options, &Silent)?];
            serde_json::to_string(&MaskEvaluation::new(bench, &options, &reports))?
        }
        "clicks" => {
            let o: ClickSettings = serde_json::from_str(options)?;
            let options = ClickOptions {
                max_side: o.max_side,
                max_clicks: o.max_clicks,
                radius: o.radius,
                min_area: o.min_area,
                targets: Targets::Masks,
            };
            if is_point_benchmark(bench) {
                let points = load_point_benchmark(bench, false)?;
                let reports = [evaluate_point_clicks(model, &points, &options, &Silent)?];
                serde_json::to_string(&ClickEvaluation {
                    data: bench,
                    max_side: o.max_side,
                    models: &reports,
                    unions: None,
                })?
            } else {
                let images = scan_mask_benchmark(bench)?;
                let reports = [evaluate_clicks(model, &images, &options, &Silent)?];
                let unions = match o.unions {
                    true => {
                        let unions = ClickOptions {
                            targets: Targets::Unions,
                            ..options
                        };
                        Some([evaluate_clicks(model, &images, &unions, &Silent)?])
                    }
                    false => None,
                };
                serde_json::to_string(&ClickEvaluation {
                    data: bench,
                    max_side: o.max_side,
                    models: &reports,
                    unions: unions.as_ref().map(|u| &u[..]),
                })?
            }
        }
        other => {
            return Err(format!("protocol \"{other}\": give points, masks, clicks or track").into())
        }
    };
    Ok(json)
}
