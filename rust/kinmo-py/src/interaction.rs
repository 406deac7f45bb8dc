//! Bindings of `kinmo_geometry::interaction`.

use pyo3::prelude::*;

/// Register this module's functions on `kinmo._core`.
pub fn register(_m: &Bound<'_, PyModule>) -> PyResult<()> {
    Ok(())
}
