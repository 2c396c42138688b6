//! The one place where core errors become Python exceptions.

use imgform_core::CoreError;
use pyo3::create_exception;
use pyo3::exceptions::{PyMemoryError, PyValueError};
use pyo3::prelude::*;

create_exception!(
    imgform_rs,
    RawError,
    PyValueError,
    "An unreadable, truncated or unsupported raw file; the message names the file."
);

/// Maps every core error to its Python class. Exhaustive on purpose: a new
/// variant must be given a class here before the crate compiles.
pub fn to_pyerr(err: CoreError) -> PyErr {
    match err {
        CoreError::InvalidArgument(msg) | CoreError::Shape(msg) => PyValueError::new_err(msg),
        CoreError::Memory(msg) => PyMemoryError::new_err(msg),
    }
}

/// Runs a kernel with the GIL released and maps its error.
///
/// Kernels never call back into Python, so they can run while other Python
/// threads work; the closure must only capture plain Rust data (slices).
pub fn detached<T, F>(py: Python<'_>, kernel: F) -> PyResult<T>
where
    T: Send,
    F: Send + FnOnce() -> imgform_core::Result<T>,
{
    py.detach(kernel).map_err(to_pyerr)
}
