//! Training batches as `matseg train` draws them (the batch plan: one
//! random size per batch, samples fitted and augmented), for PyTorch.

use crate::dataset::PyDataset;
use crate::errors::matseg_error;
use crate::samples::f32_bytes;
use matseg_net::data::{batch_samples, BatchPlan, MixedSource, SampleSource};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict, PyList};

/// The paper's batch plan as JSON (the defaults of `matseg.BatchPlan`).
#[pyfunction]
pub fn default_plan() -> String {
    serde_json::to_string(&BatchPlan::SPEC).expect("a plan serialises")
}

/// A stored dataset mixed into a batch source and the share of samples
/// taken from it (`matseg train --mix-data`, `--mix-fraction`).
pub type Mix<'py> = Option<(PyRef<'py, PyDataset>, f64)>;

/// Batch `step` of `source` (with `mix`) under `plan` (JSON) and `seed`: a
/// list of `{"width", "height", "image": RGB bytes, "weights": [f32
/// bytes], "roi": f32 bytes}`, all images of one size.
pub fn batch_list<'py>(
    py: Python<'py>,
    source: &dyn SampleSource,
    mix: Mix<'_>,
    plan: &str,
    seed: u64,
    step: u64,
) -> PyResult<Bound<'py, PyList>> {
    let plan: BatchPlan = serde_json::from_str(plan)
        .map_err(|e| PyValueError::new_err(format!("batch plan: {e}")))?;
    plan.validate()
        .map_err(|e| PyValueError::new_err(format!("batch plan: {e}")))?;
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
        d.set_item("image", PyBytes::new(py, &s.rgb))?;
        let weights = PyList::empty(py);
        for w in &s.weights {
            weights.append(PyBytes::new(py, &f32_bytes(w)))?;
        }
        d.set_item("weights", weights)?;
        d.set_item("roi", PyBytes::new(py, &f32_bytes(&s.roi)))?;
        list.append(d)?;
    }
    Ok(list)
}

/// Little-endian f32 bytes as floats, checked to hold `count` of them.
fn floats(bytes: &[u8], count: usize, what: &str) -> PyResult<Vec<f32>> {
    if bytes.len() != count * 4 {
        return Err(PyValueError::new_err(format!(
            "{what}: {} bytes, expected {count} float32 values",
            bytes.len()
        )));
    }
    Ok(bytes
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect())
}

/// The MatSeg loss as `matseg train` computes it, of unit descriptors
/// `[B, D, H, W]`, weights `[B, K, H, W]` and ROI `[B, H, W]` (f32 bytes):
/// the reference other implementations (the PyTorch trainer) are tested
/// against. `None` when the batch has fewer than two materials.
#[pyfunction]
#[pyo3(signature = (descriptors, weights, roi, shape, materials))]
pub fn matseg_loss(
    descriptors: &[u8],
    weights: &[u8],
    roi: &[u8],
    shape: (usize, usize, usize, usize),
    materials: usize,
) -> PyResult<Option<f64>> {
    use matseg_net::{matseg_loss, ImageTargets};
    use tch::Tensor;
    let (b, d, h, w) = shape;
    let desc = floats(descriptors, b * d * h * w, "descriptors")?;
    let weights = floats(weights, b * materials * h * w, "weights")?;
    let roi = floats(roi, b * h * w, "roi")?;
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
