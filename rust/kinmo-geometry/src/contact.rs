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
#[path = "contact_tests.rs"]
mod tests;
