//! Bindings of `kinmo_geometry::mesh`: `load_obj`, `load_objs`.

use kinmo_geometry::mesh::{self, TriMesh};
use numpy::PyArray2;
use pyo3::prelude::*;
use pyo3::types::PyList;

use crate::convert::{array2, faces_to_array};
use crate::errors::detach;

type MeshArrays<'py> = (Bound<'py, PyArray2<f64>>, Bound<'py, PyArray2<i64>>);

/// `(vertices (V, 3) float64, faces (F, 3) int64)` of a mesh, moving the vertex buffer.
fn mesh_to_arrays(py: Python<'_>, m: TriMesh) -> MeshArrays<'_> {
    let (vertices, faces) = m.into_parts();
    let n = vertices.len();
    let flat: Vec<f64> = vertices.iter().flat_map(|p| [p.x, p.y, p.z]).collect();
    (array2(py, flat, n, 3), faces_to_array(py, &faces))
}

/// Read a Wavefront OBJ file as one triangle mesh.
///
/// Triangulated, all objects/groups merged, materials ignored.
/// Returns `(vertices (V, 3) float64, faces (F, 3) int64)`; `OSError` naming the file
/// when it is missing, unreadable, larger than `max_bytes` or malformed.
#[pyfunction]
#[pyo3(signature = (path, max_bytes = mesh::MAX_OBJ_BYTES))]
fn load_obj(py: Python<'_>, path: std::path::PathBuf, max_bytes: u64) -> PyResult<MeshArrays<'_>> {
    let m = detach(py, "load_obj", || mesh::load_obj_bounded(&path, max_bytes))?;
    Ok(mesh_to_arrays(py, m))
}

/// Read many OBJ files in parallel; a list of `(vertices, faces)` in input order.
///
/// The first failing file (in input order) raises `OSError` naming it.
#[pyfunction]
#[pyo3(signature = (paths, max_bytes = mesh::MAX_OBJ_BYTES))]
fn load_objs(
    py: Python<'_>,
    paths: Vec<std::path::PathBuf>,
    max_bytes: u64,
) -> PyResult<Bound<'_, PyList>> {
    let meshes = detach(py, "load_objs", || {
        mesh::load_objs_bounded(&paths, max_bytes)
    })?;
    let items: Vec<MeshArrays<'_>> = meshes.into_iter().map(|m| mesh_to_arrays(py, m)).collect();
    PyList::new(py, items)
}

/// Register this module's functions on `kinmo._core`.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(load_obj, m)?)?;
    m.add_function(wrap_pyfunction!(load_objs, m)?)?;
    Ok(())
}
