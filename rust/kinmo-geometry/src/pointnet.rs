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

/// Point indices sorted by x (then index), with their x coordinates in `f64`: the points
/// within `dx` of a query in x form one run of this order.
fn x_order(points: &[Point]) -> (Vec<usize>, Vec<f64>) {
    let mut order: Vec<usize> = (0..points.len()).collect();
    order.sort_by(|&a, &b| points[a][0].total_cmp(&points[b][0]).then(a.cmp(&b)));
    let xs = order.iter().map(|&i| f64::from(points[i][0])).collect();
    (order, xs)
}

fn ball_into(points: &[Point], centers: &[Point], radius: f64, k: usize, out: &mut [i64]) {
    let r2 = radius * radius;
    let (order, xs) = x_order(points);
    let mut inside: Vec<usize> = Vec::new();
    for (c, o) in centers.iter().zip(out.chunks_mut(k)) {
        // only points with (x - cx)^2 <= r^2 can be within the radius: |dx| <= r, widened by
        // one ulp-scale margin, then checked exactly
        let cx = f64::from(c[0]);
        let lo = xs.partition_point(|&x| x < cx - radius * (1.0 + 1e-9));
        let hi = xs.partition_point(|&x| x <= cx + radius * (1.0 + 1e-9));
        inside.clear();
        inside.extend(
            order[lo..hi]
                .iter()
                .copied()
                .filter(|&i| dist2_f64(&points[i], c) <= r2),
        );
        let count = inside.len().min(k);
        if count > 0 {
            if inside.len() > k {
                inside.select_nth_unstable(k - 1);
            }
            inside[..count].sort_unstable();
        }
        for (s, &i) in o.iter_mut().zip(&inside[..count]) {
            *s = i as i64;
        }
        let fill = if count == 0 {
            nearest(points, c) as i64
        } else {
            o[0]
        };
        for s in &mut o[count..] {
            *s = fill;
        }
    }
}

/// Index of the nearest point to `c` (the first of equally near ones).
fn nearest(points: &[Point], c: &Point) -> usize {
    let mut best = f64::INFINITY;
    let mut arg = 0usize;
    for (i, p) in points.iter().enumerate() {
        let d = dist2_f64(p, c);
        if d < best {
            best = d;
            arg = i;
        }
    }
    arg
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
    let (order, xs) = x_order(points);
    let m = points.len();
    // (squared distance, index), kept sorted ascending, ties by index
    let mut best: Vec<(f64, usize)> = Vec::with_capacity(k + 1);
    for ((q, io), dout) in queries
        .iter()
        .zip(idx.chunks_mut(k))
        .zip(dist.chunks_mut(k))
    {
        best.clear();
        let qx = f64::from(q[0]);
        // walk outwards in x from the query, nearer side first; stop once the x gap alone
        // exceeds the k-th best squared distance (the gap's square never exceeds the full
        // squared distance, rounding included)
        let start = xs.partition_point(|&x| x < qx);
        let (mut lo, mut hi) = (start, start);
        loop {
            let gap_lo = if lo > 0 {
                qx - xs[lo - 1]
            } else {
                f64::INFINITY
            };
            let gap_hi = if hi < m { xs[hi] - qx } else { f64::INFINITY };
            let (gap, j) = if gap_lo <= gap_hi {
                if lo == 0 {
                    break;
                }
                lo -= 1;
                (gap_lo, lo)
            } else {
                hi += 1;
                (gap_hi, hi - 1)
            };
            if best.len() == k && gap * gap > best[k - 1].0 {
                break;
            }
            let i = order[j];
            let d = dist2_f64(&points[i], q);
            if best.len() == k && (d, i) >= best[k - 1] {
                continue;
            }
            let at = best.partition_point(|&e| e < (d, i));
            best.insert(at, (d, i));
            best.truncate(k);
        }
        for ((d2, i), (io, dout)) in best.iter().zip(io.iter_mut().zip(dout.iter_mut())) {
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
