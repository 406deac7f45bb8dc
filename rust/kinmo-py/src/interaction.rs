//! Bindings of `kinmo_geometry::interaction`: `interaction_region`.

use kinmo_geometry::interaction;
use numpy::{PyArray1, PyReadonlyArray2};
use pyo3::prelude::*;

use crate::convert::{array1, points_from_array};
use crate::errors::detach;

type Region<'py> = (
    Bound<'py, PyArray1<bool>>,
    Bound<'py, PyArray1<bool>>,
    Bound<'py, PyArray1<f64>>,
    bool,
);

/// Interaction region of two point clouds (Hu et al. 2015; Liu et al. 2023 Sec. 3.3).
///
/// `moving (Na, 3)`, `reference (Nb, 3)` float64, `radius` > 0. Returns `(mask_moving (Na,)
/// bool, mask_reference (Nb,) bool, centroid (3,) float64, empty)`. `ValueError` on bad
/// shapes, empty or non-finite point sets, or a bad radius.
#[pyfunction]
fn interaction_region<'py>(
    py: Python<'py>,
    moving: PyReadonlyArray2<'py, f64>,
    reference: PyReadonlyArray2<'py, f64>,
    radius: f64,
) -> PyResult<Region<'py>> {
    let a = points_from_array(&moving, "moving")?;
    let b = points_from_array(&reference, "reference")?;
    let r = detach(py, "interaction_region", || {
        interaction::interaction_region(&a, &b, radius)
    })?;
    let c = r.centroid;
    Ok((
        array1(py, r.mask_moving),
        array1(py, r.mask_reference),
        array1(py, vec![c.x, c.y, c.z]),
        r.empty,
    ))
}

/// Register this module's functions on `kinmo._core`.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(interaction_region, m)?)?;
    Ok(())
}
