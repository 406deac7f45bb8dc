//! Bindings of `kinmo_geometry::contact`: `contact_pairs`, `mesh_distance`.

use kinmo_geometry::contact;
use numpy::{PyArray1, PyArray2, PyReadonlyArray2};
use pyo3::prelude::*;

use crate::convert::{array1, array2, mesh_from_arrays, meshes_from_list};
use crate::errors::detach;

type PairsAndDistances<'py> = (Bound<'py, PyArray2<i64>>, Bound<'py, PyArray1<f64>>);

/// All pairs of meshes whose surfaces come within `tolerance` of each other.
///
/// `meshes`: sequence of `(vertices (V, 3) float64, faces (F, 3) int64)`; `tolerance`:
/// absolute distance, finite and >= 0. Returns `(pairs (K, 2) int64, distances (K,)
/// float64)`, pairs `i < j` sorted lexicographically, distances the exact minimum surface
/// distance of each pair. `ValueError` on bad shapes, non-finite values, indices out of
/// range or a bad tolerance.
#[pyfunction]
fn contact_pairs<'py>(
    py: Python<'py>,
    meshes: &Bound<'py, PyAny>,
    tolerance: f64,
) -> PyResult<PairsAndDistances<'py>> {
    let meshes = meshes_from_list(meshes, "meshes")?;
    let pairs = detach(py, "contact_pairs", || {
        contact::contact_pairs_of_meshes(&meshes, tolerance)
    })?;
    let flat: Vec<i64> = pairs
        .iter()
        .flat_map(|p| [p.i as i64, p.j as i64])
        .collect();
    let distances: Vec<f64> = pairs.iter().map(|p| p.distance).collect();
    Ok((array2(py, flat, pairs.len(), 2), array1(py, distances)))
}

/// Exact minimum distance between the surfaces of two triangle meshes (0 if they touch).
///
/// `ValueError` on bad arrays or a mesh without faces.
#[pyfunction]
#[pyo3(signature = (vertices_a, faces_a, vertices_b, faces_b))]
fn mesh_distance(
    py: Python<'_>,
    vertices_a: PyReadonlyArray2<'_, f64>,
    faces_a: PyReadonlyArray2<'_, i64>,
    vertices_b: PyReadonlyArray2<'_, f64>,
    faces_b: PyReadonlyArray2<'_, i64>,
) -> PyResult<f64> {
    let a = mesh_from_arrays(&vertices_a, &faces_a, "mesh_a")?;
    let b = mesh_from_arrays(&vertices_b, &faces_b, "mesh_b")?;
    detach(py, "mesh_distance", || {
        contact::mesh_distance_of_meshes(&a, &b)
    })
}

/// Register this module's functions on `kinmo._core`.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(contact_pairs, m)?)?;
    m.add_function(wrap_pyfunction!(mesh_distance, m)?)?;
    Ok(())
}
