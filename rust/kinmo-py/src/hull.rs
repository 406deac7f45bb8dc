//! Binding of `kinmo_geometry::hull`: `convex_hull`.

use numpy::{PyArray1, PyArray2, PyReadonlyArray2};
use pyo3::prelude::*;

use crate::convert::{array1, array2, points_from_array};
use crate::errors::detach;

type HullArrays<'py> = (Bound<'py, PyArray1<i64>>, Bound<'py, PyArray2<i64>>);

/// The exact convex hull of `points (N, 3)` float64: `(vertices (H,) int64, faces (F, 3)
/// int64)`, indices into `points`, faces counter-clockwise seen from outside; `None` when
/// the hull has no volume (fewer than 4 points, or all on a plane). `ValueError` on a bad
/// shape or NaN/inf.
#[pyfunction]
fn convex_hull<'py>(
    py: Python<'py>,
    points: PyReadonlyArray2<'py, f64>,
) -> PyResult<Option<HullArrays<'py>>> {
    let pts = points_from_array(&points, "points")?;
    let hull = detach(py, "convex_hull", || {
        kinmo_geometry::hull::convex_hull(&pts)
    })?;
    Ok(hull.map(|h| {
        let n = h.faces.len();
        let faces: Vec<i64> = h.faces.iter().flatten().map(|&i| i as i64).collect();
        let vertices: Vec<i64> = h.vertices.iter().map(|&i| i as i64).collect();
        (array1(py, vertices), array2(py, faces, n, 3))
    }))
}

/// Register this module's functions on `kinmo._core`.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(convex_hull, m)?)?;
    Ok(())
}
