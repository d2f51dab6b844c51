//! `matseg.Model`: a trained net answering "where else is this material?"
//! as `matseg segment` does.

use crate::buffer::{Buffer, Photo};
use crate::errors::matseg_error;
use matseg_image::device::ComputeDevice;
use matseg_model::resolve_model as resolve;
use matseg_pipeline::segment::{
    check_points, cluster, describe, load_model, query_points, Model, MAX_POINTS,
};
use matseg_pipeline::select::{select_materials, MaterialClicks};
use matseg_pipeline::track::{TrackSettings, Tracking};
use matseg_query::descriptor::{check_radius, DescriptorMap, DescriptorModel};
use matseg_query::tracking::TrackOptions;
use matseg_query::ClusterOptions;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
#[cfg(feature = "torch")]
use pyo3::types::PyDict;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

/// The folder or weights file a model name stands for (`default`: the
/// shipped model).
#[pyfunction]
pub fn resolve_model(name: PathBuf) -> PyResult<PathBuf> {
    resolve(&name).map_err(matseg_error)
}

/// The run folder and weights file of a model name, as `matseg segment`
/// finds them.
#[pyfunction]
pub fn run_files(name: PathBuf) -> PyResult<(PathBuf, PathBuf)> {
    let model = resolve(&name).map_err(matseg_error)?;
    let (folder, weights) = matseg_model::run_files(&model);
    Ok((folder.to_path_buf(), weights))
}

/// The numbers the net's PyTorch copy (`matseg.net`) shares with this
/// one, so the two cannot drift apart: input normalisation, loss
/// temperature and region threshold, the colour part's L*a*b* conversion.
#[cfg(feature = "torch")]
#[pyfunction]
pub fn net_constants(py: Python<'_>) -> PyResult<Bound<'_, PyDict>> {
    use matseg_image::lab::{D65_WHITE_XZ, LAB_EPSILON, LAB_KAPPA, LINEAR_SRGB_TO_XYZ};
    let d = PyDict::new(py);
    d.set_item("input_mean", matseg_net::net::INPUT_MEAN.to_vec())?;
    d.set_item("input_scale", matseg_net::net::INPUT_SCALE)?;
    d.set_item("temperature", matseg_net::TEMPERATURE)?;
    d.set_item("region_threshold", matseg_net::REGION_THRESHOLD)?;
    d.set_item("roi_min_mask_sum", matseg_data::reader::ROI_MIN_MASK_SUM)?;
    d.set_item(
        "linear_srgb_to_xyz",
        LINEAR_SRGB_TO_XYZ.map(|r| r.to_vec()).to_vec(),
    )?;
    d.set_item("d65_white_xz", D65_WHITE_XZ.to_vec())?;
    d.set_item("lab_epsilon", LAB_EPSILON)?;
    d.set_item("lab_kappa", LAB_KAPPA)?;
    d.set_item("colour_features", matseg_net::colour::COLOUR_FEATURES)?;
    d.set_item(
        "colour_initial_bandwidth",
        matseg_net::colour::INITIAL_BANDWIDTH,
    )?;
    d.set_item("colour_seed", matseg_net::colour::SEED)?;
    d.set_item("model_file", matseg_net::train::MODEL_FILE)?;
    d.set_item("run_file", matseg_net::train::RUN_FILE)?;
    d.set_item("checkpoint_file", matseg_net::train::CHECKPOINT_FILE)?;
    d.set_item("metrics_file", matseg_net::train::METRICS_FILE)?;
    d.set_item("plot_file", matseg_net::train::PLOT_FILE)?;
    d.set_item("best_model_file", matseg_net::train::BEST_MODEL_FILE)?;
    let keys = PyDict::new(py);
    {
        use matseg_net::checkpoint_keys::*;
        keys.set_item("model", MODEL)?;
        keys.set_item("optimizer", OPTIMIZER)?;
        keys.set_item("first_moment", FIRST_MOMENT)?;
        keys.set_item("second_moment", SECOND_MOMENT)?;
        keys.set_item("optimizer_steps", OPTIMIZER_STEPS)?;
        keys.set_item("next_step", NEXT_STEP)?;
        keys.set_item("next_batch", NEXT_BATCH)?;
    }
    d.set_item("checkpoint_keys", keys)?;
    Ok(d)
}

/// The net configuration (run.json's "net", as JSON) of a named preset,
/// with or without the encoder's and the colour features.
#[pyfunction]
pub fn net_preset(name: &str, encoder_features: bool, colour_features: bool) -> PyResult<String> {
    use matseg_model::{NetConfig, PRESETS};
    let config = NetConfig::preset(name).ok_or_else(|| {
        PyValueError::new_err(format!(
            "encoder: '{name}': expected one of {}",
            PRESETS.join(", ")
        ))
    })?;
    let config = NetConfig {
        encoder_features,
        colour_features,
        ..config
    };
    Ok(serde_json::to_string(&config).expect("a net config serialises"))
}

/// `matseg train`'s defaults, for `python -m matseg.train`.
#[cfg(feature = "torch")]
#[pyfunction]
pub fn train_defaults(py: Python<'_>) -> PyResult<Bound<'_, PyDict>> {
    use matseg_net::optim::AdamWConfig;
    use matseg_net::train::{LR_PRETRAINED, LR_SCRATCH, VALIDATION_SEED, WARMUP_STEPS};
    use matseg_pipeline::train::{TrainConfig, VALIDATION_GENERATOR_SEED};
    let adamw = AdamWConfig::default();
    let d = PyDict::new(py);
    d.set_item("validation_batches", TrainConfig::VALIDATION_BATCHES)?;
    d.set_item("mix_fraction", TrainConfig::MIX_FRACTION)?;
    d.set_item("val_max_side", matseg_eval::evaluate::DEFAULT_MAX_SIDE)?;
    d.set_item("validation_seed", VALIDATION_SEED)?;
    d.set_item("validation_generator_seed", VALIDATION_GENERATOR_SEED)?;
    d.set_item("betas", (adamw.beta1, adamw.beta2))?;
    d.set_item("eps", adamw.eps)?;
    d.set_item("lr_pretrained", LR_PRETRAINED)?;
    d.set_item("lr_scratch", LR_SCRATCH)?;
    d.set_item("warmup", WARMUP_STEPS)?;
    d.set_item("weight_decay", TrainConfig::WEIGHT_DECAY)?;
    d.set_item("steps", TrainConfig::STEPS)?;
    d.set_item("checkpoint_every", TrainConfig::CHECKPOINT_EVERY)?;
    d.set_item("encoder", TrainConfig::ENCODER)?;
    Ok(d)
}

/// The learning rate of each step of a run with `options` (run.json's
/// "options", as JSON), as `matseg train` schedules it.
#[cfg(feature = "torch")]
#[pyfunction]
pub fn lr_schedule(options: &str) -> PyResult<Vec<f64>> {
    let options: matseg_net::train::TrainOptions = serde_json::from_str(options)
        .map_err(|e| PyValueError::new_err(format!("training options: {e}")))?;
    Ok((0..options.steps).map(|s| options.lr_at(s)).collect())
}

/// The triplet accuracy (All, by material) of `model` (a run folder or
/// weights file, on the CPU) on the point benchmark `bench` (MatSeg layout)
/// with photos at `max_side` (0: as they are): what `matseg train
/// --val-points` scores each checkpoint with.
#[pyfunction]
pub fn score_points(
    py: Python<'_>,
    model: PathBuf,
    bench: PathBuf,
    max_side: u32,
) -> PyResult<f64> {
    use matseg_eval::load_point_benchmark;
    use matseg_pipeline::nets::point_score;
    py.detach(|| {
        let points = load_point_benchmark(&bench, false).map_err(|e| e.to_string())?;
        let net = load_model(&model, ComputeDevice::Cpu).map_err(|e| e.to_string())?;
        point_score(&net, &points, max_side).map_err(|e| format!("{}: {e}", bench.display()))
    })
    .map_err(matseg_error)
}

/// Draws a run's loss curve (`matseg train`'s `loss.png`) from its
/// `metrics.jsonl` into `png` (atomically).
#[cfg(feature = "torch")]
#[pyfunction]
pub fn plot_losses(metrics: PathBuf, png: PathBuf) -> PyResult<()> {
    let history = matseg_net::train::read_metrics(&metrics, u64::MAX);
    matseg_net::plot::plot_losses(&history, &png).map_err(matseg_error)
}

/// A loaded net (on the CPU).
#[pyclass(module = "matseg._core", name = "Model", frozen)]
pub struct PyModel {
    pub(crate) net: Model,
    /// The name it was loaded by, as a saved selection records it.
    name: String,
}

/// A map's descriptors as little-endian f32 `[D, height, width]`: plane
/// by plane, as numpy takes them.
fn planes_buffer(map: &DescriptorMap) -> Buffer {
    let pixels = map.width * map.height;
    let mut planes = vec![0f32; map.data.len()];
    for (i, descriptor) in map.data.chunks_exact(map.dim).enumerate() {
        for (c, &v) in descriptor.iter().enumerate() {
            planes[c * pixels + i] = v;
        }
    }
    Buffer::f32s(&planes)
}

/// Labels as little-endian i32.
fn label_buffer(labels: &[u32]) -> Buffer {
    Buffer::new(
        labels
            .iter()
            .flat_map(|&l| (l as i32).to_le_bytes())
            .collect(),
    )
}

#[pymethods]
impl PyModel {
    /// Loads `name`: `default`, a run folder or a weights file.
    #[new]
    fn new(py: Python<'_>, name: PathBuf) -> PyResult<Self> {
        let net = py
            .detach(|| load_model(Path::new(&name), ComputeDevice::Cpu))
            .map_err(matseg_error)?;
        Ok(Self {
            net,
            name: name.display().to_string(),
        })
    }

    /// Descriptor channels.
    fn dim(&self) -> usize {
        self.net.net().output_dim()
    }

    /// Unit descriptors `[D, height, width]` (f32 bytes) as `matseg
    /// segment` computes them: at the model's inference sizes, resized back.
    fn describe(&self, py: Python<'_>, image: Photo) -> PyResult<Buffer> {
        let Photo(photo) = image;
        let map = py.detach(|| self.net.describe(&photo));
        Ok(planes_buffer(&map))
    }

    /// Unit descriptors `[D, height, width]` of the net alone at the
    /// image's own size (sides multiples of 32), one scale.
    fn describe_at_own_size(&self, py: Python<'_>, image: Photo) -> PyResult<Buffer> {
        let Photo(photo) = image;
        let (w, h) = (photo.width() as usize, photo.height() as usize);
        if !w.is_multiple_of(32) || !h.is_multiple_of(32) {
            return Err(PyValueError::new_err(format!(
                "image: is {w}x{h}; the net alone takes sides that are multiples of 32"
            )));
        }
        let map = py.detach(|| self.net.net().own_size_grid(&photo).pixel_map(w, h));
        Ok(planes_buffer(&map))
    }

    /// Each point's similarity map `[K, height, width]` (f32 bytes) and,
    /// for two points or more, the nearest-point labels (i32 bytes).
    fn similarity(
        &self,
        py: Python<'_>,
        image: Photo,
        points: Vec<(f32, f32)>,
        radius: f32,
    ) -> PyResult<(Buffer, Option<Buffer>)> {
        let Photo(photo) = image;
        check_points(&photo, &points, "the image")
            .map_err(|e| PyValueError::new_err(e.to_string()))?;
        check_radius(radius).map_err(|e| PyValueError::new_err(e.to_string()))?;
        let maps = py.detach(|| query_points(&describe(&self.net, &photo), &points, radius));
        let flat: Vec<f32> = maps.similarity.concat();
        Ok((Buffer::f32s(&flat), maps.labels.map(|l| label_buffer(&l))))
    }

    /// The selection made by `positive` clicks of one material and
    /// `negative` ones: its soft map `[height, width]` (f32 bytes), its
    /// mask (u8 bytes, 1 selected) and the selection saved as JSON (what
    /// `matseg apply` reads).
    fn select(
        &self,
        py: Python<'_>,
        image: Photo,
        positive: Vec<(f32, f32)>,
        negative: Vec<(f32, f32)>,
        radius: f32,
    ) -> PyResult<(Buffer, Buffer, String)> {
        let Photo(photo) = image;
        let grouped: Vec<_> = positive.into_iter().map(|p| (Some(0), p)).collect();
        let clicks = MaterialClicks::group(&grouped, negative);
        let refused =
            |e: matseg_pipeline::error::PipelineError| PyValueError::new_err(e.to_string());
        clicks.check(&photo, "the image").map_err(refused)?;
        check_radius(radius).map_err(|e| PyValueError::new_err(e.to_string()))?;
        let name = &self.name;
        let mut selections = py
            .detach(|| {
                select_materials(&describe(&self.net, &photo), &photo, &clicks, radius, name)
            })
            .map_err(refused)?;
        let selection = selections.remove(0);
        let mask = selection.mask.iter().map(|&m| m as u8).collect();
        let saved = serde_json::to_string(&selection.saved).expect("a selection serialises");
        Ok((Buffer::f32s(&selection.soft), Buffer::new(mask), saved))
    }

    /// The photo split into `k` materials by clustering its descriptors:
    /// labels (i32 bytes) and the number of clusters.
    fn cluster(
        &self,
        py: Python<'_>,
        image: Photo,
        k: usize,
        seed: u64,
    ) -> PyResult<(Buffer, usize)> {
        if !(2..=MAX_POINTS).contains(&k) {
            return Err(PyValueError::new_err(format!(
                "k: {k} clusters; between 2 and {MAX_POINTS}"
            )));
        }
        let Photo(photo) = image;
        let options = ClusterOptions {
            seed,
            ..ClusterOptions::new(k)
        };
        let (labels, n) = py.detach(|| cluster(&describe(&self.net, &photo), &options));
        Ok((label_buffer(&labels), n))
    }
}

/// Clicks as (x, y) pixel pairs.
type Points = Vec<(f32, f32)>;

/// Clicked materials followed through frames handed over one at a time,
/// as `matseg track` follows them (`matseg.Model.track`).
#[pyclass(module = "matseg._core", name = "Tracker", frozen)]
pub struct PyTracker {
    model: Py<PyModel>,
    tracking: Mutex<Tracking>,
}

#[pymethods]
impl PyTracker {
    /// Starts following the materials under the points of `clicks` on the
    /// clicked frame (`image`), none taking the materials under its
    /// negative clicks (`clicks` is (points, negatives)); `tracker` is (memory, samples, confident, prior,
    /// temperature).
    #[new]
    fn new(
        py: Python<'_>,
        model: Py<PyModel>,
        image: Photo,
        clicks: (Points, Points),
        radius: f32,
        side: u32,
        tracker: (usize, usize, f32, f32, f32),
    ) -> PyResult<Self> {
        let Photo(clicked) = image;
        let (points, negatives) = clicks;
        let (memory, samples, confident, prior, temperature) = tracker;
        let settings = TrackSettings {
            points,
            negatives,
            frame: 0,
            radius,
            side,
            options: TrackOptions {
                memory,
                samples,
                confident,
                prior,
                temperature,
            },
        };
        let net = &model.get().net;
        let tracking = py
            .detach(|| Tracking::start(net, &clicked, &settings, "the clicked frame"))
            .map_err(|e| PyValueError::new_err(e.to_string()))?;
        Ok(Self {
            model,
            tracking: Mutex::new(tracking),
        })
    }

    /// The next frame's probabilities `[K, height, width]` (f32 bytes),
    /// labels `[height, width]` (u8 bytes: 0 none, k the k-th point's
    /// material) and each point's share of the frame.
    fn step(&self, py: Python<'_>, image: Photo) -> PyResult<(Buffer, Buffer, Vec<f64>)> {
        let Photo(frame) = image;
        let net = &self.model.get().net;
        let mut tracking = matseg_image::sync::lock(&self.tracking);
        let tracking = &mut *tracking;
        let tracked = py
            .detach(|| tracking.step(net, &frame))
            .map_err(|e| PyValueError::new_err(e.to_string()))?;
        Ok((
            Buffer::f32s(&tracked.similarity.concat()),
            Buffer::new(tracked.labels),
            tracked.areas,
        ))
    }
}
