//! `matseg.Dataset`: random access to stored samples (MatSeg folders or
//! WebDataset shards).

use crate::batches::{batch_list, MixedDataset};
use crate::errors::matseg_error;
use crate::samples::sample_dict;
use matseg_data::training::DatasetSource;
use matseg_data::Dataset;
use pyo3::exceptions::PyIndexError;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use std::path::PathBuf;

/// An opened dataset.
#[pyclass(module = "matseg._core", name = "Dataset", frozen)]
pub struct PyDataset {
    source: DatasetSource,
    root: PathBuf,
}

impl PyDataset {
    /// The dataset as training samples.
    pub fn source(&self) -> &DatasetSource {
        &self.source
    }

    fn check(&self, index: usize) -> PyResult<()> {
        let n = self.source.0.len();
        if index >= n {
            return Err(PyIndexError::new_err(format!(
                "{}: sample {index} is past the end ({n} samples)",
                self.root.display()
            )));
        }
        Ok(())
    }
}

#[pymethods]
impl PyDataset {
    /// Opens a folder of sample folders and/or `.tar` shards, or one shard.
    #[new]
    fn new(py: Python<'_>, root: PathBuf) -> PyResult<Self> {
        let dataset = py.detach(|| Dataset::open(&root)).map_err(matseg_error)?;
        Ok(Self {
            source: DatasetSource(dataset),
            root,
        })
    }

    fn __len__(&self) -> usize {
        self.source.0.len()
    }

    /// The key of sample `index` (its folder name or shard key).
    fn key(&self, index: usize) -> PyResult<String> {
        self.check(index)?;
        Ok(self.source.0.key(index))
    }

    /// Sample `index`, decoded (see `samples::sample_dict`).
    fn sample<'py>(&self, py: Python<'py>, index: usize) -> PyResult<Bound<'py, PyDict>> {
        self.check(index)?;
        let sample = py
            .detach(|| self.source.0.get(index))
            .map_err(matseg_error)?;
        sample_dict(py, sample)
    }

    /// Training batch `step` drawn from the dataset (with `mix`, another
    /// dataset mixed in) under `plan` (JSON).
    #[pyo3(signature = (plan, seed, step, mix=None))]
    fn batch<'py>(
        &self,
        py: Python<'py>,
        plan: &str,
        seed: u64,
        step: u64,
        mix: MixedDataset<'_>,
    ) -> PyResult<Bound<'py, PyList>> {
        batch_list(py, &self.source, mix, plan, seed, step)
    }
}
