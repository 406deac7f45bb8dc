//! Exact-predicate 3D convex hull (incremental, with conflict lists).
//!
//! Every combinatorial decision (is a point strictly above a face's plane? are three
//! points collinear? are four points coplanar?) is taken with Shewchuk's adaptive exact
//! predicates (`robust` crate: J. R. Shewchuk, *Adaptive Precision Floating-Point
//! Arithmetic and Fast Robust Geometric Predicates*, DCG 18, 1997). The hull is therefore
//! combinatorially consistent for any finite input: coplanar, collinear, duplicated or
//! nearly degenerate points never corrupt it, and nothing panics. Floating-point values
//! are only used to choose *which* outside point to add next (the farthest), which
//! affects speed, never correctness.
//!
//! The algorithm is the randomized-incremental / Quickhull scheme (Barber, Dobkin &
//! Huhdanpaa, *The Quickhull algorithm for convex hulls*, ACM TOMS 22, 1996): every point
//! outside the current hull is kept in the conflict list of one face that sees it; the
//! farthest point of a face is added by removing the faces it strictly sees (a
//! topological disk) and coning the horizon to it; the conflict points of the removed
//! faces are re-assigned to the new faces or dropped (a point outside the new hull that
//! saw a removed face always sees a new face). Points lying on the hull boundary (on a
//! face plane) are not hull vertices.
//!
//! **Why own code, not `parry3d_f64::transformation::convex_hull`:** parry's Quickhull
//! decides visibility with floating-point tolerances after normalising the points, and
//! refuses exactly collinear or coplanar sets. Tried as a drop-in (November 2026), it
//! returned an invalid hull for a thin part of the shared PartNet-Mobility data
//! (`102890/original-521.obj`, 27 points: 9 hull vertices, input points up to `1.4e-2`
//! units outside its faces), which made that part's OBB 2% larger than trimesh's and
//! failed the OBB containment/tightness test. The OBB needs a hull that is exactly
//! consistent on near-degenerate PartNet panels, which only exact predicates give.

use std::collections::HashMap;

use nalgebra::{Point3, Vector3};
use robust::{orient2d, orient3d, Coord, Coord3D};

/// What the convex hull of a point set is, by (exact) affine dimension.
#[derive(Debug, Clone)]
pub(crate) enum HullShape {
    /// All points are equal.
    Point,
    /// All points lie (exactly) on a line; the indices of two distinct points on it.
    Collinear([usize; 2]),
    /// All points lie (exactly) on a plane; the indices of three non-collinear points.
    Coplanar([usize; 3]),
    /// A full-dimensional hull.
    Solid(Hull),
}

/// A full-dimensional convex hull.
#[derive(Debug, Clone)]
pub(crate) struct Hull {
    /// Indices of the hull vertices in the input slice, ascending.
    pub vertices: Vec<usize>,
    /// Triangles (input indices), counter-clockwise seen from outside.
    pub faces: Vec<[usize; 3]>,
}

#[inline]
fn c3(p: &Point3<f64>) -> Coord3D<f64> {
    Coord3D {
        x: p.x,
        y: p.y,
        z: p.z,
    }
}

/// `true` when `d` is strictly on the outer side of the plane of the counter-clockwise
/// (seen from outside) triangle `a, b, c` (exact).
#[inline]
fn above(a: &Point3<f64>, b: &Point3<f64>, c: &Point3<f64>, d: &Point3<f64>) -> bool {
    // Shewchuk's orient3d is positive when `d` is *below* the plane of (a, b, c).
    orient3d(c3(a), c3(b), c3(c), c3(d)) < 0.0
}

/// Exact test: are `a`, `b`, `c` collinear? (The cross product vanishes exactly iff its
/// three components, the orientations of the three coordinate-plane projections, do.)
pub(crate) fn collinear(a: &Point3<f64>, b: &Point3<f64>, c: &Point3<f64>) -> bool {
    let xy = |p: &Point3<f64>| Coord { x: p.x, y: p.y };
    let yz = |p: &Point3<f64>| Coord { x: p.y, y: p.z };
    let zx = |p: &Point3<f64>| Coord { x: p.z, y: p.x };
    orient2d(xy(a), xy(b), xy(c)) == 0.0
        && orient2d(yz(a), yz(b), yz(c)) == 0.0
        && orient2d(zx(a), zx(b), zx(c)) == 0.0
}

#[derive(Debug, Clone)]
struct Face {
    v: [usize; 3],
    /// `adj[i]` is the face across the edge `v[i] -> v[(i + 1) % 3]`.
    adj: [usize; 3],
    /// Unnormalised outward normal and offset, only used to rank outside points.
    normal: Vector3<f64>,
    offset: f64,
    alive: bool,
    outside: Vec<usize>,
}

impl Face {
    fn new(v: [usize; 3], pts: &[Point3<f64>]) -> Self {
        let (a, b, c) = (pts[v[0]], pts[v[1]], pts[v[2]]);
        let normal = (b - a).cross(&(c - a));
        Face {
            v,
            adj: [usize::MAX; 3],
            normal,
            offset: normal.dot(&a.coords),
            alive: true,
            outside: Vec::new(),
        }
    }

    #[inline]
    fn sees(&self, p: usize, pts: &[Point3<f64>]) -> bool {
        above(&pts[self.v[0]], &pts[self.v[1]], &pts[self.v[2]], &pts[p])
    }

    #[inline]
    fn distance(&self, p: &Point3<f64>) -> f64 {
        self.normal.dot(&p.coords) - self.offset
    }
}

/// The index of the point of `idx` farthest from `f` (first on ties).
fn farthest(idx: impl Iterator<Item = usize>, f: impl Fn(usize) -> f64) -> Option<usize> {
    let mut best: Option<(usize, f64)> = None;
    for i in idx {
        let d = f(i);
        if best.is_none_or(|(_, bd)| d > bd) {
            best = Some((i, d));
        }
    }
    best.map(|(i, _)| i)
}

/// Classify the affine dimension of `pts` and pick a well-spread initial simplex.
fn initial_simplex(pts: &[Point3<f64>]) -> std::result::Result<[usize; 4], HullShape> {
    // Two far-apart points among the six coordinate-extreme points.
    let mut ext = [0usize; 6];
    for (i, p) in pts.iter().enumerate() {
        for k in 0..3 {
            if p[k] < pts[ext[2 * k]][k] {
                ext[2 * k] = i;
            }
            if p[k] > pts[ext[2 * k + 1]][k] {
                ext[2 * k + 1] = i;
            }
        }
    }
    let (mut i0, mut i1, mut best) = (ext[0], ext[1], -1.0);
    for a in 0..6 {
        for b in a + 1..6 {
            let d = (pts[ext[a]] - pts[ext[b]]).norm_squared();
            if d > best {
                (i0, i1, best) = (ext[a], ext[b], d);
            }
        }
    }
    if best <= 0.0 {
        return Err(HullShape::Point);
    }
    let (p0, p1) = (pts[i0], pts[i1]);
    let dir = p1 - p0;
    // Farthest point from the line; fall back to any exactly non-collinear point.
    let line_dist = |i: usize| (pts[i] - p0).cross(&dir).norm_squared();
    let mut i2 = farthest(0..pts.len(), line_dist).unwrap_or(0);
    if collinear(&p0, &p1, &pts[i2]) {
        match (0..pts.len()).find(|&i| !collinear(&p0, &p1, &pts[i])) {
            Some(i) => i2 = i,
            None => return Err(HullShape::Collinear([i0, i1])),
        }
    }
    let p2 = pts[i2];
    let n = (p1 - p0).cross(&(p2 - p0));
    let plane_dist = |i: usize| n.dot(&(pts[i] - p0)).abs();
    let mut i3 = farthest(0..pts.len(), plane_dist).unwrap_or(0);
    if orient3d(c3(&p0), c3(&p1), c3(&p2), c3(&pts[i3])) == 0.0 {
        match (0..pts.len()).find(|&i| orient3d(c3(&p0), c3(&p1), c3(&p2), c3(&pts[i])) != 0.0) {
            Some(i) => i3 = i,
            None => return Err(HullShape::Coplanar([i0, i1, i2])),
        }
    }
    Ok([i0, i1, i2, i3])
}

/// Link the `adj` fields of `faces[ids]` by matching opposite half-edges.
fn link(faces: &mut [Face], ids: &[usize]) {
    let mut half: HashMap<(usize, usize), (usize, usize)> = HashMap::new();
    for &f in ids {
        for e in 0..3 {
            half.insert((faces[f].v[e], faces[f].v[(e + 1) % 3]), (f, e));
        }
    }
    for &f in ids {
        for e in 0..3 {
            let (a, b) = (faces[f].v[e], faces[f].v[(e + 1) % 3]);
            if let Some(&(g, _)) = half.get(&(b, a)) {
                faces[f].adj[e] = g;
            }
        }
    }
}

/// The exact convex hull of `pts` (finite coordinates), classified by dimension.
///
/// Returns `None` only if an internal invariant is found broken (which exact predicates
/// should make impossible); callers then fall back to using all points.
pub(crate) fn convex_hull(pts: &[Point3<f64>]) -> Option<HullShape> {
    if pts.is_empty() {
        return None;
    }
    let simplex = match initial_simplex(pts) {
        Ok(s) => s,
        Err(shape) => return Some(shape),
    };
    let mut faces: Vec<Face> = Vec::new();
    for omit in 0..4 {
        let mut tri = [0usize; 3];
        let mut k = 0;
        for (j, &s) in simplex.iter().enumerate() {
            if j != omit {
                tri[k] = s;
                k += 1;
            }
        }
        // Orient so that the omitted vertex is strictly inside.
        if above(
            &pts[tri[0]],
            &pts[tri[1]],
            &pts[tri[2]],
            &pts[simplex[omit]],
        ) {
            tri.swap(1, 2);
        }
        faces.push(Face::new(tri, pts));
    }
    link(&mut faces, &[0, 1, 2, 3]);
    for p in 0..pts.len() {
        if simplex.contains(&p) {
            continue;
        }
        if let Some(f) = (0..4).find(|&f| faces[f].sees(p, pts)) {
            faces[f].outside.push(p);
        }
    }

    let mut stamp: Vec<u32> = vec![0; faces.len()];
    let mut round = 0u32;
    let mut visible: Vec<usize> = Vec::new();
    let mut stack: Vec<usize> = Vec::new();
    let mut horizon: Vec<(usize, usize, usize)> = Vec::new(); // (a, b, outer face)
    let mut i = 0;
    while i < faces.len() {
        if !faces[i].alive || faces[i].outside.is_empty() {
            i += 1;
            continue;
        }
        let face = &faces[i];
        let apex = farthest(face.outside.iter().copied(), |p| face.distance(&pts[p]))?;
        // Visible region: flood fill from face i over faces that strictly see the apex.
        round += 1;
        stamp.resize(faces.len(), 0);
        visible.clear();
        horizon.clear();
        stack.clear();
        stack.push(i);
        stamp[i] = round;
        while let Some(f) = stack.pop() {
            visible.push(f);
            for e in 0..3 {
                let g = faces[f].adj[e];
                let gf = faces.get(g)?;
                if stamp[g] == round {
                    continue;
                }
                if gf.alive && gf.sees(apex, pts) {
                    stamp[g] = round;
                    stack.push(g);
                }
            }
        }
        // Horizon edges: visible face edges whose neighbour is not visible.
        for &f in &visible {
            for e in 0..3 {
                let g = faces[f].adj[e];
                if stamp[g] != round {
                    horizon.push((faces[f].v[e], faces[f].v[(e + 1) % 3], g));
                }
            }
        }
        // Cone the horizon to the apex.
        let first_new = faces.len();
        let mut by_start: HashMap<usize, usize> = HashMap::with_capacity(horizon.len());
        for (k, &(a, b, outer)) in horizon.iter().enumerate() {
            let id = first_new + k;
            let mut nf = Face::new([a, b, apex], pts);
            nf.adj[0] = outer;
            // Re-link the outer face's half-edge (b, a) to the new face.
            let of = faces.get_mut(outer)?;
            let e = (0..3).find(|&e| of.v[e] == b && of.v[(e + 1) % 3] == a)?;
            of.adj[e] = id;
            faces.push(nf);
            if by_start.insert(a, id).is_some() {
                return None; // horizon is not a simple cycle
            }
        }
        for (k, &(_, b, _)) in horizon.iter().enumerate() {
            let id = first_new + k;
            // Edge (b, apex) meets the new face starting at b; edge (apex, a) meets the
            // new face ending at a, whose edge (a, apex) is its edge 1.
            let next = *by_start.get(&b)?;
            faces[id].adj[1] = next;
            faces[next].adj[2] = id;
        }
        // Retire the visible faces and re-assign their conflict points.
        let mut orphans: Vec<usize> = Vec::new();
        for &f in &visible {
            faces[f].alive = false;
            orphans.append(&mut faces[f].outside);
        }
        let new_ids = first_new..faces.len();
        for p in orphans {
            if p == apex {
                continue;
            }
            if let Some(f) = new_ids.clone().find(|&f| faces[f].sees(p, pts)) {
                faces[f].outside.push(p);
            }
        }
        i += 1;
    }

    let out: Vec<[usize; 3]> = faces.iter().filter(|f| f.alive).map(|f| f.v).collect();
    let mut vertices: Vec<usize> = out.iter().flatten().copied().collect();
    vertices.sort_unstable();
    vertices.dedup();
    Some(HullShape::Solid(Hull {
        vertices,
        faces: out,
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lcg(seed: &mut u64) -> f64 {
        *seed = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((*seed >> 11) as f64) / ((1u64 << 53) as f64)
    }

    fn check_hull(pts: &[Point3<f64>], hull: &Hull) {
        // Euler characteristic of a closed triangulated sphere: V - E + F = 2, E = 3F/2.
        let f = hull.faces.len();
        assert_eq!(hull.vertices.len() + f - 3 * f / 2, 2);
        // Every point is on or below every face (exact).
        for t in &hull.faces {
            for p in pts {
                assert!(!above(&pts[t[0]], &pts[t[1]], &pts[t[2]], p));
            }
        }
    }

    #[test]
    fn random_cloud_hull_is_closed_and_contains_points() {
        let mut s = 7;
        let pts: Vec<Point3<f64>> = (0..500)
            .map(|_| Point3::new(lcg(&mut s), lcg(&mut s), lcg(&mut s)))
            .collect();
        match convex_hull(&pts) {
            Some(HullShape::Solid(h)) => check_hull(&pts, &h),
            other => panic!("expected a solid hull, got {other:?}"),
        }
    }

    #[test]
    fn grid_with_many_coplanar_points() {
        // A 6x6x6 lattice: hugely degenerate (coplanar faces, collinear edges).
        let mut pts = Vec::new();
        for i in 0..6 {
            for j in 0..6 {
                for k in 0..6 {
                    pts.push(Point3::new(i as f64, j as f64 * 0.5, k as f64 * 0.25));
                }
            }
        }
        match convex_hull(&pts) {
            Some(HullShape::Solid(h)) => {
                check_hull(&pts, &h);
                assert_eq!(h.vertices.len(), 8, "only the corners are vertices");
            }
            other => panic!("expected a solid hull, got {other:?}"),
        }
    }

    #[test]
    fn dimensions_are_classified_exactly() {
        let p = |x, y, z| Point3::new(x, y, z);
        assert!(matches!(
            convex_hull(&[p(1., 2., 3.); 4]),
            Some(HullShape::Point)
        ));
        let line: Vec<_> = (0..5).map(|i| p(i as f64, 2.0 * i as f64, 1.0)).collect();
        assert!(matches!(convex_hull(&line), Some(HullShape::Collinear(_))));
        let plane: Vec<_> = (0..9)
            .map(|i| p((i % 3) as f64, 0.5, (i / 3) as f64))
            .collect();
        assert!(matches!(convex_hull(&plane), Some(HullShape::Coplanar(_))));
        assert!(convex_hull(&[]).is_none());
    }
}
