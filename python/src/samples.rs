//! A decoded sample as a Python dict of buffers and sizes.

use crate::buffer::Buffer;
use matseg_data::Sample;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

/// `{"key", "width", "height", "image": RGB buffer, "masks": [buffer],
/// "roi": buffer | None, "meta": JSON text | None}`: 8-bit planes row by
/// row.
pub fn sample_dict(py: Python<'_>, sample: Sample) -> PyResult<Bound<'_, PyDict>> {
    let d = PyDict::new(py);
    let (w, h) = sample.image.dimensions();
    d.set_item("key", &sample.key)?;
    d.set_item("width", w)?;
    d.set_item("height", h)?;
    d.set_item("image", Buffer::new(sample.image.into_raw()))?;
    let masks = PyList::empty(py);
    for m in sample.masks {
        masks.append(Buffer::new(m.into_raw()))?;
    }
    d.set_item("masks", masks)?;
    d.set_item("roi", sample.roi.map(|r| Buffer::new(r.into_raw())))?;
    d.set_item("meta", sample.meta.as_ref().map(|m| m.to_string()))?;
    Ok(d)
}

/// Reads a photo (JPEG, PNG...) as `matseg` commands do: (RGB buffer,
/// width, height), the same pixels the command line sees.
#[pyfunction]
pub fn read_rgb(py: Python<'_>, path: std::path::PathBuf) -> PyResult<(Buffer, u32, u32)> {
    let image = py
        .detach(|| matseg_image::io::read_rgb(&path))
        .map_err(crate::errors::matseg_error)?;
    let (w, h) = image.dimensions();
    Ok((Buffer::new(image.into_raw()), w, h))
}
