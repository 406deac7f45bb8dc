//! Bindings of `kinmo_geometry::mesh`.

use pyo3::prelude::*;

/// Register this module's functions on `kinmo._core`.
pub fn register(_m: &Bound<'_, PyModule>) -> PyResult<()> {
    Ok(())
}
