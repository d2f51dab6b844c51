//! Training batches as `matseg train` draws them (the batch plan: one
//! random size per batch, samples fitted and augmented), for PyTorch.

use crate::buffer::Buffer;
use crate::dataset::PyDataset;
use crate::errors::matseg_error;
use matseg_data::training::{batch_samples, BatchPlan, MixedSource, SampleSource};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

/// The paper's batch plan as JSON (the defaults of `matseg.BatchPlan`).
#[pyfunction]
pub fn default_plan() -> String {
    serde_json::to_string(&BatchPlan::SPEC).expect("a plan serialises")
}

/// A stored dataset mixed into a batch source and the share of samples
/// taken from it (`matseg train --mix-data`, `--mix-fraction`).
pub type MixedDataset<'py> = Option<(PyRef<'py, PyDataset>, f64)>;

/// A batch plan from its JSON (`matseg.BatchPlan.to_json`), checked.
pub fn parse_plan(plan: &str) -> PyResult<BatchPlan> {
    let invalid = |e: &dyn std::fmt::Display| PyValueError::new_err(format!("batch plan: {e}"));
    let plan: BatchPlan = serde_json::from_str(plan).map_err(|e| invalid(&e))?;
    plan.validate().map_err(|e| invalid(&e))?;
    Ok(plan)
}

/// Batch `step` of `source` (with `mix`) under `plan` (JSON) and `seed`: a
/// list of `{"width", "height", "image": RGB buffer, "weights": [little-endian
/// f32 buffer], "roi": little-endian f32 buffer}`, all images of one size.
pub fn batch_list<'py>(
    py: Python<'py>,
    source: &dyn SampleSource,
    mix: MixedDataset<'_>,
    plan: &str,
    seed: u64,
    step: u64,
) -> PyResult<Bound<'py, PyList>> {
    let plan = parse_plan(plan)?;
    let mixed = match &mix {
        Some((other, fraction)) => {
            MixedSource::check_fraction(*fraction)
                .map_err(|e| PyValueError::new_err(format!("mix fraction {fraction}: {e}")))?;
            Some(MixedSource {
                main: source,
                other: other.source(),
                fraction: *fraction,
            })
        }
        None => None,
    };
    let source: &dyn SampleSource = match &mixed {
        Some(mixed) => mixed,
        None => source,
    };
    let samples = py
        .detach(|| batch_samples(source, &plan, seed, step))
        .map_err(matseg_error)?;
    let list = PyList::empty(py);
    for s in samples {
        let d = PyDict::new(py);
        d.set_item("width", s.width)?;
        d.set_item("height", s.height)?;
        d.set_item("image", Buffer::new(s.rgb))?;
        let weights = PyList::empty(py);
        for w in &s.weights {
            weights.append(Buffer::f32s(w))?;
        }
        d.set_item("weights", weights)?;
        d.set_item("roi", Buffer::f32s(&s.roi))?;
        list.append(d)?;
    }
    Ok(list)
}

/// The MatSeg loss as `matseg train` computes it, of unit descriptors
/// `[B, D, H, W]`, weights `[B, K, H, W]` and ROI `[B, H, W]` (C-contiguous
/// float32 arrays):
/// the reference other implementations (the PyTorch trainer) are tested
/// against. `None` when the batch has fewer than two materials.
#[cfg(feature = "torch")]
#[pyfunction]
#[pyo3(signature = (descriptors, weights, roi, shape, materials))]
pub fn matseg_loss(
    py: Python<'_>,
    descriptors: &Bound<'_, PyAny>,
    weights: &Bound<'_, PyAny>,
    roi: &Bound<'_, PyAny>,
    shape: (usize, usize, usize, usize),
    materials: usize,
) -> PyResult<Option<f64>> {
    use crate::buffer::contiguous;
    use matseg_net::{matseg_loss, ImageTargets};
    use tch::Tensor;
    let (b, d, h, w) = shape;
    let desc: Vec<f32> = contiguous(py, descriptors, b * d * h * w, "descriptors")?;
    let weights: Vec<f32> = contiguous(py, weights, b * materials * h * w, "weights")?;
    let roi: Vec<f32> = contiguous(py, roi, b * h * w, "roi")?;
    let [b, d, h, w, k] = [b, d, h, w, materials].map(|n| n as i64);
    let desc = Tensor::from_slice(&desc).view([b, d, h, w]);
    let weights = Tensor::from_slice(&weights).view([b, k, h, w]);
    let roi = Tensor::from_slice(&roi).view([b, h, w]);
    let targets: Vec<ImageTargets> = (0..b)
        .map(|i| ImageTargets {
            weights: weights.get(i),
            roi: roi.get(i),
        })
        .collect();
    Ok(matseg_loss(&desc, &targets).map(|l| l.double_value(&[])))
}
