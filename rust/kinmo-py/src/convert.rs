//! Shared numpy <-> Rust conversions of the bindings, with input validation.
//!
//! Every binding reads its arrays through these helpers, so shapes, finiteness and index
//! ranges are checked the same way everywhere and reported as `ValueError` naming the
//! argument (through [`crate::errors::to_py`]). Inputs may be non-contiguous (any strides);
//! C-contiguous arrays take a fast path (checked with ndarray's `as_slice`, which requires
//! standard layout: numpy's own `as_slice` also accepts Fortran order, in memory order).
//! Outputs are built from flat `Vec`s without copying, or allocated by numpy with
//! [`zeros`]. Every array a binding copies or creates is first checked against
//! [`MAX_VALUES`] by [`check_values`], the one size check of the bindings.

// Shared toolbox: not every helper is used by every binding module.
#![allow(dead_code)]

use kinmo_geometry::mesh::TriMesh;
use kinmo_geometry::GeometryError;
use nalgebra::{Point3, Vector3};
use numpy::ndarray::{Array1, Array2, Array3};
use numpy::{
    IntoPyArray, PyArray1, PyArray2, PyArray3, PyReadonlyArray1, PyReadonlyArray2,
    PyReadonlyArray3, PyUntypedArrayMethods,
};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

use crate::errors::to_py;

/// Most values (array elements) of one array that a binding copies or creates:
/// `2**30` (8 GiB of float64). Checked before any copy or allocation, so a huge request
/// (`n = 2**40`, a broadcast view of `2**31` rows) is a `ValueError` naming the argument,
/// never an aborted process or a `PanicException`.
pub const MAX_VALUES: usize = 1 << 30;

/// Check that an array of shape `dims` (requested by argument `what`) has at most
/// [`MAX_VALUES`] values; returns the number of values.
///
/// The one size check of the bindings: every input copy and every output allocation goes
/// through it.
///
/// # Errors
/// `ValueError` `"{what}: an array of shape (..) has N values, more than the limit of
/// 1073741824 of kinmo._core"`.
pub fn check_values(what: &str, dims: &[usize]) -> PyResult<usize> {
    let n = dims
        .iter()
        .try_fold(1u128, |acc, &d| acc.checked_mul(d as u128));
    match n {
        Some(n) if n <= MAX_VALUES as u128 => Ok(n as usize),
        _ => {
            let shape: Vec<String> = dims.iter().map(usize::to_string).collect();
            let count = n.map_or_else(|| "more than 2**128".to_string(), |n| n.to_string());
            Err(PyValueError::new_err(format!(
                "{what}: an array of shape ({}) has {count} values, more than the limit of \
                 {MAX_VALUES} (8 GiB of float64) of kinmo._core",
                shape.join(", ")
            )))
        }
    }
}

/// A zero-filled numpy array of shape `dims`, checked with [`check_values`] (naming
/// `what`) and allocated by numpy itself (`numpy.zeros`), so a failed allocation is a
/// `MemoryError`, and large arrays get numpy's transparent-huge-page advice (cheap
/// first-touch page faults when filled in place).
///
/// # Errors
/// `ValueError` from [`check_values`]; `MemoryError` from numpy.
pub fn zeros<'py, T: numpy::Element, D: numpy::ndarray::Dimension>(
    py: Python<'py>,
    dims: &[usize],
    what: &str,
) -> PyResult<Bound<'py, numpy::PyArray<T, D>>> {
    check_values(what, dims)?;
    let np = py.import("numpy")?;
    let shape = pyo3::types::PyTuple::new(py, dims)?;
    let arr = np.getattr("zeros")?.call1((shape, T::get_dtype(py)))?;
    Ok(arr.cast_into::<numpy::PyArray<T, D>>()?)
}

/// Shape error `what: expected shape {expected}, got (a, b, ...)`.
fn shape_error(what: &str, expected: &str, got: &[usize]) -> PyErr {
    let dims: Vec<String> = got.iter().map(|d| d.to_string()).collect();
    let got = if dims.len() == 1 {
        format!("({},)", dims[0])
    } else {
        format!("({})", dims.join(", "))
    };
    to_py(GeometryError::Shape {
        what: what.to_string(),
        expected: expected.to_string(),
        got,
    })
}

/// Read an `(N, 3)` float64 array as points, checking the shape and finiteness.
///
/// `N = 0` is accepted; callers that need points check emptiness themselves.
///
/// # Errors
/// `ValueError` naming `what`: wrong shape, or the flat index of the first NaN/inf.
pub fn points_from_array(
    arr: &PyReadonlyArray2<'_, f64>,
    what: &str,
) -> PyResult<Vec<Point3<f64>>> {
    let shape = arr.shape();
    if shape[1] != 3 {
        return Err(shape_error(what, "(N, 3)", shape));
    }
    check_values(what, shape)?;
    let view = arr.as_array();
    let owned;
    let flat: &[f64] = match view.as_slice() {
        Some(s) => s,
        None => {
            owned = view.iter().copied().collect::<Vec<f64>>();
            &owned
        }
    };
    if let Some(index) = flat.iter().position(|x| !x.is_finite()) {
        return Err(to_py(GeometryError::NonFinite {
            what: what.to_string(),
            index,
        }));
    }
    Ok(flat
        .chunks_exact(3)
        .map(|c| Point3::new(c[0], c[1], c[2]))
        .collect())
}

/// Check `1 <= value < 2**64` (a Python int of any size): `ValueError` "`{what}` must be
/// >= 1, got `{value}`" otherwise (`what` names the argument, e.g. `"k:"`).
pub fn positive(value: i128, what: &str) -> PyResult<usize> {
    usize::try_from(value)
        .ok()
        .filter(|&v| v >= 1)
        .ok_or_else(|| PyValueError::new_err(format!("{what} must be >= 1, got {value}")))
}

/// Read a `(B, N, 3)` float32 array as `B` clouds of `N` points, row-major
/// (`points[b * N + i]`), checking the shape and size. Finiteness is checked by the
/// geometry functions that read them (`kinmo_geometry::pointnet`).
///
/// # Errors
/// `ValueError` naming `what`: wrong shape, or more than [`MAX_VALUES`] values.
pub fn clouds_from_array(
    arr: &PyReadonlyArray3<'_, f32>,
    what: &str,
) -> PyResult<(Vec<[f32; 3]>, usize, usize)> {
    let shape = arr.shape();
    if shape[2] != 3 {
        return Err(shape_error(what, "(B, N, 3)", shape));
    }
    check_values(what, shape)?;
    let view = arr.as_array();
    let points = match view.as_slice() {
        Some(s) => s
            .chunks_exact(3)
            .map(|c| [c[0], c[1], c[2]])
            .collect::<Vec<_>>(),
        None => {
            let flat: Vec<f32> = view.iter().copied().collect();
            flat.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect()
        }
    };
    Ok((points, shape[0], shape[1]))
}

/// Read an `(F, 3)` int64 array as triangles indexing `n_vertices` vertices.
///
/// # Errors
/// `ValueError` naming `what`: wrong shape, or a negative / too large index (naming the
/// face and the index).
pub fn faces_from_array(
    arr: &PyReadonlyArray2<'_, i64>,
    n_vertices: usize,
    what: &str,
) -> PyResult<Vec<[u32; 3]>> {
    let shape = arr.shape();
    if shape[1] != 3 {
        return Err(shape_error(what, "(F, 3)", shape));
    }
    check_values(what, shape)?;
    let view = arr.as_array();
    let owned;
    let flat: &[i64] = match view.as_slice() {
        Some(s) => s,
        None => {
            owned = view.iter().copied().collect::<Vec<i64>>();
            &owned
        }
    };
    let mut faces = Vec::with_capacity(flat.len() / 3);
    for (face, c) in flat.chunks_exact(3).enumerate() {
        let mut tri = [0u32; 3];
        for (slot, &v) in tri.iter_mut().zip(c) {
            *slot = match u32::try_from(v) {
                Ok(u) if (u as usize) < n_vertices => u,
                _ => {
                    return Err(to_py(GeometryError::IndexOutOfRange {
                        what: what.to_string(),
                        face,
                        vertex: v,
                        n_vertices,
                    }))
                }
            };
        }
        faces.push(tri);
    }
    Ok(faces)
}

/// Read `(C, 3)` float64 direction vectors, `C` fixed by `n_origins` (the lines' origins).
///
/// # Errors
/// `ValueError` naming `what`: wrong shape or length, or the flat index of a NaN/inf.
pub fn directions_from_array(
    arr: &PyReadonlyArray2<'_, f64>,
    n_origins: usize,
    what: &str,
) -> PyResult<Vec<Vector3<f64>>> {
    let d: Vec<Vector3<f64>> = points_from_array(arr, what)?
        .into_iter()
        .map(|p| p.coords)
        .collect();
    if d.len() != n_origins {
        return Err(to_py(GeometryError::Shape {
            what: what.to_string(),
            expected: format!("(C, 3) with C = {n_origins} (the number of origins)"),
            got: format!("({}, 3)", d.len()),
        }));
    }
    Ok(d)
}

/// Read a `(V, 3)` float64 / `(F, 3)` int64 pair as a validated [`TriMesh`].
///
/// Error messages name `"{what} vertices"` or `"{what} faces"`. Empty meshes are accepted;
/// callers decide whether they are an error.
///
/// # Errors
/// `ValueError` as in [`points_from_array`] and [`faces_from_array`].
pub fn mesh_from_arrays(
    vertices: &PyReadonlyArray2<'_, f64>,
    faces: &PyReadonlyArray2<'_, i64>,
    what: &str,
) -> PyResult<TriMesh> {
    let v = points_from_array(vertices, &format!("{what} vertices"))?;
    let f = faces_from_array(faces, v.len(), &format!("{what} faces"))?;
    TriMesh::new(v, f, what).map_err(to_py)
}

/// Read a Python sequence of `(vertices (V, 3) float64, faces (F, 3) int64)` pairs.
///
/// Mesh `i` is named `"{what}[i]"` in error messages.
///
/// # Errors
/// `ValueError` when `obj` is not a sequence, an item is not such a pair of arrays, or a
/// mesh is invalid.
pub fn meshes_from_list(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<Vec<TriMesh>> {
    let iter = obj.try_iter().map_err(|_| {
        PyValueError::new_err(format!(
            "{what}: expected a sequence of (vertices, faces) pairs"
        ))
    })?;
    let mut meshes = Vec::new();
    for (i, item) in iter.enumerate() {
        let item = item?;
        let name = format!("{what}[{i}]");
        let (v, f): (PyReadonlyArray2<'_, f64>, PyReadonlyArray2<'_, i64>) =
            item.extract().map_err(|_| {
                PyValueError::new_err(format!(
                    "{name}: expected a (vertices (V, 3) float64, faces (F, 3) int64) pair \
                     of C-compatible numpy arrays"
                ))
            })?;
        meshes.push(mesh_from_arrays(&v, &f, &name)?);
    }
    Ok(meshes)
}

/// Read a 1-D float64 array of length `len` (when given), checking finiteness.
///
/// # Errors
/// `ValueError` naming `what`: wrong length, or the index of the first NaN/inf.
pub fn floats_from_array(
    arr: &PyReadonlyArray1<'_, f64>,
    len: Option<usize>,
    what: &str,
) -> PyResult<Vec<f64>> {
    check_values(what, arr.shape())?;
    let view = arr.as_array();
    let values: Vec<f64> = match view.as_slice() {
        Some(s) => s.to_vec(),
        None => view.iter().copied().collect(),
    };
    if let Some(n) = len {
        if values.len() != n {
            return Err(shape_error(what, &format!("({n},)"), &[values.len()]));
        }
    }
    if let Some(index) = values.iter().position(|x| !x.is_finite()) {
        return Err(to_py(GeometryError::NonFinite {
            what: what.to_string(),
            index,
        }));
    }
    Ok(values)
}

/// Points as an `(N, 3)` float64 array.
pub fn points_to_array<'py>(py: Python<'py>, points: &[Point3<f64>]) -> Bound<'py, PyArray2<f64>> {
    let flat: Vec<f64> = points.iter().flat_map(|p| [p.x, p.y, p.z]).collect();
    // The length is 3 * N by construction, so the reshape cannot fail.
    array2(py, flat, points.len(), 3)
}

/// Triangles as an `(F, 3)` int64 array.
pub fn faces_to_array<'py>(py: Python<'py>, faces: &[[u32; 3]]) -> Bound<'py, PyArray2<i64>> {
    let flat: Vec<i64> = faces.iter().flatten().map(|&i| i64::from(i)).collect();
    array2(py, flat, faces.len(), 3)
}

/// A flat row-major buffer as a `(rows, cols)` array, without copying.
///
/// # Panics
/// If `flat.len() != rows * cols` (a bug in the caller, never user data).
pub fn array2<'py, T: numpy::Element>(
    py: Python<'py>,
    flat: Vec<T>,
    rows: usize,
    cols: usize,
) -> Bound<'py, PyArray2<T>> {
    #[allow(clippy::expect_used)]
    Array2::from_shape_vec((rows, cols), flat)
        .expect("array2: buffer length matches the shape")
        .into_pyarray(py)
}

/// A flat row-major buffer as an `(a, b, c)` array, without copying.
///
/// # Panics
/// If `flat.len() != a * b * c` (a bug in the caller, never user data).
pub fn array3<'py, T: numpy::Element>(
    py: Python<'py>,
    flat: Vec<T>,
    shape: (usize, usize, usize),
) -> Bound<'py, PyArray3<T>> {
    #[allow(clippy::expect_used)]
    Array3::from_shape_vec(shape, flat)
        .expect("array3: buffer length matches the shape")
        .into_pyarray(py)
}

/// A `Vec` as a 1-D array, without copying.
pub fn array1<'py, T: numpy::Element>(py: Python<'py>, values: Vec<T>) -> Bound<'py, PyArray1<T>> {
    Array1::from_vec(values).into_pyarray(py)
}
