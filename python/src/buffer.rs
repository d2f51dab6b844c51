//! Arrays crossing between Rust and Python through the buffer protocol,
//! with no bytes objects in between: [`Buffer`] hands bytes made in Rust
//! to numpy, which wraps them without a copy (`numpy.frombuffer` gives a
//! writable array that keeps the buffer alive); [`contiguous`] reads a
//! C-contiguous numpy array passed in, and [`Photo`] an RGB image.

use image::RgbImage;
use pyo3::buffer::{Element, PyBuffer};
use pyo3::exceptions::{PyBufferError, PyValueError};
use pyo3::ffi;
use pyo3::prelude::*;
use std::ffi::{c_int, c_void};
use std::ptr::NonNull;

/// Bytes owned by Rust, exported to Python as a one-dimensional, writable
/// buffer of unsigned bytes (format `B`).
#[pyclass(module = "matseg._core", frozen)]
pub struct Buffer {
    /// The start of the boxed bytes (dangling when empty).
    start: NonNull<u8>,
    /// Their count.
    len: usize,
}

// SAFETY: the buffer owns its bytes (a leaked Box<[u8]>, freed in Drop);
// Rust never reads or writes them after construction, only Python's
// consumers of the exported view do, as they would a bytearray's.
unsafe impl Send for Buffer {}
unsafe impl Sync for Buffer {}

impl Buffer {
    /// A buffer taking ownership of `bytes`.
    pub fn new(bytes: Vec<u8>) -> Self {
        let len = bytes.len();
        let boxed: Box<[u8]> = bytes.into_boxed_slice();
        let start = NonNull::new(Box::into_raw(boxed).cast::<u8>()).expect("a box is not null");
        Self { start, len }
    }

    /// Little-endian `f32` values, for `numpy.frombuffer(dtype="<f4")`.
    pub fn f32s(values: &[f32]) -> Self {
        Self::new(values.iter().flat_map(|v| v.to_le_bytes()).collect())
    }
}

impl Drop for Buffer {
    fn drop(&mut self) {
        let slice = std::ptr::slice_from_raw_parts_mut(self.start.as_ptr(), self.len);
        // SAFETY: `start` and `len` come from Box::into_raw in `new`, and
        // Python holds a reference to the buffer while any view of it
        // lives, so no view outlives this.
        drop(unsafe { Box::from_raw(slice) });
    }
}

/// The format of one unsigned byte, as the buffer protocol spells it.
const UNSIGNED_BYTE: &std::ffi::CStr = c"B";

#[pymethods]
impl Buffer {
    /// Fills `view` with the whole buffer, one-dimensional and writable.
    ///
    /// # Safety
    /// `view` must point at a `Py_buffer` the caller owns (Python's
    /// buffer protocol guarantees it).
    unsafe fn __getbuffer__(
        slf: Bound<'_, Self>,
        view: *mut ffi::Py_buffer,
        flags: c_int,
    ) -> PyResult<()> {
        if view.is_null() {
            return Err(PyBufferError::new_err("no view to fill"));
        }
        let (start, len) = (slf.get().start, slf.get().len);
        // SAFETY: `view` is valid (checked above and by the protocol); the
        // shape and strides point into the view itself, which outlives
        // every use of them; the format is a static string.
        unsafe {
            (*view).obj = slf.into_any().into_ptr();
            (*view).buf = start.as_ptr().cast::<c_void>();
            (*view).len = len as ffi::Py_ssize_t;
            (*view).readonly = 0;
            (*view).itemsize = 1;
            (*view).format = if flags & ffi::PyBUF_FORMAT != 0 {
                UNSIGNED_BYTE.as_ptr().cast_mut()
            } else {
                std::ptr::null_mut()
            };
            (*view).ndim = 1;
            (*view).shape = if flags & ffi::PyBUF_ND == ffi::PyBUF_ND {
                &mut (*view).len
            } else {
                std::ptr::null_mut()
            };
            (*view).strides = if flags & ffi::PyBUF_STRIDES == ffi::PyBUF_STRIDES {
                &mut (*view).itemsize
            } else {
                std::ptr::null_mut()
            };
            (*view).suboffsets = std::ptr::null_mut();
            (*view).internal = std::ptr::null_mut();
        }
        Ok(())
    }

    /// Nothing to release: the view's format is static and its shape and
    /// strides live in the view.
    unsafe fn __releasebuffer__(&self, _view: *mut ffi::Py_buffer) {}

    /// Bytes in the buffer.
    fn __len__(&self) -> usize {
        self.len
    }
}

/// `data` as a C-contiguous buffer of `T` (a numpy array of the matching
/// dtype: uint8 for `u8`, float32 for `f32`); `what` names it in errors.
fn c_contiguous<T: Element>(data: &Bound<'_, PyAny>, what: &str) -> PyResult<PyBuffer<T>> {
    let buffer = PyBuffer::<T>::get(data).map_err(|e| {
        PyValueError::new_err(format!(
            "{what}: not an array of {}: {e}",
            std::any::type_name::<T>()
        ))
    })?;
    if !buffer.is_c_contiguous() {
        return Err(PyValueError::new_err(format!(
            "{what}: the array is not C-contiguous"
        )));
    }
    Ok(buffer)
}

/// The values of `data`, a C-contiguous buffer of `expected` values of
/// `T` (see [`c_contiguous`]), copied once into Rust; `what` names it in
/// errors.
pub fn contiguous<T: Element + Copy>(
    py: Python<'_>,
    data: &Bound<'_, PyAny>,
    expected: usize,
    what: &str,
) -> PyResult<Vec<T>> {
    let buffer = c_contiguous::<T>(data, what)?;
    if buffer.item_count() != expected {
        return Err(PyValueError::new_err(format!(
            "{what}: {} values, expected {expected}",
            buffer.item_count()
        )));
    }
    buffer.to_vec(py)
}

/// A C-contiguous float32 array handed in from Python, read where numpy
/// keeps it rather than copied: a model's answer, hundreds of megabytes at
/// full resolution. The buffer view keeps the memory alive and, while it
/// is held, the array cannot be resized; the harness reads it before it
/// asks the model anything else, and the model's contract is not to
/// change an answer it has returned meanwhile.
pub struct HeldArray(PyBuffer<f32>);

impl HeldArray {
    /// `data`'s values, `expected` of them; `what` names it in errors.
    pub fn new(data: &Bound<'_, PyAny>, expected: usize, what: &str) -> PyResult<Self> {
        let buffer = c_contiguous::<f32>(data, what)?;
        if buffer.item_count() != expected {
            return Err(PyValueError::new_err(format!(
                "{what}: {} values, expected {expected}",
                buffer.item_count()
            )));
        }
        Ok(Self(buffer))
    }
}

impl std::ops::Deref for HeldArray {
    type Target = [f32];

    fn deref(&self) -> &[f32] {
        let count = self.0.item_count();
        if count == 0 {
            return &[];
        }
        // SAFETY: the view is of `count` C-contiguous, aligned f32 values
        // (PyBuffer::get checked the format, item size and alignment), and
        // it keeps the exporting object's memory alive until it is
        // released with the view, after any borrow of `self` ends.
        unsafe { std::slice::from_raw_parts(self.0.buf_ptr().cast::<f32>().cast_const(), count) }
    }
}

/// An RGB image handed in as a C-contiguous `height x width x 3` uint8
/// array, its size read from the array's own shape.
pub struct Photo(pub RgbImage);

impl<'a, 'py> FromPyObject<'a, 'py> for Photo {
    type Error = PyErr;

    fn extract(obj: Borrowed<'a, 'py, PyAny>) -> PyResult<Self> {
        let buffer = c_contiguous::<u8>(&obj, "image")?;
        let &[height, width, 3] = buffer.shape() else {
            return Err(PyValueError::new_err(format!(
                "image: expected shape HxWx3, got {:?}",
                buffer.shape()
            )));
        };
        let (Ok(w), Ok(h)) = (u32::try_from(width), u32::try_from(height)) else {
            return Err(PyValueError::new_err(format!(
                "image: {width}x{height} is too large"
            )));
        };
        if w == 0 || h == 0 {
            return Err(PyValueError::new_err(format!(
                "image: {width}x{height} has no pixels"
            )));
        }
        let bytes = buffer.to_vec(obj.py())?;
        Ok(Self(
            RgbImage::from_raw(w, h, bytes).expect("the shape was checked"),
        ))
    }
}
