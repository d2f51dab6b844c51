//! A decoded sample as a Python dict of bytes and sizes.

use matseg_data::Sample;
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict, PyList};

/// `{"key", "width", "height", "image": RGB bytes, "masks": [bytes],
/// "roi": bytes | None, "meta": JSON text | None}`: 8-bit planes row by row.
pub fn sample_dict<'py>(py: Python<'py>, sample: &Sample) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    let (w, h) = sample.image.dimensions();
    d.set_item("key", &sample.key)?;
    d.set_item("width", w)?;
    d.set_item("height", h)?;
    d.set_item("image", PyBytes::new(py, sample.image.as_raw()))?;
    let masks = PyList::empty(py);
    for m in &sample.masks {
        masks.append(PyBytes::new(py, m.as_raw()))?;
    }
    d.set_item("masks", masks)?;
    d.set_item(
        "roi",
        sample.roi.as_ref().map(|r| PyBytes::new(py, r.as_raw())),
    )?;
    d.set_item("meta", sample.meta.as_ref().map(|m| m.to_string()))?;
    Ok(d)
}

/// Little-endian bytes of `values`, for `numpy.frombuffer(dtype="<f4")`.
pub fn f32_bytes(values: &[f32]) -> Vec<u8> {
    values.iter().flat_map(|v| v.to_le_bytes()).collect()
}

/// Reads a photo (JPEG, PNG...) as `matseg` commands do: (RGB bytes,
/// width, height), the same pixels the command line sees.
#[pyfunction]
pub fn read_rgb(
    py: Python<'_>,
    path: std::path::PathBuf,
) -> PyResult<(Bound<'_, PyBytes>, u32, u32)> {
    let image = py
        .detach(|| matseg_image::io::read_rgb(&path))
        .map_err(crate::errors::matseg_error)?;
    let (w, h) = image.dimensions();
    Ok((PyBytes::new(py, image.as_raw()), w, h))
}
