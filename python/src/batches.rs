//! Training batches as `matseg train` draws them (the batch plan: one
//! random size per batch, samples fitted and augmented), for PyTorch.

use crate::errors::matseg_error;
use crate::samples::f32_bytes;
use matseg_net::data::{batch_samples, BatchPlan, SampleSource};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict, PyList};

/// The paper's batch plan as JSON (the defaults of `matseg.BatchPlan`).
#[pyfunction]
pub fn default_plan() -> String {
    serde_json::to_string(&BatchPlan::SPEC).expect("a plan serialises")
}

/// Batch `step` of `source` under `plan` (JSON) and `seed`: a list of
/// `{"width", "height", "image": RGB bytes, "weights": [f32 bytes],
/// "roi": f32 bytes}`, all images of one size.
pub fn batch_list<'py>(
    py: Python<'py>,
    source: &dyn SampleSource,
    plan: &str,
    seed: u64,
    step: u64,
) -> PyResult<Bound<'py, PyList>> {
    let plan: BatchPlan = serde_json::from_str(plan)
        .map_err(|e| PyValueError::new_err(format!("batch plan: {e}")))?;
    plan.validate()
        .map_err(|e| PyValueError::new_err(format!("batch plan: {e}")))?;
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
