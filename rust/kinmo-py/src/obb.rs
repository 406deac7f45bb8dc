//! Bindings of `kinmo_geometry::obb`: `fit_obb`, `fit_obb_batch`.

use kinmo_geometry::obb::{self, Obb, ObbParams};
use nalgebra::Vector3;
use numpy::{PyArray1, PyArray2, PyArray3, PyReadonlyArray2};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

use crate::convert::{array1, array2, array3, points_from_array};
use crate::errors::detach;

type ObbArrays<'py> = (
    Bound<'py, PyArray1<f64>>,
    Bound<'py, PyArray2<f64>>,
    Bound<'py, PyArray1<f64>>,
);

type ObbBatchArrays<'py> = (
    Bound<'py, PyArray2<f64>>,
    Bound<'py, PyArray3<f64>>,
    Bound<'py, PyArray2<f64>>,
);

fn params(volume_tolerance: f64, up: Option<[f64; 3]>, symmetry: bool) -> ObbParams {
    ObbParams {
        volume_tolerance,
        up: up.map(Vector3::from),
        symmetry,
        ..ObbParams::default()
    }
}

/// Row-major axes of a box.
fn axes_flat(b: &Obb) -> [f64; 9] {
    let a = &b.axes;
    [
        a[(0, 0)],
        a[(0, 1)],
        a[(0, 2)],
        a[(1, 0)],
        a[(1, 1)],
        a[(1, 2)],
        a[(2, 0)],
        a[(2, 1)],
        a[(2, 2)],
    ]
}

/// Fit a tight, up- and symmetry-aligned oriented bounding box to `points (N, 3)`.
///
/// Returns `(center (3,), axes (3, 3) rows, half_extents (3,))`, all float64. `up=None`
/// disables the up preference. `ValueError` on empty input, bad shape, NaN/inf or bad
/// options. See `kinmo.geometry.obb.fit_obb`.
#[pyfunction]
#[pyo3(signature = (points, *, volume_tolerance = 0.01, up = Some([0.0, 1.0, 0.0]), symmetry = true))]
fn fit_obb<'py>(
    py: Python<'py>,
    points: PyReadonlyArray2<'py, f64>,
    volume_tolerance: f64,
    up: Option<[f64; 3]>,
    symmetry: bool,
) -> PyResult<ObbArrays<'py>> {
    let pts = points_from_array(&points, "points")?;
    let p = params(volume_tolerance, up, symmetry);
    let b = detach(py, "fit_obb", || obb::fit_obb_with(&pts, &p))?;
    Ok((
        array1(py, b.center.coords.iter().copied().collect()),
        array2(py, axes_flat(&b).to_vec(), 3, 3),
        array1(py, b.half_extents.iter().copied().collect()),
    ))
}

/// Fit one box per point set of `point_sets` (a sequence of `(N_i, 3)` float64 arrays),
/// in parallel.
///
/// Returns `(centers (B, 3), axes (B, 3, 3), half_extents (B, 3))`. Set `i` is named
/// `point_sets[i]` in error messages.
#[pyfunction]
#[pyo3(signature = (point_sets, *, volume_tolerance = 0.01, up = Some([0.0, 1.0, 0.0]), symmetry = true))]
fn fit_obb_batch<'py>(
    py: Python<'py>,
    point_sets: &Bound<'py, PyAny>,
    volume_tolerance: f64,
    up: Option<[f64; 3]>,
    symmetry: bool,
) -> PyResult<ObbBatchArrays<'py>> {
    let iter = point_sets.try_iter().map_err(|_| {
        PyValueError::new_err("point_sets: expected a sequence of (N, 3) float64 arrays")
    })?;
    let mut sets = Vec::new();
    for (i, item) in iter.enumerate() {
        let item = item?;
        let name = format!("point_sets[{i}]");
        let arr: PyReadonlyArray2<'py, f64> = item.extract().map_err(|_| {
            PyValueError::new_err(format!("{name}: expected an (N, 3) float64 numpy array"))
        })?;
        sets.push(points_from_array(&arr, &name)?);
    }
    let p = params(volume_tolerance, up, symmetry);
    let boxes = detach(py, "fit_obb_batch", || obb::fit_obb_batch(&sets, &p))?;
    let n = boxes.len();
    let centers: Vec<f64> = boxes
        .iter()
        .flat_map(|b| [b.center.x, b.center.y, b.center.z])
        .collect();
    let axes: Vec<f64> = boxes.iter().flat_map(axes_flat).collect();
    let half: Vec<f64> = boxes
        .iter()
        .flat_map(|b| [b.half_extents.x, b.half_extents.y, b.half_extents.z])
        .collect();
    Ok((
        array2(py, centers, n, 3),
        array3(py, axes, (n, 3, 3)),
        array2(py, half, n, 3),
    ))
}

/// Register this module's functions on `kinmo._core`.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(fit_obb, m)?)?;
    m.add_function(wrap_pyfunction!(fit_obb_batch, m)?)?;
    Ok(())
}
