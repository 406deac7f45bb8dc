//! Bindings of `kinmo_geometry::motion`: `motion_transforms`, `apply_motions`.

use kinmo_geometry::motion;
use nalgebra::{Point3, Vector3};
use numpy::{PyArray3, PyArrayMethods, PyReadonlyArray1, PyReadonlyArray2};
use pyo3::prelude::*;

use crate::convert::{
    array3, check_values, directions_from_array, floats_from_array, points_from_array, zeros,
};
use crate::errors::{detach, to_py};

/// The validated `(origins, directions, angles, translations)` of C candidates.
type Candidates = (Vec<Point3<f64>>, Vec<Vector3<f64>>, Vec<f64>, Vec<f64>);

fn candidates(
    origins: &PyReadonlyArray2<'_, f64>,
    directions: &PyReadonlyArray2<'_, f64>,
    angles: &PyReadonlyArray1<'_, f64>,
    translations: &PyReadonlyArray1<'_, f64>,
) -> PyResult<Candidates> {
    let o = points_from_array(origins, "origins")?;
    let c = o.len();
    let d = directions_from_array(directions, c, "directions")?;
    let a = floats_from_array(angles, Some(c), "angles")?;
    let t = floats_from_array(translations, Some(c), "translations")?;
    Ok((o, d, a, t))
}

/// Homogeneous `(C, 4, 4)` float64 matrices of C candidate motions (column vectors).
///
/// Rotation by `angles[c]` rad about the line `(origins[c], directions[c])` (right-hand
/// rule), then translation by `translations[c]` along the unit direction.
#[pyfunction]
fn motion_transforms<'py>(
    py: Python<'py>,
    origins: PyReadonlyArray2<'py, f64>,
    directions: PyReadonlyArray2<'py, f64>,
    angles: PyReadonlyArray1<'py, f64>,
    translations: PyReadonlyArray1<'py, f64>,
) -> PyResult<Bound<'py, PyArray3<f64>>> {
    let (o, d, a, t) = candidates(&origins, &directions, &angles, &translations)?;
    let c = o.len();
    check_values("origins", &[c, 4, 4])?;
    let flat = detach(py, "motion_transforms", || {
        motion::motion_transforms(&o, &d, &a, &t)
    })?;
    Ok(array3(py, flat, (c, 4, 4)))
}

/// Apply C candidate motions to `points (N, 3)`: `(C, N, 3)` float64, parallel.
///
/// The output is allocated by numpy (so it gets numpy's transparent-huge-page advice for
/// large arrays, which makes first-touch page faults far cheaper) and filled in place
/// with the GIL released.
#[pyfunction]
fn apply_motions<'py>(
    py: Python<'py>,
    points: PyReadonlyArray2<'py, f64>,
    origins: PyReadonlyArray2<'py, f64>,
    directions: PyReadonlyArray2<'py, f64>,
    angles: PyReadonlyArray1<'py, f64>,
    translations: PyReadonlyArray1<'py, f64>,
) -> PyResult<Bound<'py, PyArray3<f64>>> {
    let p = points_from_array(&points, "points")?;
    let (o, d, a, t) = candidates(&origins, &directions, &angles, &translations)?;
    let motions = motion::motions(&o, &d, &a, &t).map_err(to_py)?;
    let out: Bound<'py, PyArray3<f64>> =
        zeros(py, &[o.len(), p.len(), 3], "origins x points (output)")?;
    {
        let mut rw = out.readwrite();
        let buf = rw.as_slice_mut()?;
        detach(py, "apply_motions", || {
            motion::apply_motions_into(&motions, &p, buf)
        })?;
    }
    Ok(out)
}

/// Register this module's functions on `kinmo._core`.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(motion_transforms, m)?)?;
    m.add_function(wrap_pyfunction!(apply_motions, m)?)?;
    Ok(())
}
