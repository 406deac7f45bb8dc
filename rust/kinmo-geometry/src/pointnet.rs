//! PointNet++ neighbourhoods (Qi et al. NeurIPS 2017): farthest point sampling, ball query
//! and k nearest neighbours, for one point cloud or a batch of clouds.
//!
//! These are the index computations of PointNet++'s set abstraction (centres and their
//! groups) and feature propagation (the coarse points each point interpolates from). They
//! depend only on the coordinates, so a network can compute them for a whole batch before
//! its forward pass (`kinmo.ancsh.pointnet2`).
//!
//! Coordinates are `f32` (the network's precision), `[x, y, z]` per point. Batched functions
//! read row-major `(B, N, 3)` buffers, write row-major outputs and run in parallel over the
//! batch (rayon). Every result is deterministic and the same whatever the number of threads.
//!
//! Numerical rules (the reference semantics of the PyTorch implementation in
//! `kinmo.ancsh.pointnet2`):
//!
//! - **Farthest point sampling** starts at point 0. The distance of a point to the chosen set
//!   is kept in `f32`, each squared distance evaluated as `(dx * dx + dy * dy) + dz * dz` in
//!   `f32` (the order PyTorch uses), and the next centre is the *first* point of largest
//!   distance. The result is exactly PyTorch's on `f32` input.
//! - **Ball query** and **k nearest neighbours** compare squared distances evaluated in
//!   `f64` from the `f32` coordinates (no cancellation: `|p - c|²` term by term), against
//!   `radius²` in `f64`. A ball holds the first `k` points *in index order* within the
//!   radius; fewer than `k` are padded with the first; a centre with none at all gets its
//!   nearest point `k` times. Nearest neighbours are ordered by distance, then by index.
//!
//! Nearest neighbours search a `kiddo` k-d tree of each cloud, then test the points found with
//! the distance above, so they are exact, the same as a brute-force scan, at a fraction of its
//! cost. Ball query is PointNet++'s own scan in index order, stopping at the `k`-th point
//! inside; it allocates nothing per centre, where the tree search returns a new vector of
//! every point within the radius. On the 16-core machine of a GPU session the tree's ball
//! query of a paper-preset batch (16 clouds of 1024 points, radius 0.2) took 30 ms on one
//! thread and 81 ms on 16, the scan 23 ms and 2.2 ms (docs/results/benchmarks.md). On 2 cores
//! the scan is as fast as the tree or faster at every level.
//! Farthest point sampling is the plain `O(M N)` loop.

use std::num::NonZeroUsize;

use kiddo::immutable::float::kdtree::ImmutableKdTree;
use kiddo::SquaredEuclidean;
use rayon::prelude::*;

use crate::error::{GeometryError, Result};

/// Most neighbours [`ball_query`] and [`k_nearest`] return per centre or query.
pub const MAX_K: usize = 1 << 16;

/// One point: `[x, y, z]`.
pub type Point = [f32; 3];

fn check_finite(what: &str, points: &[Point]) -> Result<()> {
    match points.iter().flatten().position(|v: &f32| !v.is_finite()) {
        Some(index) => Err(GeometryError::NonFinite {
            what: what.to_string(),
            index,
        }),
        None => Ok(()),
    }
}

fn check_k(k: usize) -> Result<()> {
    if k == 0 || k > MAX_K {
        return Err(GeometryError::Invalid(format!(
            "k: the number of neighbours must be in [1, {MAX_K}], got {k}"
        )));
    }
    Ok(())
}

fn check_radius(radius: f64) -> Result<()> {
    if !(radius.is_finite() && radius > 0.0) {
        return Err(GeometryError::Invalid(format!(
            "radius: must be finite and > 0, got {radius}"
        )));
    }
    Ok(())
}

/// Squared distance in `f32`, `(dx * dx + dy * dy) + dz * dz` (PyTorch's order).
#[inline]
fn dist2_f32(a: &Point, b: &Point) -> f32 {
    let (dx, dy, dz) = (a[0] - b[0], a[1] - b[1], a[2] - b[2]);
    dx * dx + dy * dy + dz * dz
}

/// Squared distance in `f64` from `f32` coordinates.
#[inline]
fn dist2_f64(a: &Point, b: &Point) -> f64 {
    let dx = f64::from(a[0]) - f64::from(b[0]);
    let dy = f64::from(a[1]) - f64::from(b[1]);
    let dz = f64::from(a[2]) - f64::from(b[2]);
    dx * dx + dy * dy + dz * dz
}

fn fps_into(points: &[Point], out: &mut [i64]) {
    // structure of arrays, so that the distance update vectorises
    let xs: Vec<f32> = points.iter().map(|p| p[0]).collect();
    let ys: Vec<f32> = points.iter().map(|p| p[1]).collect();
    let zs: Vec<f32> = points.iter().map(|p| p[2]).collect();
    let mut dist = vec![f32::INFINITY; points.len()];
    let mut far = 0usize;
    for slot in out.iter_mut() {
        *slot = far as i64;
        let c = points[far];
        let mut best = f32::NEG_INFINITY;
        for (((d, x), y), z) in dist.iter_mut().zip(&xs).zip(&ys).zip(&zs) {
            let e = dist2_f32(&[*x, *y, *z], &c);
            *d = if e < *d { e } else { *d };
            best = if *d > best { *d } else { best };
        }
        // the first point of largest distance
        far = dist.iter().position(|&d| d == best).unwrap_or(0);
    }
}

/// Farthest point sampling of `m` of `points`, starting at point 0 (module rules).
///
/// Returns the indices of the chosen points, in the order chosen (`out[0] == 0`).
///
/// # Errors
/// `Degenerate` for no points, `Invalid` for `m == 0` or `m > points.len()`, `NonFinite`
/// for a NaN or infinite coordinate (flat index).
pub fn farthest_point_sample(points: &[Point], m: usize) -> Result<Vec<i64>> {
    let mut out = vec![0; m];
    farthest_point_sample_batch(points, 1, points.len(), &mut out)?;
    Ok(out)
}

/// [`farthest_point_sample`] of each cloud of a row-major `(B, N, 3)` batch, in parallel:
/// `out` is `(B, M)` and sets `M`.
///
/// # Errors
/// `Shape` when `points` is not `B * N` points or `out` not a multiple of `B`; otherwise as
/// [`farthest_point_sample`].
pub fn farthest_point_sample_batch(
    points: &[Point],
    b: usize,
    n: usize,
    out: &mut [i64],
) -> Result<()> {
    check_batch("points", points.len(), b, n)?;
    let m = per_item("out", out.len(), b)?;
    if b == 0 {
        return Ok(());
    }
    if n == 0 {
        return Err(GeometryError::Degenerate(
            "points: farthest point sampling needs at least one point".to_string(),
        ));
    }
    if m == 0 || m > n {
        return Err(GeometryError::Invalid(format!(
            "m: the number of samples must be in [1, {n}] (the number of points), got {m}"
        )));
    }
    check_finite("points", points)?;
    out.par_chunks_mut(m)
        .zip(points.par_chunks(n))
        .for_each(|(o, p)| fps_into(p, o));
    Ok(())
}

/// A `kiddo` k-d tree over one cloud (item: the point's index), coordinates widened to `f64`.
type KdTree = ImmutableKdTree<f64, u32, 3, 32>;

fn kd_tree(points: &[Point]) -> KdTree {
    let coords: Vec<[f64; 3]> = points.iter().map(widen).collect();
    ImmutableKdTree::new_from_slice(&coords)
}

#[inline]
fn widen(p: &Point) -> [f64; 3] {
    p.map(f64::from)
}

/// Tree searches reach this factor beyond the squared distance asked for, and every point
/// found is then tested with [`dist2_f64`]: rounding inside the tree never adds or drops a
/// point.
const SLACK: f64 = 1.0 + 1e-9;

/// The points of `tree` (built over `points`) within squared distance `r2` of `q`, by
/// [`dist2_f64`], in arbitrary order.
fn within(tree: &KdTree, points: &[Point], q: &Point, r2: f64) -> Vec<u32> {
    tree.within_unsorted::<SquaredEuclidean>(&widen(q), r2 * SLACK)
        .into_iter()
        .map(|nb| nb.item)
        .filter(|&i| dist2_f64(&points[i as usize], q) <= r2)
        .collect()
}

/// The `k` (at most the cloud's size) nearest points to `q` as `(squared distance, index)`,
/// ascending by distance then index: the tree's `k` nearest give the `k`-th distance, and
/// every point within it competes, so ties at the `k`-th distance go to the lower indices.
fn k_best(tree: &KdTree, points: &[Point], q: &Point, k: usize) -> Vec<(f64, usize)> {
    let k = k.min(points.len()).max(1);
    let qty = NonZeroUsize::new(k).unwrap_or(NonZeroUsize::MIN);
    let dk = tree
        .nearest_n::<SquaredEuclidean>(&widen(q), qty)
        .iter()
        .map(|nb| dist2_f64(&points[nb.item as usize], q))
        .fold(0.0, f64::max);
    let mut best: Vec<(f64, usize)> = within(tree, points, q, dk)
        .into_iter()
        .map(|i| (dist2_f64(&points[i as usize], q), i as usize))
        .collect();
    best.sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    best.truncate(k);
    best
}

fn ball_into(points: &[Point], centers: &[Point], radius: f64, k: usize, out: &mut [i64]) {
    // PointNet++'s own ball query: a scan in index order that stops at the k-th point
    // inside, with no allocation (see the module docs for why not the k-d tree)
    let r2 = radius * radius;
    for (c, o) in centers.iter().zip(out.chunks_mut(k)) {
        let mut count = 0;
        for (i, p) in points.iter().enumerate() {
            if dist2_f64(p, c) <= r2 {
                o[count] = i as i64;
                count += 1;
                if count == k {
                    break;
                }
            }
        }
        let fill = if count == 0 { nearest(points, c) } else { o[0] };
        for s in &mut o[count..] {
            *s = fill;
        }
    }
}

/// The index of the point of `points` nearest to `q` by [`dist2_f64`], the lowest on ties.
fn nearest(points: &[Point], q: &Point) -> i64 {
    let mut best = (f64::INFINITY, 0usize);
    for (i, p) in points.iter().enumerate() {
        let d = dist2_f64(p, q);
        if d < best.0 {
            best = (d, i);
        }
    }
    best.1 as i64
}

/// Ball query: for each centre, the first `k` points (index order) within `radius`, padded
/// as the module rules say. Returns `centers.len() * k` indices, row-major.
///
/// # Errors
/// `Degenerate` for no points, `Invalid` for `k` outside `[1, MAX_K]` or a radius that is
/// not finite and positive, `NonFinite` for a NaN or infinite coordinate.
pub fn ball_query(points: &[Point], centers: &[Point], radius: f64, k: usize) -> Result<Vec<i64>> {
    let mut out = vec![0; centers.len() * k];
    ball_query_batch(
        points,
        centers,
        1,
        points.len(),
        centers.len(),
        radius,
        k,
        &mut out,
    )?;
    Ok(out)
}

/// [`ball_query`] over a batch: `points` `(B, N, 3)`, `centers` `(B, M, 3)`, `out`
/// `(B, M, k)`, all row-major; parallel over the batch. Indices are into each cloud's `N`.
///
/// # Errors
/// `Shape` for buffers of the wrong length; otherwise as [`ball_query`].
#[allow(clippy::too_many_arguments)]
pub fn ball_query_batch(
    points: &[Point],
    centers: &[Point],
    b: usize,
    n: usize,
    m: usize,
    radius: f64,
    k: usize,
    out: &mut [i64],
) -> Result<()> {
    check_batch("points", points.len(), b, n)?;
    check_batch("centers", centers.len(), b, m)?;
    check_k(k)?;
    check_radius(radius)?;
    check_batch("out", out.len(), b, m * k)?;
    if b == 0 || m == 0 {
        return Ok(());
    }
    if n == 0 {
        return Err(GeometryError::Degenerate(
            "points: a ball query needs at least one point".to_string(),
        ));
    }
    check_finite("points", points)?;
    check_finite("centers", centers)?;
    out.par_chunks_mut(m * k)
        .zip(points.par_chunks(n).zip(centers.par_chunks(m)))
        .for_each(|(o, (p, c))| ball_into(p, c, radius, k, o));
    Ok(())
}

fn knn_into(points: &[Point], queries: &[Point], k: usize, idx: &mut [i64], dist: &mut [f32]) {
    let tree = kd_tree(points);
    for ((q, io), dout) in queries
        .iter()
        .zip(idx.chunks_mut(k))
        .zip(dist.chunks_mut(k))
    {
        for ((d2, i), (io, dout)) in k_best(&tree, points, q, k)
            .iter()
            .zip(io.iter_mut().zip(dout.iter_mut()))
        {
            *io = *i as i64;
            *dout = d2.sqrt() as f32;
        }
    }
}

/// The `k` nearest of `points` to each query, by distance then index (module rules).
///
/// Returns `(indices, distances)`, each `queries.len() * k` row-major; distances are
/// Euclidean (not squared), rounded to `f32`.
///
/// # Errors
/// `Invalid` for `k` outside `[1, points.len()]` (or above `MAX_K`), `NonFinite` for a NaN
/// or infinite coordinate.
pub fn k_nearest(points: &[Point], queries: &[Point], k: usize) -> Result<(Vec<i64>, Vec<f32>)> {
    let mut idx = vec![0; queries.len() * k];
    let mut dist = vec![0.0; queries.len() * k];
    k_nearest_batch(
        points,
        queries,
        1,
        points.len(),
        queries.len(),
        k,
        &mut idx,
        &mut dist,
    )?;
    Ok((idx, dist))
}

/// [`k_nearest`] over a batch: `points` `(B, M, 3)` (the reference clouds), `queries`
/// `(B, N, 3)`, outputs `(B, N, k)`, all row-major; parallel over the batch. Indices are
/// into each reference cloud's `M`.
///
/// # Errors
/// `Shape` for buffers of the wrong length; otherwise as [`k_nearest`].
#[allow(clippy::too_many_arguments)]
pub fn k_nearest_batch(
    points: &[Point],
    queries: &[Point],
    b: usize,
    m: usize,
    n: usize,
    k: usize,
    idx: &mut [i64],
    dist: &mut [f32],
) -> Result<()> {
    check_batch("points", points.len(), b, m)?;
    check_batch("queries", queries.len(), b, n)?;
    check_k(k)?;
    if k > m {
        return Err(GeometryError::Invalid(format!(
            "k: the number of neighbours must be at most the number of points ({m}), got {k}"
        )));
    }
    check_batch("indices", idx.len(), b, n * k)?;
    check_batch("distances", dist.len(), b, n * k)?;
    if b == 0 || n == 0 {
        return Ok(());
    }
    check_finite("points", points)?;
    check_finite("queries", queries)?;
    idx.par_chunks_mut(n * k)
        .zip(dist.par_chunks_mut(n * k))
        .zip(points.par_chunks(m).zip(queries.par_chunks(n)))
        .for_each(|((io, dout), (p, q))| knn_into(p, q, k, io, dout));
    Ok(())
}

/// Check that a buffer of `len` items holds `b * n`.
fn check_batch(what: &str, len: usize, b: usize, n: usize) -> Result<()> {
    if b.checked_mul(n) != Some(len) {
        return Err(GeometryError::Shape {
            what: what.to_string(),
            expected: format!("({b}, {n}) items"),
            got: format!("{len} items"),
        });
    }
    Ok(())
}

/// Items per batch element of a buffer of `len` items (`len` a multiple of `b`).
fn per_item(what: &str, len: usize, b: usize) -> Result<usize> {
    if b == 0 {
        return if len == 0 {
            Ok(0)
        } else {
            Err(GeometryError::Shape {
                what: what.to_string(),
                expected: "an empty buffer for an empty batch".to_string(),
                got: format!("{len} items"),
            })
        };
    }
    if !len.is_multiple_of(b) {
        return Err(GeometryError::Shape {
            what: what.to_string(),
            expected: format!("a multiple of the batch size {b}"),
            got: format!("{len} items"),
        });
    }
    Ok(len / b)
}

#[cfg(test)]
#[path = "pointnet_tests.rs"]
mod tests;
