//! The single place where `GeometryError` becomes a Python exception.

use kinmo_geometry::GeometryError;
use pyo3::exceptions::{PyOSError, PyValueError};
use pyo3::PyErr;

/// Convert a geometry error into `OSError` (files) or `ValueError` (everything else).
#[allow(dead_code)]
pub fn to_py(err: GeometryError) -> PyErr {
    match err {
        GeometryError::Io { .. } => PyOSError::new_err(err.to_string()),
        other => PyValueError::new_err(other.to_string()),
    }
}
