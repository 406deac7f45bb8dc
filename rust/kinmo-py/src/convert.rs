//! Shared numpy -> Rust conversion and input validation for ALL bindings of `kinmo._core`
//! (mesh, sampling, obb, contact, interaction, motion). Reuse these helpers instead of ad-hoc
//! checks, so every function reports bad input the same way: a `ValueError` whose message
//! starts with the argument name (`"vertices: expected shape (N, 3), got (4,)"`), or a
//! `TypeError` when an argument is not a numpy array of the right dtype.
//!
//! Arrays are accepted with any number of dimensions (`PyReadonlyArray<T, D>` for any `D`, so
//! signatures may use `PyReadonlyArrayDyn` to turn a wrong `ndim` into a clear shape error
//! instead of pyo3's generic conversion error) and any strides (non-contiguous arrays are
//! copied in logical order). All checks run with the GIL held, before the pure-Rust work.

use kinmo_geometry::mesh::TriMesh;
use kinmo_geometry::GeometryError;
use nalgebra::Point3;
use numpy::ndarray::Dimension;
use numpy::{Element, PyArray2, PyReadonlyArray, PyReadonlyArrayDyn, PyUntypedArrayMethods};
use pyo3::exceptions::PyTypeError;
use pyo3::prelude::*;

use crate::errors::to_py;

/// Format a shape as Python prints it: `(4,)`, `(5, 3)`.
pub fn shape_str(shape: &[usize]) -> String {
    match shape {
        [n] => format!("({n},)"),
        _ => format!(
            "({})",
            shape
                .iter()
                .map(|d| d.to_string())
                .collect::<Vec<_>>()
                .join(", ")
        ),
    }
}

/// A `ValueError` for a wrong shape: `"{what}: expected shape {expected}, got (..)"`.
pub fn shape_error(what: &str, expected: &str, got: &[usize]) -> PyErr {
    to_py(GeometryError::Shape {
        what: what.to_string(),
        expected: expected.to_string(),
        got: shape_str(got),
    })
}

/// Copy the values of an array in logical (C) order, whatever its strides.
fn flat_values<T: Element + Copy, D: Dimension>(arr: &PyReadonlyArray<'_, T, D>) -> Vec<T> {
    match arr.as_slice() {
        Ok(s) => s.to_vec(),
        Err(_) => arr.as_array().iter().copied().collect(),
    }
}

/// Points of an `(N, 3) float64` array (N may be 0), checked finite.
///
/// # Errors
/// `ValueError` naming `what`: wrong shape, or the flat index of the first NaN / inf.
pub fn points_from_array<D: Dimension>(
    arr: &PyReadonlyArray<'_, f64, D>,
    what: &str,
) -> PyResult<Vec<Point3<f64>>> {
    let shape = arr.shape();
    if shape.len() != 2 || shape[1] != 3 {
        return Err(shape_error(what, "(N, 3)", shape));
    }
    let flat = flat_values(arr);
    if let Some(i) = flat.iter().position(|x| !x.is_finite()) {
        return Err(to_py(GeometryError::NonFinite {
            what: what.to_string(),
            index: i,
        }));
    }
    Ok(flat
        .chunks_exact(3)
        .map(|c| Point3::new(c[0], c[1], c[2]))
        .collect())
}

/// Like [`points_from_array`], and at least one point.
///
/// # Errors
/// Those of [`points_from_array`], and a `ValueError` `"{what}: empty (0 points)"`.
pub fn nonempty_points_from_array<D: Dimension>(
    arr: &PyReadonlyArray<'_, f64, D>,
    what: &str,
) -> PyResult<Vec<Point3<f64>>> {
    let pts = points_from_array(arr, what)?;
    if pts.is_empty() {
        return Err(to_py(GeometryError::Degenerate(format!(
            "{what}: empty (0 points)"
        ))));
    }
    Ok(pts)
}

/// Triangles of an `(F, 3) int64` array (F may be 0), each index in `0..n_vertices`.
///
/// # Errors
/// `ValueError` naming `what`: wrong shape, or the first face with a negative or
/// `>= n_vertices` index (face number and offending index in the message).
pub fn faces_from_array<D: Dimension>(
    arr: &PyReadonlyArray<'_, i64, D>,
    n_vertices: usize,
    what: &str,
) -> PyResult<Vec<[u32; 3]>> {
    let shape = arr.shape();
    if shape.len() != 2 || shape[1] != 3 {
        return Err(shape_error(what, "(F, 3)", shape));
    }
    let flat = flat_values(arr);
    let mut faces = Vec::with_capacity(flat.len() / 3);
    for (f, c) in flat.chunks_exact(3).enumerate() {
        let mut tri = [0u32; 3];
        for (slot, &v) in tri.iter_mut().zip(c) {
            if v < 0 || v as u64 >= n_vertices as u64 {
                return Err(to_py(GeometryError::IndexOutOfRange {
                    what: what.to_string(),
                    face: f,
                    vertex: v,
                    n_vertices,
                }));
            }
            // In range of a vertex count that fits memory; vertex counts above u32 are refused
            // by `mesh_from_arrays`.
            *slot = v as u32;
        }
        faces.push(tri);
    }
    Ok(faces)
}

/// A validated [`TriMesh`] from `(V, 3) float64` vertices and `(F, 3) int64` faces.
///
/// Empty meshes are accepted here (sampling refuses them with its own message).
/// `what` prefixes the argument names, e.g. `"meshes[3]"` gives `"meshes[3].vertices"`;
/// pass `""` for plain `vertices` / `faces`.
///
/// # Errors
/// Those of [`points_from_array`] and [`faces_from_array`], and a `ValueError` for more than
/// 2^32 - 1 vertices.
pub fn mesh_from_arrays<D1: Dimension, D2: Dimension>(
    vertices: &PyReadonlyArray<'_, f64, D1>,
    faces: &PyReadonlyArray<'_, i64, D2>,
    what: &str,
) -> PyResult<TriMesh> {
    let (vn, fname) = if what.is_empty() {
        ("vertices".to_string(), "faces".to_string())
    } else {
        (format!("{what}.vertices"), format!("{what}.faces"))
    };
    let v = points_from_array(vertices, &vn)?;
    if v.len() > u32::MAX as usize {
        return Err(to_py(GeometryError::Invalid(format!(
            "{vn}: {} vertices, at most {} supported",
            v.len(),
            u32::MAX
        ))));
    }
    let f = faces_from_array(faces, v.len(), &fname)?;
    Ok(TriMesh {
        vertices: v,
        faces: f,
    })
}

/// Extract a float64 numpy array (any ndim) from a Python object, `TypeError` naming `what`.
pub fn f64_array<'py>(obj: &Bound<'py, PyAny>, what: &str) -> PyResult<PyReadonlyArrayDyn<'py, f64>> {
    obj.extract::<PyReadonlyArrayDyn<'py, f64>>().map_err(|_| {
        PyTypeError::new_err(format!(
            "{what}: expected a float64 numpy array, got {}",
            type_desc(obj)
        ))
    })
}

/// Extract an int64 numpy array (any ndim) from a Python object, `TypeError` naming `what`.
pub fn i64_array<'py>(obj: &Bound<'py, PyAny>, what: &str) -> PyResult<PyReadonlyArrayDyn<'py, i64>> {
    obj.extract::<PyReadonlyArrayDyn<'py, i64>>().map_err(|_| {
        PyTypeError::new_err(format!(
            "{what}: expected an int64 numpy array, got {}",
            type_desc(obj)
        ))
    })
}

fn type_desc(obj: &Bound<'_, PyAny>) -> String {
    let tname = obj
        .get_type()
        .name()
        .map(|n| n.to_string())
        .unwrap_or_else(|_| "object".to_string());
    match obj.getattr("dtype") {
        Ok(dt) => format!("{tname} of dtype {dt}"),
        Err(_) => tname,
    }
}

/// The `(V, F)` meshes of a Python sequence of `(vertices (V, 3) float64, faces (F, 3) int64)`
/// pairs, each validated like [`mesh_from_arrays`] with names `"{what}[i].vertices"`.
///
/// # Errors
/// `TypeError` when `meshes` is not iterable, an item is not a pair or holds arrays of the
/// wrong dtype; `ValueError` for shapes, non-finite values and face indices (naming the
/// mesh index).
pub fn meshes_from_list(meshes: &Bound<'_, PyAny>, what: &str) -> PyResult<Vec<TriMesh>> {
    let mut out = Vec::new();
    for (i, item) in meshes
        .try_iter()
        .map_err(|_| PyTypeError::new_err(format!("{what}: expected a sequence of (vertices, faces) pairs")))?
        .enumerate()
    {
        let item = item?;
        let name = format!("{what}[{i}]");
        let (v, f): (Bound<'_, PyAny>, Bound<'_, PyAny>) = item.extract().map_err(|_| {
            PyTypeError::new_err(format!("{name}: expected a (vertices, faces) pair"))
        })?;
        let v = f64_array(&v, &format!("{name}.vertices"))?;
        let f = i64_array(&f, &format!("{name}.faces"))?;
        out.push(mesh_from_arrays(&v, &f, &name)?);
    }
    Ok(out)
}

/// The point sets of a Python sequence of `(N_i, 3) float64` arrays, named `"{what}[i]"` in
/// errors (empty sets are accepted; check emptiness yourself if it matters).
///
/// # Errors
/// `TypeError` for a non-sequence or a non-float64 item, `ValueError` for shapes and
/// non-finite values.
pub fn point_sets_from_list(sets: &Bound<'_, PyAny>, what: &str) -> PyResult<Vec<Vec<Point3<f64>>>> {
    let mut out = Vec::new();
    for (i, item) in sets
        .try_iter()
        .map_err(|_| PyTypeError::new_err(format!("{what}: expected a sequence of (N, 3) arrays")))?
        .enumerate()
    {
        let name = format!("{what}[{i}]");
        let arr = f64_array(&item?, &name)?;
        out.push(points_from_array(&arr, &name)?);
    }
    Ok(out)
}

/// The finite values of a 1-D float64 array, of length `len` when given.
///
/// # Errors
/// `ValueError` naming `what`: not 1-D, wrong length, or the index of the first NaN / inf.
pub fn vector_from_array<D: Dimension>(
    arr: &PyReadonlyArray<'_, f64, D>,
    len: Option<usize>,
    what: &str,
) -> PyResult<Vec<f64>> {
    let shape = arr.shape();
    let ok = shape.len() == 1 && len.is_none_or(|n| shape[0] == n);
    if !ok {
        let expected = match len {
            Some(n) => format!("({n},)"),
            None => "(N,)".to_string(),
        };
        return Err(shape_error(what, &expected, shape));
    }
    let flat = flat_values(arr);
    if let Some(i) = flat.iter().position(|x| !x.is_finite()) {
        return Err(to_py(GeometryError::NonFinite {
            what: what.to_string(),
            index: i,
        }));
    }
    Ok(flat)
}

/// A finite float scalar argument.
///
/// # Errors
/// `ValueError` `"{what}: non-finite value at index 0"` for NaN / inf.
pub fn finite_scalar(x: f64, what: &str) -> PyResult<f64> {
    if x.is_finite() {
        Ok(x)
    } else {
        Err(to_py(GeometryError::NonFinite {
            what: what.to_string(),
            index: 0,
        }))
    }
}

/// Points as a new `(N, 3) float64` numpy array.
pub fn points_to_pyarray<'py>(py: Python<'py>, points: &[Point3<f64>]) -> Bound<'py, PyArray2<f64>> {
    let flat: Vec<f64> = points.iter().flat_map(|p| [p.x, p.y, p.z]).collect();
    flat_to_pyarray2(py, flat, 3)
}

/// A row-major flat vector as a new `(len / cols, cols)` numpy array, without copying.
///
/// `flat.len()` must be a multiple of `cols` (an internal invariant; violations are truncated
/// rather than panicking).
pub fn flat_to_pyarray2<'py>(py: Python<'py>, mut flat: Vec<f64>, cols: usize) -> Bound<'py, PyArray2<f64>> {
    let cols = cols.max(1);
    let rows = flat.len() / cols;
    flat.truncate(rows * cols);
    let arr = numpy::ndarray::Array2::from_shape_vec((rows, cols), flat)
        .unwrap_or_else(|_| numpy::ndarray::Array2::zeros((0, cols)));
    numpy::IntoPyArray::into_pyarray(arr, py)
}
