//! The single place where `GeometryError` becomes a Python exception, and the boundary
//! that keeps Rust panics from crossing into Python.

use std::panic::{catch_unwind, AssertUnwindSafe};

use kinmo_geometry::GeometryError;
use pyo3::exceptions::{PyOSError, PyRuntimeError, PyValueError};
use pyo3::{PyErr, PyResult, Python};

/// Convert a geometry error into `OSError` (files) or `ValueError` (everything else).
pub fn to_py(err: GeometryError) -> PyErr {
    match err {
        GeometryError::Io { .. } => PyOSError::new_err(err.to_string()),
        other => PyValueError::new_err(other.to_string()),
    }
}

/// The `RuntimeError` a caught panic becomes: `"{function}: internal error in kinmo._core
/// (...)"`, an ordinary (picklable) `Exception`, never pyo3's `PanicException`.
pub fn panic_to_py(function: &str, payload: &(dyn std::any::Any + Send)) -> PyErr {
    let msg = payload
        .downcast_ref::<&str>()
        .map(|s| (*s).to_string())
        .or_else(|| payload.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "unknown panic".to_string());
    PyRuntimeError::new_err(format!(
        "{function}: internal error in kinmo._core ({msg}); this is a bug, please report it"
    ))
}

/// Run the pure-Rust part of binding `function` with the GIL released, mapping its
/// `GeometryError` with [`to_py`] and, as a last resort, a panic with [`panic_to_py`].
///
/// Every binding runs its Rust work through this function, so no panic crosses into
/// Python.
pub fn detach<T, F>(py: Python<'_>, function: &str, f: F) -> PyResult<T>
where
    T: Send,
    F: FnOnce() -> Result<T, GeometryError> + Send,
{
    match py.detach(|| catch_unwind(AssertUnwindSafe(f))) {
        Ok(result) => result.map_err(to_py),
        Err(payload) => Err(panic_to_py(function, payload.as_ref())),
    }
}
