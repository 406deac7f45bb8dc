//! Bindings of `kinmo_geometry::pointnet`: `farthest_point_sample`, `ball_query`,
//! `k_nearest` (batched PointNet++ neighbourhoods of float32 clouds).

use kinmo_geometry::pointnet;
use numpy::{PyArray2, PyArray3, PyReadonlyArray3};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

use crate::convert::{array2, array3, check_values, clouds_from_array, positive};
use crate::errors::detach;

/// `(indices (B, N, k) int64, distances (B, N, k) float32)`.
type Neighbours<'py> = (Bound<'py, PyArray3<i64>>, Bound<'py, PyArray3<f32>>);

/// Check that two batches have the same size.
fn same_batch(a: usize, b: usize, what: &str) -> PyResult<()> {
    if a != b {
        return Err(PyValueError::new_err(format!(
            "{what}: batch size {b} differs from the points' {a}"
        )));
    }
    Ok(())
}

/// Farthest point sampling of `m` points of each cloud of `points (B, N, 3)` float32,
/// starting at point 0: `(B, m)` int64 indices, in the order chosen. Parallel over the
/// batch; `ValueError` for a bad shape, `m` outside `[1, N]` or a NaN/inf coordinate.
#[pyfunction]
fn farthest_point_sample<'py>(
    py: Python<'py>,
    points: PyReadonlyArray3<'py, f32>,
    m: i128,
) -> PyResult<Bound<'py, PyArray2<i64>>> {
    let (p, b, n) = clouds_from_array(&points, "points")?;
    // m <= N is checked by the core, with the same message
    let m = positive(m, "m:")?;
    let len = check_values("m", &[b, m])?;
    let out = detach(py, "farthest_point_sample", || {
        let mut out = vec![0i64; len];
        pointnet::farthest_point_sample_batch(&p, b, n, &mut out)?;
        Ok(out)
    })?;
    Ok(array2(py, out, b, m))
}

/// Ball query: for each centre of `centers (B, M, 3)`, the first `k` points of
/// `points (B, N, 3)` (index order) within `radius`, padded with the first, or the nearest
/// point `k` times when none is within it: `(B, M, k)` int64. Float32 inputs; parallel over
/// the batch; `ValueError` for bad shapes, `k < 1`, a radius not finite and positive, or a
/// NaN/inf coordinate.
#[pyfunction]
fn ball_query<'py>(
    py: Python<'py>,
    points: PyReadonlyArray3<'py, f32>,
    centers: PyReadonlyArray3<'py, f32>,
    radius: f64,
    k: i128,
) -> PyResult<Bound<'py, PyArray3<i64>>> {
    let (p, b, n) = clouds_from_array(&points, "points")?;
    let (c, bc, m) = clouds_from_array(&centers, "centers")?;
    same_batch(b, bc, "centers")?;
    let k = positive(k, "k:")?;
    let len = check_values("k", &[b, m, k])?;
    let out = detach(py, "ball_query", || {
        let mut out = vec![0i64; len];
        pointnet::ball_query_batch(&p, &c, b, n, m, radius, k, &mut out)?;
        Ok(out)
    })?;
    Ok(array3(py, out, (b, m, k)))
}

/// The `k` nearest points of `points (B, M, 3)` to each query of `queries (B, N, 3)`, by
/// distance then index: `(indices (B, N, k) int64, distances (B, N, k) float32)`. Float32
/// inputs; parallel over the batch; `ValueError` for bad shapes, `k` outside `[1, M]` or a
/// NaN/inf coordinate.
#[pyfunction]
fn k_nearest<'py>(
    py: Python<'py>,
    points: PyReadonlyArray3<'py, f32>,
    queries: PyReadonlyArray3<'py, f32>,
    k: i128,
) -> PyResult<Neighbours<'py>> {
    let (p, b, m) = clouds_from_array(&points, "points")?;
    let (q, bq, n) = clouds_from_array(&queries, "queries")?;
    same_batch(b, bq, "queries")?;
    let k = positive(k, "k:")?;
    let len = check_values("k", &[b, n, k])?;
    let (idx, dist) = detach(py, "k_nearest", || {
        let mut idx = vec![0i64; len];
        let mut dist = vec![0f32; len];
        pointnet::k_nearest_batch(&p, &q, b, m, n, k, &mut idx, &mut dist)?;
        Ok((idx, dist))
    })?;
    Ok((array3(py, idx, (b, n, k)), array3(py, dist, (b, n, k))))
}

/// Register this module's functions on `kinmo._core`.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(farthest_point_sample, m)?)?;
    m.add_function(wrap_pyfunction!(ball_query, m)?)?;
    m.add_function(wrap_pyfunction!(k_nearest, m)?)?;
    Ok(())
}
