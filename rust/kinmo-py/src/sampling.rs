//! Bindings of `kinmo_geometry::sampling`: `sample_surface`, `sample_surface_groups`.

use kinmo_geometry::sampling::{self, AreaSampler};
use numpy::{PyArray1, PyArray2, PyArray3, PyArrayMethods, PyReadonlyArray2};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

use crate::convert::{mesh_from_arrays, meshes_from_list, positive, zeros};
use crate::errors::detach;

/// `(points (n, 3) float64, face_index (n,) int64)`.
type Samples<'py> = (Bound<'py, PyArray2<f64>>, Bound<'py, PyArray1<i64>>);

/// Check `0 <= seed < 2**64`.
fn seed(seed: i128) -> PyResult<u64> {
    u64::try_from(seed)
        .map_err(|_| PyValueError::new_err(format!("seed: must be in [0, 2**64), got {seed}")))
}

/// Sample `n` points uniformly by area on a triangle mesh.
///
/// Returns `(points (n, 3) float64, face_index (n,) int64)`; `ValueError` for bad arrays,
/// `n < 1`, a seed outside `[0, 2**64)` or zero total area.
#[pyfunction]
fn sample_surface<'py>(
    py: Python<'py>,
    vertices: PyReadonlyArray2<'py, f64>,
    faces: PyReadonlyArray2<'py, i64>,
    n: i128,
    seed: i128,
) -> PyResult<Samples<'py>> {
    let n = positive(n, "n: the number of points")?;
    let seed = self::seed(seed)?;
    let mesh = mesh_from_arrays(&vertices, &faces, "mesh")?;
    // Outputs are numpy arrays filled in place (no intermediate buffers).
    let points: Bound<'py, PyArray2<f64>> = zeros(py, &[n, 3], "n")?;
    let face_index: Bound<'py, PyArray1<i64>> = zeros(py, &[n], "n")?;
    {
        let mut p = points.readwrite();
        let mut f = face_index.readwrite();
        let (p, f) = (p.as_slice_mut()?, f.as_slice_mut()?);
        detach(py, "sample_surface", || {
            let sampler = AreaSampler::new(&[&mesh])?;
            sampler.fill(seed, p, Some(f));
            Ok(())
        })?;
    }
    Ok((points, face_index))
}

/// Sample `n` points on the union of each group of meshes, in parallel over groups.
///
/// Returns `(G, n, 3) float64`; group `g` uses a seed derived from `(seed, g)`.
#[pyfunction]
fn sample_surface_groups<'py>(
    py: Python<'py>,
    meshes: &Bound<'py, PyAny>,
    groups: Vec<Vec<i128>>,
    n: i128,
    seed: i128,
) -> PyResult<Bound<'py, PyArray3<f64>>> {
    let n = positive(n, "n: the number of points")?;
    let seed = self::seed(seed)?;
    let meshes = meshes_from_list(meshes, "meshes")?;
    let groups = groups
        .iter()
        .enumerate()
        .map(|(g, members)| {
            members
                .iter()
                .map(|&i| {
                    usize::try_from(i)
                        .ok()
                        .filter(|&i| i < meshes.len())
                        .ok_or_else(|| {
                            PyValueError::new_err(format!(
                                "groups[{g}] references mesh {i}, but there are only {} meshes",
                                meshes.len()
                            ))
                        })
                })
                .collect::<PyResult<Vec<usize>>>()
        })
        .collect::<PyResult<Vec<_>>>()?;
    // Filled in place: numpy's allocator advises huge pages for large arrays, which makes
    // first-touch page faults of a large output far cheaper than a fresh Rust buffer.
    let out: Bound<'py, PyArray3<f64>> = zeros(py, &[groups.len(), n, 3], "n")?;
    {
        let mut rw = out.readwrite();
        let buf = rw.as_slice_mut()?;
        detach(py, "sample_surface_groups", || {
            sampling::sample_surface_groups_into(&meshes, &groups, n, seed, buf)
        })?;
    }
    Ok(out)
}

/// Register this module's functions on `kinmo._core`.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(sample_surface, m)?)?;
    m.add_function(wrap_pyfunction!(sample_surface_groups, m)?)?;
    Ok(())
}
