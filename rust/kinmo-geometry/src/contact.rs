//! Contact adjacency between the parts of a shape: exact triangle-level surface distances.
//!
//! Two parts of a shape are *in contact* when their surfaces come within a tolerance of
//! each other. kinmo's part graphs use `tolerance = 0.01 × diagonal` of the object's
//! axis-aligned bounding box ([`DEFAULT_RELATIVE_TOLERANCE`]).
//!
//! The pipeline of [`contact_pairs`], on parry3d-f64:
//!
//! 1. one parry `Bvh` per mesh over its triangle AABBs (the hierarchy of parry's
//!    `TriMesh`, binned SAH build) ([`MeshBvh`]);
//! 2. broad phase: a parry `Bvh` over the mesh AABBs, each loosened by `tolerance / 2`,
//!    queried with each mesh's loosened AABB, then the exact AABB distance test;
//! 3. narrow phase, over the candidate pairs: parry's simultaneous traversal of the two
//!    hierarchies (`Bvh::leaf_pairs`), first over overlapping node pairs only (do the
//!    surfaces touch?), then pruning every pair of nodes farther apart than the best
//!    distance found so far (initially `tolerance`), with an exact triangle-triangle
//!    distance at the leaves. It stops as soon as the surfaces are found to touch, and
//!    otherwise returns the true minimum distance of the pairs within `tolerance`.
//!
//! Steps 1 and 3 run in parallel (rayon) when the meshes have 20 000 triangles or more.
//! [`contact_pairs_of_meshes`] (what kinmo's part graphs call) runs the broad phase first, on
//! boxes taken from the vertices, and builds each hierarchy once, only for the meshes of some
//! candidate pair, then reuses it for every pair of the sweep (`kinmo prepare` on the shared
//! PartNet-Mobility objects: most leaves are near few others, and the BVH build was the
//! largest single cost of the contact stage).
//!
//! **Own code kept:** the triangle-triangle distance at the leaves. parry measures the
//! distance of two triangles with GJK (`query::distance` on support maps), an iterative
//! method accurate to its convergence tolerance (about `1e-9` relative here): contacts
//! exactly at the tolerance would flip, and touching triangles come out at a tiny positive
//! distance. The exact closed-form distance (below) decides those cases exactly; it first
//! rejects pairs lying on one side of the other's plane beyond the bound, then tests the 9
//! edge pairs with the separating-slab early exit of PQP (Larsen et al., *Fast Proximity
//! Queries with Swept Sphere Volumes*, 1999), the 6 edge-triangle crossings (intersection:
//! distance 0) and the 6 vertex-face projections. Zero-area triangles reduce to their
//! edges.
//!
//! Distances are Euclidean, in the units of the vertices, between the *surfaces* (the
//! triangles): a mesh nested inside a closed mesh without touching it is at a positive
//! distance. [`contact_pairs_of_meshes`] and [`mesh_distance_of_meshes`] first scale all
//! coordinates by one power of two (exact) so that the largest magnitude is about 1, so
//! squared distances neither overflow (coordinates up to `f64::MAX`) nor underflow
//! (coordinates down to about `1e-300`).

use std::cell::Cell;

use nalgebra::{Point3, Vector3};
use parry3d_f64::bounding_volume::{Aabb, BoundingVolume};
use parry3d_f64::partitioning::{Bvh, BvhBuildStrategy, BvhNode};
use rayon::prelude::*;

use crate::error::{GeometryError, Result};
use crate::mesh::TriMesh;

/// Fraction of the object's bounding-box diagonal used as contact tolerance by kinmo's
/// part graphs (`tolerance = DEFAULT_RELATIVE_TOLERANCE × diagonal`).
pub const DEFAULT_RELATIVE_TOLERANCE: f64 = 0.01;

/// Below this many triangles in total, [`contact_pairs`] runs on the calling thread: waking
/// the thread pool would cost more than the work (about a millisecond).
const PARALLEL_MIN_TRIANGLES: usize = 20_000;

/// Squared distance between two boxes (0 when they overlap).
#[inline]
fn aabb_distance2(a_mins: &Point3<f64>, a_maxs: &Point3<f64>, b: &BvhNode) -> f64 {
    let (b_mins, b_maxs) = (b.mins(), b.maxs());
    let mut d2 = 0.0;
    for k in 0..3 {
        let gap = (b_mins[k] - a_maxs[k]).max(a_mins[k] - b_maxs[k]);
        if gap > 0.0 {
            d2 += gap * gap;
        }
    }
    d2
}

/// Squared distance between two parry AABBs (0 when they overlap).
#[inline]
fn box_distance2(a: &Aabb, b: &Aabb) -> f64 {
    let mut d2 = 0.0;
    for k in 0..3 {
        let gap = (b.mins[k] - a.maxs[k]).max(a.mins[k] - b.maxs[k]);
        if gap > 0.0 {
            d2 += gap * gap;
        }
    }
    d2
}

/// A triangle mesh with parry's bounding volume hierarchy, ready for distance queries.
///
/// Zero-area triangles and duplicate vertices are accepted: a degenerate triangle behaves
/// as its edges. A mesh without faces has no surface ([`MeshBvh::is_empty`]).
#[derive(Clone)]
pub struct MeshBvh {
    /// parry's hierarchy over the triangle AABBs (leaf `i`: triangle `i`); `None` when
    /// the mesh has no triangle.
    bvh: Option<Bvh>,
    /// Corners and unnormalised normal `(b - a) × (c - a)` of each triangle, in parry's
    /// triangle order (contiguous, so the leaves read no index buffer).
    triangles: Vec<([Point3<f64>; 3], Vector3<f64>)>,
}

impl std::fmt::Debug for MeshBvh {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("MeshBvh")
            .field("num_triangles", &self.num_triangles())
            .finish()
    }
}

impl MeshBvh {
    /// Build the hierarchy of a mesh given by its vertices and faces.
    ///
    /// # Errors
    ///
    /// [`GeometryError::NonFinite`] if a vertex coordinate is NaN or infinite,
    /// [`GeometryError::IndexOutOfRange`] if a face references a missing vertex. A mesh
    /// without faces is valid and has no surface ([`MeshBvh::is_empty`]).
    pub fn new(vertices: &[Point3<f64>], faces: &[[u32; 3]]) -> Result<MeshBvh> {
        Self::with_name(vertices, faces, "mesh")
    }

    /// Same as [`MeshBvh::new`], with `what` naming the mesh in error messages.
    pub fn with_name(vertices: &[Point3<f64>], faces: &[[u32; 3]], what: &str) -> Result<Self> {
        let mesh = TriMesh::new(
            vertices.to_vec(),
            faces.to_vec(),
            &format!("{what} vertices"),
        )
        .map_err(|e| match e {
            GeometryError::IndexOutOfRange {
                face,
                vertex,
                n_vertices,
                ..
            } => GeometryError::IndexOutOfRange {
                what: format!("{what} faces"),
                face,
                vertex,
                n_vertices,
            },
            other => other,
        })?;
        Ok(Self::from_mesh(&mesh))
    }

    /// Build the hierarchy of an already validated mesh.
    pub fn from_mesh(mesh: &TriMesh) -> MeshBvh {
        Self::from_mesh_scaled(mesh, 1.0)
    }

    /// Build the hierarchy of `mesh` with every coordinate multiplied by `scale` (a power
    /// of two in this module, so the scaling is exact).
    fn from_mesh_scaled(mesh: &TriMesh, scale: f64) -> MeshBvh {
        let v = mesh.vertices();
        let triangles: Vec<([Point3<f64>; 3], Vector3<f64>)> = mesh
            .faces()
            .iter()
            .map(|f| {
                let t = [v[f[0] as usize], v[f[1] as usize], v[f[2] as usize]]
                    .map(|p| crate::mesh::flush_tiny(&(p * scale)));
                (t, normal(&t))
            })
            .collect();
        if triangles.is_empty() {
            return MeshBvh {
                bvh: None,
                triangles,
            };
        }
        // The hierarchy parry's `TriMesh` builds (binned SAH over the triangle AABBs),
        // without the rest of `TriMesh` (copies of the buffers), which no query here uses.
        let boxes: Vec<Aabb> = triangles
            .iter()
            .map(|(t, _)| Aabb::from_points(t.iter().copied()))
            .collect();
        MeshBvh {
            bvh: Some(Bvh::from_leaves(BvhBuildStrategy::Binned, &boxes)),
            triangles,
        }
    }

    /// Number of triangles.
    pub fn num_triangles(&self) -> usize {
        self.triangles.len()
    }

    /// True when the mesh has no triangle (no surface).
    pub fn is_empty(&self) -> bool {
        self.bvh.is_none()
    }

    /// Axis-aligned bounding box `(mins, maxs)`, `None` for an empty mesh.
    pub fn aabb(&self) -> Option<(Point3<f64>, Point3<f64>)> {
        self.root_aabb().map(|b| (b.mins, b.maxs))
    }

    fn root_aabb(&self) -> Option<Aabb> {
        self.bvh.as_ref().map(Bvh::root_aabb)
    }
}

/// Squared minimum surface distance between `a` and `b` if it is `<= bound2`.
///
/// parry's simultaneous traversal of the two hierarchies, pruning node pairs farther than
/// the best distance so far; returns as soon as a distance of 0 is found.
/// `bound2 = INFINITY` gives the unconditional minimum.
fn min_distance2_within(a: &MeshBvh, b: &MeshBvh, bound2: f64) -> Option<f64> {
    let (Some(ta), Some(tb)) = (&a.bvh, &b.bvh) else {
        return None;
    };
    if box_distance2(&ta.root_aabb(), &tb.root_aabb()) > bound2 {
        return None;
    }
    // First pass: do the surfaces touch? Only overlapping node pairs are visited, and most
    // touching parts are found here at a fraction of the cost of the bounded search.
    let overlap = |na: &BvhNode, nb: &BvhNode| aabb_distance2(&na.mins(), &na.maxs(), nb) <= 0.0;
    for (ia, ib) in ta.leaf_pairs(tb, overlap) {
        if let (Some((pa, na)), Some((pb, nb))) =
            (a.triangles.get(ia as usize), b.triangles.get(ib as usize))
        {
            if triangle_distance2_below((pa, na), (pb, nb), 0.0) <= 0.0 {
                return Some(0.0);
            }
        }
    }
    let best2 = Cell::new(bound2);
    let mut found = false;
    let check =
        |na: &BvhNode, nb: &BvhNode| aabb_distance2(&na.mins(), &na.maxs(), nb) <= best2.get();
    for (ia, ib) in ta.leaf_pairs(tb, check) {
        let (Some((ta, na)), Some((tb, nb))) =
            (a.triangles.get(ia as usize), b.triangles.get(ib as usize))
        else {
            continue;
        };
        let t2 = triangle_distance2_below((ta, na), (tb, nb), best2.get());
        if t2 <= best2.get() {
            best2.set(t2);
            found = true;
            if t2 == 0.0 {
                return Some(0.0);
            }
        }
    }
    found.then_some(best2.get())
}

/// Unnormalised normal `(b - a) × (c - a)` (zero when degenerate).
#[inline]
fn normal(t: &[Point3<f64>; 3]) -> Vector3<f64> {
    (t[1] - t[0]).cross(&(t[2] - t[0]))
}

/// Exact minimum distance between the surfaces of two meshes (0 if they touch or
/// intersect), in the units of the vertices.
///
/// # Errors
///
/// [`GeometryError::Degenerate`] if either mesh has no triangle.
pub fn mesh_distance(a: &MeshBvh, b: &MeshBvh) -> Result<f64> {
    for (m, what) in [(a, "mesh_a"), (b, "mesh_b")] {
        if m.is_empty() {
            return Err(GeometryError::Degenerate(format!("{what}: no faces")));
        }
    }
    min_distance2_within(a, b, f64::INFINITY)
        .map(f64::sqrt)
        .ok_or_else(|| GeometryError::Degenerate("meshes have no surface".into()))
}

/// [`mesh_distance`] of two validated meshes, scale-robust: coordinates are first scaled
/// by a power of two (exact) so the largest magnitude is about 1, and the distance is
/// scaled back, so it is neither `inf` at `1e200` nor `0` at `1e-300`.
///
/// # Errors
///
/// [`GeometryError::Degenerate`] if either mesh has no triangle.
pub fn mesh_distance_of_meshes(a: &TriMesh, b: &TriMesh) -> Result<f64> {
    let s = unit_scale([a, b]);
    let (ba, bb) = rayon::join(
        || MeshBvh::from_mesh_scaled(a, s),
        || MeshBvh::from_mesh_scaled(b, s),
    );
    Ok(mesh_distance(&ba, &bb)? / s)
}

/// The power of two `s` such that `s × max |coordinate|` of `meshes` is in `[0.5, 1)`
/// (`1` when all coordinates are zero).
fn unit_scale<'a>(meshes: impl IntoIterator<Item = &'a TriMesh>) -> f64 {
    let m = meshes
        .into_iter()
        .flat_map(|m| m.vertices().iter())
        .flat_map(|p| p.iter().map(|x| x.abs()))
        .fold(0.0f64, f64::max);
    if !(m > 0.0 && m.is_finite()) {
        return 1.0;
    }
    // 2^-e with m = f × 2^e, f in [0.5, 1); built from the exponent, clamped to the range
    // of normal doubles.
    let e = m.log2().floor() as i32 + 1;
    2f64.powi((-e).clamp(-1022, 1023))
}

/// Minimum surface distance between `a` and `b` if it is `<= tolerance`, else `None`.
///
/// Cheaper than [`mesh_distance`] for far-apart meshes: the traversal only explores pairs
/// of nodes within `tolerance`, and stops at the first contact.
pub fn distance_within(a: &MeshBvh, b: &MeshBvh, tolerance: f64) -> Option<f64> {
    if tolerance.is_nan() || tolerance < 0.0 {
        return None;
    }
    min_distance2_within(a, b, tolerance * tolerance).map(f64::sqrt)
}

/// Two meshes of a shape whose surfaces are within the tolerance.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ContactPair {
    /// Index of the first mesh (`i < j`).
    pub i: usize,
    /// Index of the second mesh.
    pub j: usize,
    /// Minimum surface distance, `<= tolerance` (0 for touching or intersecting meshes).
    pub distance: f64,
}

/// Pairs of boxes within `tolerance` of each other (`i < j`): a parry `Bvh` over the boxes
/// loosened by `tolerance / 2`, then the exact box distance. `None` entries never pair.
fn broad_phase(boxes: &[Option<Aabb>], tolerance: f64) -> Vec<(usize, usize)> {
    let tol2 = tolerance * tolerance;
    let ids: Vec<usize> = (0..boxes.len()).filter(|&i| boxes[i].is_some()).collect();
    let loose: Vec<Aabb> = ids
        .iter()
        .filter_map(|&i| boxes[i].map(|b| b.loosened(0.5 * tolerance)))
        .collect();
    if loose.is_empty() {
        return Vec::new();
    }
    let bvh = Bvh::from_leaves(BvhBuildStrategy::Binned, &loose);
    let mut pairs = Vec::new();
    for (k, (&i, b)) in ids.iter().zip(&loose).enumerate() {
        for leaf in bvh.intersect_aabb(b) {
            let l = leaf as usize;
            if l <= k {
                continue;
            }
            let j = ids[l];
            if let (Some(bi), Some(bj)) = (&boxes[i], &boxes[j]) {
                if box_distance2(bi, bj) <= tol2 {
                    pairs.push((i, j));
                }
            }
        }
    }
    pairs.sort_unstable();
    pairs
}

/// All pairs of meshes whose surfaces come within `tolerance` of each other.
///
/// Exact triangle-level distances (no sampling); see the module documentation for the
/// algorithm. Pairs are tested in parallel (rayon) when the meshes have 20 000 triangles or
/// more in total.
///
/// # Arguments
///
/// * `meshes` - the parts of one shape; meshes without triangles are in contact with
///   nothing.
/// * `tolerance` - absolute distance, finite and `>= 0` (kinmo uses
///   [`DEFAULT_RELATIVE_TOLERANCE`] × the shape's bounding-box diagonal).
///
/// # Returns
///
/// The pairs sorted by `(i, j)`, with `i < j`.
///
/// # Errors
///
/// [`GeometryError::Invalid`] for a negative or non-finite tolerance.
pub fn contact_pairs(meshes: &[MeshBvh], tolerance: f64) -> Result<Vec<ContactPair>> {
    check_tolerance(tolerance)?;
    pairs_within(meshes, tolerance, 1.0)
}

/// [`contact_pairs`] on meshes scaled by `scale`, with `tolerance` and the distances in the
/// unscaled units.
fn pairs_within(meshes: &[MeshBvh], tolerance: f64, scale: f64) -> Result<Vec<ContactPair>> {
    let boxes: Vec<Option<Aabb>> = meshes.iter().map(MeshBvh::root_aabb).collect();
    let candidates = broad_phase(&boxes, tolerance * scale);
    let hierarchies: Vec<Option<&MeshBvh>> = meshes.iter().map(Some).collect();
    Ok(narrow_phase(&hierarchies, &candidates, tolerance, scale))
}

/// The exact distances of the `candidates` pairs (broad-phase output), kept when within
/// `tolerance`; `meshes[i]` is `None` only for meshes in no candidate pair.
fn narrow_phase(
    meshes: &[Option<&MeshBvh>],
    candidates: &[(usize, usize)],
    tolerance: f64,
    scale: f64,
) -> Vec<ContactPair> {
    let tol = tolerance * scale;
    let tol2 = tol * tol;
    let narrow = |&(i, j): &(usize, usize)| {
        let (a, b) = (meshes[i]?, meshes[j]?);
        let distance = min_distance2_within(a, b, tol2)?.sqrt() / scale;
        // Also guards against `tolerance²` overflowing to infinity.
        (distance <= tolerance).then_some(ContactPair { i, j, distance })
    };
    let total: usize = meshes.iter().flatten().map(|m| m.num_triangles()).sum();
    let mut pairs: Vec<ContactPair> = if total >= PARALLEL_MIN_TRIANGLES {
        candidates.par_iter().filter_map(narrow).collect()
    } else {
        candidates.iter().filter_map(narrow).collect()
    };
    pairs.sort_unstable_by_key(|p| (p.i, p.j));
    pairs
}

fn check_tolerance(tolerance: f64) -> Result<()> {
    if tolerance.is_finite() && tolerance >= 0.0 {
        Ok(())
    } else {
        Err(GeometryError::Invalid(format!(
            "tolerance: expected a finite value >= 0, got {tolerance}"
        )))
    }
}

/// [`contact_pairs`] on validated meshes, on coordinates scaled by one power of two (see
/// the module documentation).
///
/// The broad phase runs first, on each mesh's bounding box (the box of its scaled triangle
/// corners, exactly the root box of its hierarchy), and a hierarchy is built (in parallel
/// for large shapes) only for the meshes of at least one candidate pair: a mesh far from
/// every other costs one pass over its faces, not a BVH build. Same pairs and distances
/// as building every hierarchy.
///
/// # Errors
///
/// As [`contact_pairs`].
pub fn contact_pairs_of_meshes(meshes: &[TriMesh], tolerance: f64) -> Result<Vec<ContactPair>> {
    check_tolerance(tolerance)?;
    let s = unit_scale(meshes);
    let boxes: Vec<Option<Aabb>> = meshes.iter().map(|m| scaled_aabb(m, s)).collect();
    let candidates = broad_phase(&boxes, tolerance * s);
    let mut needed = vec![false; meshes.len()];
    for &(i, j) in &candidates {
        needed[i] = true;
        needed[j] = true;
    }
    let total: usize = meshes
        .iter()
        .zip(&needed)
        .filter(|(_, &n)| n)
        .map(|(m, _)| m.n_faces())
        .sum();
    let build = |(m, &n): (&TriMesh, &bool)| n.then(|| MeshBvh::from_mesh_scaled(m, s));
    let bvhs: Vec<Option<MeshBvh>> = if total >= PARALLEL_MIN_TRIANGLES {
        meshes.par_iter().zip(&needed).map(build).collect()
    } else {
        meshes.iter().zip(&needed).map(build).collect()
    };
    let refs: Vec<Option<&MeshBvh>> = bvhs.iter().map(Option::as_ref).collect();
    Ok(narrow_phase(&refs, &candidates, tolerance, s))
}

/// The box of the triangle corners of `mesh` scaled by `scale` (with [`flush_tiny`], as in
/// [`MeshBvh::from_mesh_scaled`]): the root box of its hierarchy, `None` without faces.
///
/// [`flush_tiny`]: crate::mesh::flush_tiny
fn scaled_aabb(mesh: &TriMesh, scale: f64) -> Option<Aabb> {
    let v = mesh.vertices();
    let mut used = mesh.faces().iter().flatten();
    let first = crate::mesh::flush_tiny(&(v[*used.next()? as usize] * scale));
    let (lo, hi) = used.fold((first, first), |(lo, hi), &i| {
        let p = crate::mesh::flush_tiny(&(v[i as usize] * scale));
        (lo.inf(&p), hi.sup(&p))
    });
    Some(Aabb::new(lo, hi))
}

// ---------------------------------------------------------------------------------------
// Exact triangle-triangle distance.
// ---------------------------------------------------------------------------------------

/// Squared distance between two triangles (0 if they intersect).
///
/// For disjoint triangles the minimum is reached between two edges or between a vertex
/// and the interior of the other triangle; intersecting triangles have an edge of one
/// crossing the other (coplanar overlaps give a zero edge-edge or vertex-face distance).
/// Degenerate triangles reduce to their edges.
#[cfg(test)]
fn triangle_distance2(p: &[Point3<f64>; 3], q: &[Point3<f64>; 3]) -> f64 {
    let np = (p[1] - p[0]).cross(&(p[2] - p[0]));
    let nq = (q[1] - q[0]).cross(&(q[2] - q[0]));
    triangle_distance2_below((p, &np), (q, &nq), f64::INFINITY)
}

/// Squared distance between two triangles if it is `<= bound2`; otherwise some value
/// `> bound2` (a cheaper lower bound).
///
/// Rejects first when one triangle lies entirely on one side of the other's plane, farther
/// than `sqrt(bound2)`.
#[inline]
fn triangle_distance2_below(
    (p, np): (&[Point3<f64>; 3], &Vector3<f64>),
    (q, nq): (&[Point3<f64>; 3], &Vector3<f64>),
    bound2: f64,
) -> f64 {
    if bound2 < f64::INFINITY {
        for (n, o, t) in [(np, &p[0], q), (nq, &q[0], p)] {
            let s = [n.dot(&(t[0] - o)), n.dot(&(t[1] - o)), n.dot(&(t[2] - o))];
            let same_side = (s[0] > 0.0 && s[1] > 0.0 && s[2] > 0.0)
                || (s[0] < 0.0 && s[1] < 0.0 && s[2] < 0.0);
            if same_side {
                let m = s[0].abs().min(s[1].abs()).min(s[2].abs());
                let nn = n.norm_squared();
                // m / |n| is the distance of the closest vertex to the plane: a lower
                // bound of the triangle distance.
                if m * m > bound2 * nn {
                    return m * m / nn;
                }
            }
        }
    }
    // Edge pairs first, with the separation test of PQP (Larsen et al., *Fast Proximity
    // Queries with Swept Sphere Volumes*, 1999): if the closest points `P`, `Q` of two edges
    // leave the third vertex of each triangle on its own side of the slab orthogonal to
    // `Q - P`, the slab separates the triangles and `|Q - P|` is their distance.
    let mut best = f64::INFINITY;
    for i in 0..3 {
        let (a0, a1, a2) = (&p[i], &p[(i + 1) % 3], &p[(i + 2) % 3]);
        for j in 0..3 {
            let (b0, b1, b2) = (&q[j], &q[(j + 1) % 3], &q[(j + 2) % 3]);
            let (cp, cq) = segment_closest_points(a0, a1, b0, b1);
            let v = cq - cp;
            let dd = v.norm_squared();
            if dd <= best {
                best = dd;
                if (a2 - cp).dot(&v) <= 0.0 && (b2 - cq).dot(&v) >= 0.0 {
                    return dd;
                }
            }
        }
    }
    for k in 0..3 {
        if segment_crosses_triangle(&p[k], &p[(k + 1) % 3], q, nq)
            || segment_crosses_triangle(&q[k], &q[(k + 1) % 3], p, np)
        {
            return 0.0;
        }
    }
    for v in p {
        if let Some(d2) = interior_distance2(v, q, nq) {
            best = best.min(d2);
        }
    }
    for v in q {
        if let Some(d2) = interior_distance2(v, p, np) {
            best = best.min(d2);
        }
    }
    best
}

/// Whether `x` (assumed on the plane of `t`) lies inside triangle `t` of normal `n`.
#[inline]
fn inside(x: &Point3<f64>, t: &[Point3<f64>; 3], n: &Vector3<f64>) -> bool {
    (t[1] - t[0]).cross(&(x - t[0])).dot(n) >= 0.0
        && (t[2] - t[1]).cross(&(x - t[1])).dot(n) >= 0.0
        && (t[0] - t[2]).cross(&(x - t[2])).dot(n) >= 0.0
}

/// Whether segment `s0 s1` properly crosses the plane of `t` inside `t` (not coplanar).
#[inline]
fn segment_crosses_triangle(
    s0: &Point3<f64>,
    s1: &Point3<f64>,
    t: &[Point3<f64>; 3],
    n: &Vector3<f64>,
) -> bool {
    let d0 = n.dot(&(s0 - t[0]));
    let d1 = n.dot(&(s1 - t[0]));
    if (d0 > 0.0 && d1 > 0.0) || (d0 < 0.0 && d1 < 0.0) || d0 == d1 {
        return false;
    }
    let x = s0 + (s1 - s0) * (d0 / (d0 - d1));
    inside(&x, t, n)
}

/// Squared distance from `v` to triangle `t` when the projection of `v` falls inside `t`.
#[inline]
fn interior_distance2(v: &Point3<f64>, t: &[Point3<f64>; 3], n: &Vector3<f64>) -> Option<f64> {
    let nn = n.norm_squared();
    if nn.is_nan() || nn <= 0.0 {
        return None;
    }
    let h = n.dot(&(v - t[0]));
    let x = v - n * (h / nn);
    inside(&x, t, n).then(|| h * h / nn)
}

/// Closest points of segments `p0 p1` and `q0 q1` (Ericson, *Real-Time Collision
/// Detection*, 2005, Sec. 5.1.9), degenerate segments included.
#[inline]
fn segment_closest_points(
    p0: &Point3<f64>,
    p1: &Point3<f64>,
    q0: &Point3<f64>,
    q1: &Point3<f64>,
) -> (Point3<f64>, Point3<f64>) {
    let d1 = p1 - p0;
    let d2 = q1 - q0;
    let r = p0 - q0;
    let a = d1.norm_squared();
    let e = d2.norm_squared();
    let f = d2.dot(&r);
    let (s, t);
    if a <= f64::MIN_POSITIVE && e <= f64::MIN_POSITIVE {
        return (*p0, *q0);
    }
    if a <= f64::MIN_POSITIVE {
        s = 0.0;
        t = (f / e).clamp(0.0, 1.0);
    } else {
        let c = d1.dot(&r);
        if e <= f64::MIN_POSITIVE {
            t = 0.0;
            s = (-c / a).clamp(0.0, 1.0);
        } else {
            let b = d1.dot(&d2);
            let denom = a * e - b * b;
            let s0 = if denom > 0.0 {
                ((b * f - c * e) / denom).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let t0 = (b * s0 + f) / e;
            if t0 < 0.0 {
                t = 0.0;
                s = (-c / a).clamp(0.0, 1.0);
            } else if t0 > 1.0 {
                t = 1.0;
                s = ((b - c) / a).clamp(0.0, 1.0);
            } else {
                t = t0;
                s = s0;
            }
        }
    }
    (p0 + d1 * s, q0 + d2 * t)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Axis-aligned box mesh (12 triangles, outward normals).
    fn cube(min: [f64; 3], size: [f64; 3]) -> (Vec<Point3<f64>>, Vec<[u32; 3]>) {
        let mut v = Vec::new();
        for i in 0..8u32 {
            v.push(Point3::new(
                min[0] + size[0] * f64::from(i & 1),
                min[1] + size[1] * f64::from((i >> 1) & 1),
                min[2] + size[2] * f64::from((i >> 2) & 1),
            ));
        }
        let f = vec![
            [0, 2, 1],
            [1, 2, 3],
            [4, 5, 6],
            [5, 7, 6],
            [0, 1, 4],
            [1, 5, 4],
            [2, 6, 3],
            [3, 6, 7],
            [0, 4, 2],
            [2, 4, 6],
            [1, 3, 5],
            [3, 7, 5],
        ];
        (v, f)
    }

    fn bvh(m: &(Vec<Point3<f64>>, Vec<[u32; 3]>)) -> MeshBvh {
        MeshBvh::new(&m.0, &m.1).expect("valid mesh")
    }

    /// Tiny deterministic generator (xorshift64*), values in [0, 1).
    struct Rng(u64);
    impl Rng {
        fn next(&mut self) -> f64 {
            self.0 ^= self.0 >> 12;
            self.0 ^= self.0 << 25;
            self.0 ^= self.0 >> 27;
            (self.0.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 11) as f64 / (1u64 << 53) as f64
        }
        fn point(&mut self, s: f64) -> Point3<f64> {
            Point3::new(self.next() * s, self.next() * s, self.next() * s)
        }
    }

    #[test]
    fn cubes_at_gap_pair_iff_gap_within_tolerance() {
        // Dyadic values: `1 + gap` is exact, so `gap == tol` is on the boundary.
        let tol = 0.25;
        for &gap in &[0.0, 0.125, 0.2421875, 0.25, 0.2578125, 0.5, 3.0] {
            let a = bvh(&cube([0.0, 0.0, 0.0], [1.0, 1.0, 1.0]));
            let b = bvh(&cube([1.0 + gap, 0.3, -0.2], [1.0, 1.0, 1.0]));
            let pairs = contact_pairs(&[a.clone(), b.clone()], tol).expect("ok");
            assert_eq!(pairs.len(), usize::from(gap <= tol), "gap {gap}");
            if let Some(p) = pairs.first() {
                assert_eq!((p.i, p.j), (0, 1));
                assert!((p.distance - gap).abs() < 1e-12, "{} vs {gap}", p.distance);
            }
            let d = mesh_distance(&a, &b).expect("ok");
            assert!((d - gap).abs() < 1e-12, "{d} vs {gap}");
        }
    }

    #[test]
    fn touching_and_intersecting_are_zero() {
        let a = bvh(&cube([0.0, 0.0, 0.0], [1.0, 1.0, 1.0]));
        // Shares a face patch.
        let touching = bvh(&cube([1.0, 0.5, 0.5], [1.0, 1.0, 1.0]));
        // Overlaps: surfaces cross.
        let crossing = bvh(&cube([0.5, 0.5, 0.5], [1.0, 1.0, 1.0]));
        // Touches only along an edge.
        let edge = bvh(&cube([1.0, 1.0, 0.2], [1.0, 1.0, 0.5]));
        for m in [&touching, &crossing, &edge] {
            assert_eq!(mesh_distance(&a, m).expect("ok"), 0.0);
            assert_eq!(distance_within(&a, m, 0.0), Some(0.0));
        }
        let pairs = contact_pairs(&[a, touching, crossing], 0.0).expect("ok");
        let ij: Vec<_> = pairs.iter().map(|p| (p.i, p.j)).collect();
        assert_eq!(ij, vec![(0, 1), (0, 2), (1, 2)]);
        assert!(pairs.iter().all(|p| p.distance == 0.0));
    }

    #[test]
    fn nested_box_is_at_surface_distance() {
        let outer = bvh(&cube([0.0, 0.0, 0.0], [1.0, 1.0, 1.0]));
        let inner = bvh(&cube([0.3, 0.4, 0.2], [0.2, 0.2, 0.2]));
        let d = mesh_distance(&outer, &inner).expect("ok");
        assert!((d - 0.2).abs() < 1e-12, "{d}");
    }

    #[test]
    fn far_apart_is_absent() {
        let a = bvh(&cube([0.0, 0.0, 0.0], [1.0, 1.0, 1.0]));
        let b = bvh(&cube([10.0, 10.0, 10.0], [1.0, 1.0, 1.0]));
        assert!(contact_pairs(&[a.clone(), b.clone()], 1.0)
            .expect("ok")
            .is_empty());
        assert_eq!(distance_within(&a, &b, 1.0), None);
        let d = mesh_distance(&a, &b).expect("ok");
        assert!((d - 9.0 * 3f64.sqrt()).abs() < 1e-12);
        // `tolerance²` overflows: no pair is reported beyond the tolerance.
        let huge = bvh(&cube([0.0; 3], [1e200; 3]));
        let huge_far = bvh(&cube([3e200, 0.0, 0.0], [1e200; 3]));
        assert!(contact_pairs(&[huge, huge_far], 1e160)
            .expect("ok")
            .is_empty());
    }

    #[test]
    fn diagonal_gap_between_corners() {
        let a = bvh(&cube([0.0, 0.0, 0.0], [1.0, 1.0, 1.0]));
        let b = bvh(&cube([1.1, 1.2, 1.3], [1.0, 1.0, 1.0]));
        let want = (0.01f64 + 0.04 + 0.09).sqrt();
        assert!((mesh_distance(&a, &b).expect("ok") - want).abs() < 1e-12);
    }

    #[test]
    fn broad_phase_matches_brute_force_on_random_boxes() {
        let mut rng = Rng(0x9E37_79B9_7F4A_7C15);
        let boxes: Vec<Aabb> = (0..300)
            .map(|_| {
                let c = rng.point(10.0);
                let s = rng.point(1.0);
                Aabb::new(c, c + s.coords)
            })
            .collect();
        for &tol in &[0.0, 0.1, 0.7] {
            let refs: Vec<Option<Aabb>> = boxes.iter().copied().map(Some).collect();
            let mut got = broad_phase(&refs, tol);
            got.sort_unstable();
            let mut want = Vec::new();
            for i in 0..boxes.len() {
                for j in i + 1..boxes.len() {
                    if box_distance2(&boxes[i], &boxes[j]) <= tol * tol {
                        want.push((i, j));
                    }
                }
            }
            assert!(!want.is_empty());
            assert_eq!(got, want, "tol {tol}");
        }
    }

    #[test]
    fn contact_pairs_match_brute_force_on_random_boxes() {
        let mut rng = Rng(42);
        let meshes: Vec<_> = (0..60)
            .map(|_| {
                let c = rng.point(4.0);
                let s = rng.point(0.8);
                cube([c.x, c.y, c.z], [s.x + 0.05, s.y + 0.05, s.z + 0.05])
            })
            .collect();
        let bvhs: Vec<MeshBvh> = meshes.iter().map(bvh).collect();
        let tris: Vec<TriMesh> = meshes
            .iter()
            .map(|(v, f)| TriMesh::new(v.clone(), f.clone(), "m").expect("valid"))
            .collect();
        let tol = 0.1;
        let got = contact_pairs_of_meshes(&tris, tol).expect("ok");
        assert_eq!(got, contact_pairs(&bvhs, tol).expect("ok"));
        let mut want = Vec::new();
        for i in 0..bvhs.len() {
            for j in i + 1..bvhs.len() {
                let d = mesh_distance(&bvhs[i], &bvhs[j]).expect("ok");
                if d <= tol {
                    want.push((i, j, d));
                }
            }
        }
        assert!(want.len() > 5);
        assert_eq!(got.len(), want.len());
        for (g, w) in got.iter().zip(&want) {
            assert_eq!((g.i, g.j), (w.0, w.1));
            assert!((g.distance - w.2).abs() < 1e-12);
        }
    }

    #[test]
    fn broad_phase_boxes_are_the_hierarchy_root_boxes() {
        // contact_pairs_of_meshes decides which hierarchies to build from these boxes: they
        // must be exactly the root boxes, unreferenced vertices and tiny coordinates included.
        let mut rng = Rng(7);
        for n in [0usize, 1, 2, 17, 300] {
            let mut v: Vec<Point3<f64>> = (0..n + 3).map(|_| rng.point(3.0)).collect();
            v.push(Point3::new(1e-200, -1e-170, 50.0)); // never referenced
            v[0] = Point3::new(1e-160, 2.0, -1e-155);
            let f: Vec<[u32; 3]> = (0..n)
                .map(|k| [k as u32, (k + 1) as u32, (k + 2) as u32])
                .collect();
            let m = TriMesh::new(v, f, "m").expect("valid");
            for scale in [1.0, 0.25, 1024.0] {
                let root = MeshBvh::from_mesh_scaled(&m, scale).root_aabb();
                assert_eq!(scaled_aabb(&m, scale), root, "n = {n}, scale = {scale}");
            }
        }
    }

    #[test]
    fn bvh_distance_matches_triangle_brute_force_and_parry() {
        use parry3d_f64::query;
        use parry3d_f64::shape::TriMesh;
        let mut rng = Rng(7);
        for trial in 0..20 {
            let soup = |rng: &mut Rng, off: f64| {
                let mut v = Vec::new();
                let mut f = Vec::new();
                for k in 0..40u32 {
                    let c = rng.point(1.0) + Vector3::new(off, 0.0, 0.0);
                    for _ in 0..3 {
                        v.push(c + (rng.point(0.3) - Point3::new(0.15, 0.15, 0.15)));
                    }
                    f.push([3 * k, 3 * k + 1, 3 * k + 2]);
                }
                (v, f)
            };
            let ma = soup(&mut rng, 0.0);
            let mb = soup(&mut rng, 0.6 + 0.05 * f64::from(trial));
            let (a, b) = (bvh(&ma), bvh(&mb));
            let got = mesh_distance(&a, &b).expect("ok");
            let mut brute = f64::INFINITY;
            let tris = |m: &MeshBvh| -> Vec<[Point3<f64>; 3]> {
                m.triangles.iter().map(|t| t.0).collect()
            };
            for ta in &tris(&a) {
                for tb in &tris(&b) {
                    brute = brute.min(triangle_distance2(ta, tb).sqrt());
                }
            }
            assert_eq!(got, brute);
            let pa = TriMesh::new(ma.0.clone(), ma.1.clone()).expect("parry mesh");
            let pb = TriMesh::new(mb.0.clone(), mb.1.clone()).expect("parry mesh");
            let id = nalgebra::Isometry3::identity();
            let want = query::distance(&id, &pa, &id, &pb).expect("supported");
            assert!(
                (got - want).abs() < 1e-9,
                "trial {trial}: {got} vs parry {want}"
            );
        }
    }

    #[test]
    fn triangle_distance_cases() {
        let t = [
            Point3::new(0.0, 0.0, 0.0),
            Point3::new(1.0, 0.0, 0.0),
            Point3::new(0.0, 1.0, 0.0),
        ];
        // Parallel triangle above: vertex-face distance.
        let up = t.map(|p| p + Vector3::new(0.1, 0.1, 0.5));
        assert!((triangle_distance2(&t, &up) - 0.25).abs() < 1e-15);
        // Piercing triangle: 0.
        let pierce = [
            Point3::new(0.2, 0.2, -1.0),
            Point3::new(0.3, 0.2, 1.0),
            Point3::new(0.2, 0.3, 1.0),
        ];
        assert_eq!(triangle_distance2(&t, &pierce), 0.0);
        // Coplanar, one inside the other: 0.
        let inner = [
            Point3::new(0.1, 0.1, 0.0),
            Point3::new(0.2, 0.1, 0.0),
            Point3::new(0.1, 0.2, 0.0),
        ];
        assert_eq!(triangle_distance2(&t, &inner), 0.0);
        // Degenerate (a segment, a point) triangles.
        let seg = [
            Point3::new(2.0, 0.0, 0.0),
            Point3::new(3.0, 0.0, 0.0),
            Point3::new(2.5, 0.0, 0.0),
        ];
        assert!((triangle_distance2(&t, &seg) - 1.0).abs() < 1e-15);
        let pt = [Point3::new(0.2, 0.2, 0.7); 3];
        assert!((triangle_distance2(&t, &pt) - 0.49).abs() < 1e-15);
        assert!((triangle_distance2(&pt, &t) - 0.49).abs() < 1e-15);
    }

    #[test]
    fn degenerate_meshes_do_not_panic() {
        let p = Point3::new(0.5, 0.5, 0.5);
        // Zero-area triangles and duplicate vertices only.
        let v = vec![p, p, p, Point3::new(1.5, 0.5, 0.5)];
        let f = vec![[0, 1, 2], [0, 0, 3], [3, 3, 3]];
        let m = MeshBvh::new(&v, &f).expect("accepted");
        let c = bvh(&cube([0.0, 0.0, 0.0], [1.0, 1.0, 1.0]));
        assert_eq!(mesh_distance(&c, &m).expect("ok"), 0.0);
        let far = MeshBvh::new(&[p; 3], &[[0, 1, 2]]).expect("accepted");
        assert!((mesh_distance(&c, &far).expect("ok") - 0.5).abs() < 1e-15);
        // Many identical triangles: the build must terminate with leaves > LEAF_SIZE.
        let same = MeshBvh::new(&v, &vec![[0, 1, 3]; 100]).expect("accepted");
        assert_eq!(same.num_triangles(), 100);
        assert_eq!(mesh_distance(&same, &c).expect("ok"), 0.0);
        // Empty meshes pair with nothing; mesh_distance refuses them.
        let empty = MeshBvh::new(&[], &[]).expect("accepted");
        assert!(empty.is_empty());
        assert!(contact_pairs(&[empty.clone(), c.clone()], 1.0)
            .expect("ok")
            .is_empty());
        assert!(matches!(
            mesh_distance(&empty, &c),
            Err(GeometryError::Degenerate(_))
        ));
    }

    #[test]
    fn bad_inputs_are_errors() {
        let (v, f) = cube([0.0; 3], [1.0; 3]);
        let mut bad = v.clone();
        bad[2].y = f64::NAN;
        assert!(matches!(
            MeshBvh::new(&bad, &f),
            Err(GeometryError::NonFinite { index: 7, .. })
        ));
        assert!(matches!(
            MeshBvh::new(&v, &[[0, 1, 8]]),
            Err(GeometryError::IndexOutOfRange {
                face: 0,
                vertex: 8,
                ..
            })
        ));
        let m = bvh(&(v, f));
        for tol in [-1.0, f64::NAN, f64::INFINITY] {
            assert!(matches!(
                contact_pairs(std::slice::from_ref(&m), tol),
                Err(GeometryError::Invalid(_))
            ));
        }
        let err = MeshBvh::with_name(&bad, &[[0, 1, 2]], "meshes[3]");
        assert!(err
            .expect_err("NaN")
            .to_string()
            .contains("meshes[3] vertices"));
    }

    #[test]
    fn distances_are_scale_robust() {
        let tri = |m: &(Vec<Point3<f64>>, Vec<[u32; 3]>), s: f64| {
            let v = m.0.iter().map(|p| p * s).collect();
            TriMesh::new(v, m.1.clone(), "m").expect("valid")
        };
        let a = cube([0.0; 3], [1.0; 3]);
        let b = cube([1.5, 0.0, 0.0], [1.0; 3]);
        for s in [1.0, 1e200, 1e-300, 1e300, 3e-310] {
            let (ta, tb) = (tri(&a, s), tri(&b, s));
            let d = mesh_distance_of_meshes(&ta, &tb).expect("ok");
            assert!((d / (0.5 * s) - 1.0).abs() < 1e-9, "scale {s}: {d}");
            let pairs = contact_pairs_of_meshes(&[ta.clone(), tb.clone()], 0.6 * s).expect("ok");
            assert_eq!(pairs.len(), 1, "scale {s}");
            assert!((pairs[0].distance / (0.5 * s) - 1.0).abs() < 1e-9);
            assert!(contact_pairs_of_meshes(&[ta, tb], 0.4 * s)
                .expect("ok")
                .is_empty());
        }
    }
}
