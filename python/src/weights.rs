//! safetensors files for `matseg.safetensors`, read and written by
//! matseg-weights (the reader and writer of `matseg weights`).

use matseg_weights::{
    read_safetensors as read_tensors, read_safetensors_metadata,
    write_safetensors as write_tensors, DType, Tensor,
};
use pyo3::exceptions::{PyOSError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyBytes;
use std::path::PathBuf;

/// A tensor as Python sees it: (name, safetensors dtype, shape, bytes).
type PyTensor<'py> = (String, &'static str, Vec<usize>, Bound<'py, PyBytes>);

/// A file's tensors and its metadata (key, value).
type PyTensors<'py> = (Vec<PyTensor<'py>>, Vec<(String, String)>);

/// The tensors of the file at `path` in data order, and its metadata.
#[pyfunction]
pub fn read_safetensors(py: Python<'_>, path: PathBuf) -> PyResult<PyTensors<'_>> {
    let name = path.display().to_string();
    let bytes = std::fs::read(&path).map_err(|e| PyOSError::new_err(format!("{name}: {e}")))?;
    let invalid = |e: matseg_weights::WeightsError| PyValueError::new_err(e.to_string());
    let tensors = read_tensors(&bytes, &name).map_err(invalid)?;
    let metadata = read_safetensors_metadata(&bytes, &name).map_err(invalid)?;
    let tensors = tensors
        .into_iter()
        .map(|t| {
            let data = PyBytes::new(py, &t.data);
            (t.name, t.dtype.safetensors_name(), t.shape, data)
        })
        .collect();
    Ok((tensors, metadata))
}

/// Writes `tensors` (name, safetensors dtype, shape, little-endian bytes)
/// and `metadata` to `path` through a temporary file renamed into place.
#[pyfunction]
pub fn write_safetensors(
    path: PathBuf,
    tensors: Vec<(String, String, Vec<usize>, Bound<'_, PyBytes>)>,
    metadata: Vec<(String, String)>,
) -> PyResult<()> {
    let tensors = tensors
        .into_iter()
        .map(|(name, dtype, shape, data)| {
            let data = data.as_bytes().to_vec();
            let dtype = DType::from_safetensors_name(&dtype)
                .ok_or_else(|| PyValueError::new_err(format!("{name}: unknown dtype {dtype}")))?;
            if data.len() != shape.iter().product::<usize>() * dtype.size() {
                return Err(PyValueError::new_err(format!(
                    "{name}: {} bytes do not hold shape {shape:?} of {}",
                    data.len(),
                    dtype.safetensors_name()
                )));
            }
            Ok(Tensor {
                name,
                dtype,
                shape,
                data,
            })
        })
        .collect::<PyResult<Vec<_>>>()?;
    let metadata: Vec<(&str, &str)> = metadata
        .iter()
        .map(|(k, v)| (k.as_str(), v.as_str()))
        .collect();
    matseg_image::io::write_atomic(&path, &write_tensors(&tensors, &metadata))
        .map_err(|e| PyOSError::new_err(format!("{}: cannot write: {e}", path.display())))
}
