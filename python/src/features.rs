//! `matseg.FeatureCache`: a feature cache made by `matseg features`, and
//! its training batches as `matseg train --features` draws them.

use crate::batches::parse_plan;
use crate::buffer::Buffer;
use crate::errors::matseg_error;
use matseg_net::features::{CacheManifest, FeatureCache};
use matseg_net::train::cached_batch;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use std::path::PathBuf;

/// An opened feature cache.
#[pyclass(module = "matseg._core", name = "FeatureCache", frozen)]
pub struct PyFeatureCache {
    cache: FeatureCache,
}

#[pymethods]
impl PyFeatureCache {
    /// Opens the cache in `dir` (every shard indexed and checked).
    #[new]
    fn new(py: Python<'_>, dir: PathBuf) -> PyResult<Self> {
        let cache = py
            .detach(|| FeatureCache::open(&dir))
            .map_err(matseg_error)?;
        Ok(Self { cache })
    }

    fn __len__(&self) -> usize {
        self.cache.len() as usize
    }

    /// The manifest (`cache.json`) as JSON.
    fn manifest(&self) -> String {
        serde_json::to_string(&self.cache.manifest).expect("a manifest serialises")
    }

    /// What differs between this cache and the one `manifest` (JSON, as a
    /// run's `features.manifest` keeps it) describes, in words; `None`
    /// when they are the same.
    fn difference(&self, manifest: &str) -> PyResult<Option<&'static str>> {
        let other: CacheManifest = serde_json::from_str(manifest)
            .map_err(|e| PyValueError::new_err(format!("cache manifest: {e}")))?;
        Ok(self.cache.manifest.difference(&other))
    }

    /// Batch `step` under `plan` (JSON) and `seed`: a list of samples, each
    /// `{name: (shape, buffer of little-endian 16-bit floats)}` for `s4`, `s8`, `s16`, `s32`,
    /// `lab`, `weights` and `roi`.
    fn batch<'py>(
        &self,
        py: Python<'py>,
        plan: &str,
        seed: u64,
        step: u64,
    ) -> PyResult<Bound<'py, PyList>> {
        let plan = parse_plan(plan)?;
        let samples = py
            .detach(|| cached_batch(&self.cache, &plan, seed, step))
            .map_err(matseg_error)?;
        let list = PyList::empty(py);
        for sample in samples {
            let d = PyDict::new(py);
            for t in sample.into_stored() {
                d.set_item(t.name, (t.shape, Buffer::new(t.data)))?;
            }
            list.append(d)?;
        }
        Ok(list)
    }
}
