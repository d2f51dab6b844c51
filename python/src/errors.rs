//! How the library's errors reach Python: as `matseg.MatsegError` with the
//! message the command line prints.

use pyo3::exceptions::PyException;
use pyo3::PyErr;
use std::fmt::Display;

pyo3::create_exception!(
    _core,
    MatsegError,
    PyException,
    "A matseg operation failed; the message names the file or setting and the problem."
);

/// The error as a [`MatsegError`] carrying its message.
pub fn matseg_error(e: impl Display) -> PyErr {
    MatsegError::new_err(e.to_string())
}
