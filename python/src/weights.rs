//! safetensors files for `matseg.safetensors`, read and written by
//! matseg-weights (the reader and writer of `matseg weights`).

use crate::buffer::{contiguous, Buffer};
use matseg_weights::{
    read_safetensors as read_tensors, read_safetensors_metadata,
    write_safetensors as write_tensors, DType, Tensor,
};
use pyo3::exceptions::{PyOSError, PyValueError};
use pyo3::prelude::*;
use std::path::PathBuf;

/// A tensor as Python sees it: (name, safetensors dtype, shape, its
/// little-endian bytes as a buffer).
type PyTensor = (String, &'static str, Vec<usize>, Buffer);

/// A file's tensors and its metadata (key, value).
type PyTensors = (Vec<PyTensor>, Vec<(String, String)>);

/// The tensors of the file at `path` in data order, and its metadata.
#[pyfunction]
pub fn read_safetensors(path: PathBuf) -> PyResult<PyTensors> {
    let name = path.display().to_string();
    let bytes = std::fs::read(&path).map_err(|e| PyOSError::new_err(format!("{name}: {e}")))?;
    let invalid = |e: matseg_weights::WeightsError| PyValueError::new_err(e.to_string());
    let tensors = read_tensors(&bytes, &name).map_err(invalid)?;
    let metadata = read_safetensors_metadata(&bytes, &name).map_err(invalid)?;
    let tensors = tensors
        .into_iter()
        .map(|t| {
            let data = Buffer::new(t.data);
            (t.name, t.dtype.safetensors_name(), t.shape, data)
        })
        .collect();
    Ok((tensors, metadata))
}

/// Writes `tensors` (name, safetensors dtype, shape, its little-endian
/// bytes as a C-contiguous uint8 array) and `metadata` to `path` through
/// a temporary file renamed into place.
#[pyfunction]
pub fn write_safetensors(
    py: Python<'_>,
    path: PathBuf,
    tensors: Vec<(String, String, Vec<usize>, Bound<'_, PyAny>)>,
    metadata: Vec<(String, String)>,
) -> PyResult<()> {
    let tensors = tensors
        .into_iter()
        .map(|(name, dtype, shape, data)| {
            let dtype = DType::from_safetensors_name(&dtype)
                .ok_or_else(|| PyValueError::new_err(format!("{name}: unknown dtype {dtype}")))?;
            let expected = shape.iter().product::<usize>() * dtype.size();
            let what = format!("{name} (shape {shape:?} of {})", dtype.safetensors_name());
            let data = contiguous(py, &data, expected, &what)?;
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
    matseg_image::outputs::write_atomic(&path, &write_tensors(&tensors, &metadata))
        .map_err(|e| PyOSError::new_err(format!("{}: cannot write: {e}", path.display())))
}
