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
//! Ball query and nearest neighbours visit the cells of a uniform grid around each centre or
//! query (cells a hair larger than the radius; rings of cells until the k-th distance is
//! below the distance to the unsearched cells), so they are exact, the same as a brute-force
//! scan, at a fraction of its cost. Farthest point sampling is the plain `O(M N)` loop.

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

/// Safety factor on cell sizes and search bounds: rounding in the cell arithmetic is far
/// below it, so no point is ever missed.
const MARGIN: f64 = 1e-9;

/// A uniform grid of cubic cells over one cloud: each cell lists its points in index order.
struct Grid {
    lo: [f64; 3],
    h: f64,
    dims: [usize; 3],
    /// `starts[c]..starts[c + 1]` indexes `items` for cell `c`.
    starts: Vec<usize>,
    items: Vec<u32>,
}

/// The bounding box `(low, high)` of a cloud, in `f64`.
fn bounds(points: &[Point]) -> ([f64; 3], [f64; 3]) {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for p in points {
        for a in 0..3 {
            lo[a] = lo[a].min(f64::from(p[a]));
            hi[a] = hi[a].max(f64::from(p[a]));
        }
    }
    (lo, hi)
}

impl Grid {
    /// Cells of side at least `h`, doubled until there are at most `4 n + 8` cells.
    fn new(points: &[Point], h: f64) -> Self {
        let (lo, hi) = bounds(points);
        let ext = [0, 1, 2].map(|a| (hi[a] - lo[a]).max(0.0));
        let cap = 4 * points.len() + 8;
        let mut h = if h.is_finite() && h > 0.0 { h } else { 1.0 };
        let mut dims;
        loop {
            dims = ext.map(|e| (e / h).floor().min(cap as f64) as usize + 1);
            if dims[0].saturating_mul(dims[1]).saturating_mul(dims[2]) <= cap {
                break;
            }
            h *= 2.0;
        }
        let mut grid = Grid {
            lo,
            h,
            dims,
            starts: vec![0; dims[0] * dims[1] * dims[2] + 1],
            items: vec![0; points.len()],
        };
        let cells: Vec<usize> = points.iter().map(|p| grid.cell_index(p)).collect();
        for &c in &cells {
            grid.starts[c + 1] += 1;
        }
        for c in 0..grid.starts.len() - 1 {
            grid.starts[c + 1] += grid.starts[c];
        }
        let mut fill = grid.starts.clone();
        for (i, &c) in cells.iter().enumerate() {
            grid.items[fill[c]] = i as u32;
            fill[c] += 1;
        }
        grid
    }

    /// The cell coordinates of a point (clamped to the grid).
    fn cell(&self, p: &Point) -> [usize; 3] {
        [0, 1, 2].map(|a| {
            let t = ((f64::from(p[a]) - self.lo[a]) / self.h).floor();
            (t.max(0.0) as usize).min(self.dims[a] - 1)
        })
    }

    fn cell_index(&self, p: &Point) -> usize {
        let c = self.cell(p);
        (c[0] * self.dims[1] + c[1]) * self.dims[2] + c[2]
    }

    /// The distance from `q` (in cell `c`) to the nearest face, with cells beyond it, of the
    /// box of cells within Chebyshev distance `ring` of `c` (infinite when the box covers
    /// the grid): a lower bound of the distance to every point outside the box.
    fn gap(&self, q: &Point, c: [usize; 3], ring: usize) -> f64 {
        let mut gap = f64::INFINITY;
        for a in 0..3 {
            let qa = f64::from(q[a]);
            if c[a] > ring {
                gap = gap.min(qa - (self.lo[a] + (c[a] - ring) as f64 * self.h));
            }
            if c[a] + ring + 1 < self.dims[a] {
                gap = gap.min(self.lo[a] + (c[a] + ring + 1) as f64 * self.h - qa);
            }
        }
        gap.max(0.0)
    }

    /// Call `f` with the points of every cell at Chebyshev distance exactly `ring` from
    /// cell `c`.
    fn ring(&self, c: [usize; 3], ring: usize, mut f: impl FnMut(u32)) {
        let r = ring as isize;
        let range = |a: usize| {
            let lo = (c[a] as isize - r).max(0) as usize;
            let hi = ((c[a] as isize + r) as usize).min(self.dims[a] - 1);
            (lo, hi)
        };
        let (x0, x1) = range(0);
        let (y0, y1) = range(1);
        let (z0, z1) = range(2);
        let on_ring = |v: usize, a: usize| (v as isize - c[a] as isize).abs() == r;
        for x in x0..=x1 {
            for y in y0..=y1 {
                let edge = on_ring(x, 0) || on_ring(y, 1);
                let mut z = z0;
                while z <= z1 {
                    if edge || on_ring(z, 2) {
                        let cell = (x * self.dims[1] + y) * self.dims[2] + z;
                        for &i in &self.items[self.starts[cell]..self.starts[cell + 1]] {
                            f(i);
                        }
                        z += 1;
                    } else {
                        // interior of this column: jump to the far face
                        z = (c[2] as isize + r) as usize;
                    }
                }
            }
        }
    }
}

fn ball_into(points: &[Point], centers: &[Point], radius: f64, k: usize, out: &mut [i64]) {
    let r2 = radius * radius;
    // a point within the radius is at most one cell away (cells a hair larger than it)
    let grid = Grid::new(points, radius * (1.0 + MARGIN));
    let mut inside: Vec<u32> = Vec::new();
    for (c, o) in centers.iter().zip(out.chunks_mut(k)) {
        inside.clear();
        // cells are at least the radius: its ball lies in the 3 x 3 x 3 cells around
        let cc = grid.cell(c);
        for ring in 0..2 {
            grid.ring(cc, ring, |i| {
                if dist2_f64(&points[i as usize], c) <= r2 {
                    inside.push(i);
                }
            });
        }
        let count = inside.len().min(k);
        if count > 0 {
            if inside.len() > k {
                inside.select_nth_unstable(k - 1);
            }
            inside[..count].sort_unstable();
        }
        for (s, &i) in o.iter_mut().zip(&inside[..count]) {
            *s = i64::from(i);
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

/// Offer point `i` at `p` to the `k` best `(squared distance, index)` of query `q`.
fn keep_nearest(best: &mut Vec<(f64, usize)>, k: usize, p: &Point, q: &Point, i: u32) {
    let (d, i) = (dist2_f64(p, q), i as usize);
    if best.len() == k && (d, i) >= best[k - 1] {
        return;
    }
    let at = best.partition_point(|&e| e < (d, i));
    best.insert(at, (d, i));
    best.truncate(k);
}

fn knn_into(points: &[Point], queries: &[Point], k: usize, idx: &mut [i64], dist: &mut [f32]) {
    // about as many cells as points in the bounding box
    let (lo, hi) = bounds(points);
    let ext = (0..3).map(|a| hi[a] - lo[a]).fold(0.0, f64::max);
    let grid = Grid::new(points, ext / (points.len() as f64).cbrt().max(1.0));
    // (squared distance, index), kept sorted ascending, ties by index
    let mut best: Vec<(f64, usize)> = Vec::with_capacity(k + 1);
    for ((q, io), dout) in queries
        .iter()
        .zip(idx.chunks_mut(k))
        .zip(dist.chunks_mut(k))
    {
        best.clear();
        let qc = grid.cell(q);
        let mut ring = 0usize;
        loop {
            grid.ring(qc, ring, |i| {
                keep_nearest(&mut best, k, &points[i as usize], q, i)
            });
            // every point outside the cells searched so far is farther than the query's
            // distance to the nearest face of their box that has cells beyond it: stop once
            // the k-th best is strictly nearer than that
            let bound = grid.gap(q, qc, ring) * (1.0 - MARGIN);
            if bound.is_infinite() || (best.len() == k && best[k - 1].0 < bound * bound) {
                break;
            }
            ring += 1;
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
