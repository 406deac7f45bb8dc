//! Convex pieces of a concave mesh: the export's `parts` collision geometry (issue 35).
//!
//! A leaf mesh (one PartNet `textured_objs/*.obj` part) gets its convex hull, unless the
//! hull is concave: some point sampled on it lies farther than a tolerance from the mesh's
//! surface, i.e. the hull fills a slot, a shell or the inside of a frame that another part
//! may move into. A concave mesh is split into its connected components (faces sharing a
//! vertex position) when it has 2 to `max_components` of them; otherwise, and for every
//! concave piece below, it is cut in two by the plane through the middle of its face
//! centroids, across their principal axis, at most `max_depth` cuts deep. Each piece is
//! checked the same way; one no larger than the tolerance is kept whole. Every face lies in
//! exactly one piece. A flat piece becomes the hull of its points moved half a slab
//! thickness to both sides of its plane (a prism following its outline).
//!
//! [`concave_pieces`] is `kinmo.export.collision.concave_parts`' loop over the pieces of
//! one leaf. Its building blocks are the crate's: the exact hull ([`crate::hull`]), the
//! seeded area sampler ([`crate::sampling`]), parry's point-to-triangle projection
//! ([`crate::proximity`]) and nalgebra's SVD.

use std::collections::HashMap;

use nalgebra::{DMatrix, Point3, Vector3};
use parry3d_f64::bounding_volume::Aabb;

use crate::error::{GeometryError, Result};
use crate::hull::convex_hull;
use crate::mesh::TriMesh;
use crate::proximity::any_farther_than;
use crate::sampling::sample_surface;

/// Settings of [`concave_pieces`] (the constants of `kinmo.export.collision`).
#[derive(Debug, Clone, PartialEq)]
pub struct SplitParams {
    /// A piece is concave when a point of its hull lies farther than this from its surface
    /// (absolute, mesh units; `> 0`, else nothing is split).
    pub tolerance: f64,
    /// Most plane cuts on the way from the mesh to one of its pieces.
    pub max_depth: u32,
    /// A concave mesh of more connected components than this is cut by planes instead.
    pub max_components: usize,
    /// Points sampled on each hull for the concavity test (seed 0).
    pub hull_samples: usize,
    /// A point set is flat when its smallest singular value is at most this share of its
    /// largest (`kinmo.export.kinematics.FLAT_RELATIVE`).
    pub flat_relative: f64,
    /// A flat piece's prism thickness, as a share of its largest extent
    /// (`kinmo.export.kinematics.SLAB_THICKNESS`).
    pub slab_thickness: f64,
}

/// A convex piece: its corner points and triangles (outward, counter-clockwise).
pub type Piece = (Vec<Point3<f64>>, Vec<[u32; 3]>);

/// The convex pieces of one mesh, each with the faces of the mesh it covers.
///
/// Returns `(piece, faces)` pairs in depth-first order (components in order of their first
/// face, the lower half of a cut first): `faces` are ascending indices into `faces`, and
/// together they cover every face with area exactly once. A piece is the exact hull of
/// its faces' vertices (corner points in ascending vertex order), or for a flat face set
/// the prism described in the module docs. A face set without volume or area (a point, a
/// segment) has no piece and is left out.
///
/// # Errors
/// [`GeometryError::NonFinite`] for a NaN or infinite vertex of a face (other vertices
/// are not read),
/// [`GeometryError::IndexOutOfRange`] for a face naming a missing vertex,
/// [`GeometryError::Invalid`] for `hull_samples == 0` or a negative or NaN tolerance.
pub fn concave_pieces(
    vertices: &[Point3<f64>],
    faces: &[[u32; 3]],
    params: &SplitParams,
) -> Result<Vec<(Piece, Vec<u32>)>> {
    if params.hull_samples == 0 || params.tolerance.is_nan() || params.tolerance < 0.0 {
        return Err(GeometryError::Invalid(format!(
            "concave_pieces: bad settings (tolerance {}, hull_samples {})",
            params.tolerance, params.hull_samples
        )));
    }
    // faces naming existing vertices (their finiteness: the first hull's check)
    for (i, f) in faces.iter().enumerate() {
        if let Some(&v) = f.iter().find(|&&v| v as usize >= vertices.len()) {
            return Err(GeometryError::IndexOutOfRange {
                what: "faces".to_string(),
                face: i,
                vertex: i64::from(v),
                n_vertices: vertices.len(),
            });
        }
    }
    let tol = params.tolerance;
    let mut out = Vec::new();
    // (face ids, depth); depth -1: the whole mesh, not yet split
    let mut stack: Vec<(Vec<u32>, i64)> = vec![((0..faces.len() as u32).collect(), -1)];
    while let Some((sub, depth)) = stack.pop() {
        let used = used_vertices(faces, &sub);
        let local: Vec<Point3<f64>> = used.iter().map(|&i| vertices[i as usize]).collect();
        let Some(piece) = part_piece(&local, params)? else {
            continue;
        };
        if depth < i64::from(params.max_depth)
            && sub.len() > 1
            && tol > 0.0
            && piece
                .bounds()
                .is_some_and(|(lo, hi)| (hi - lo).norm() > tol)
            && concave(local, faces, &sub, &used, &piece, params)?
        {
            if depth < 0 {
                let comps = components(vertices, faces);
                if comps.len() > 1 && comps.len() <= params.max_components {
                    stack.extend(comps.into_iter().rev().map(|c| (c, 0)));
                    continue;
                }
            }
            if let Some((lower, upper)) = split(vertices, faces, &sub) {
                let next = depth.max(0) + 1;
                stack.push((upper, next));
                stack.push((lower, next));
                continue;
            }
        }
        out.push((piece.into_parts(), sub));
    }
    Ok(out)
}

/// Sorted unique vertex ids of the faces `sub`.
fn used_vertices(faces: &[[u32; 3]], sub: &[u32]) -> Vec<u32> {
    let mut used: Vec<u32> = sub.iter().flat_map(|&f| faces[f as usize]).collect();
    used.sort_unstable();
    used.dedup();
    used
}

/// Whether a singular value `small` is at most `relative` times `large` (NaN: flat), as
/// `not small > relative * large` in `kinmo.export.collision`.
fn flat(small: f64, large: f64, relative: f64) -> bool {
    small.partial_cmp(&(relative * large)) != Some(std::cmp::Ordering::Greater)
}

/// Singular values (descending) and right singular vectors (rows) of the centred points
/// (numpy's `svd(points - mean, full_matrices=False)`; zero rows pad fewer than three
/// points, which changes neither).
fn principal(points: &[Point3<f64>], want_axes: bool) -> (Vector3<f64>, Option<[Vector3<f64>; 3]>) {
    let n = points.len() as f64;
    let centre = points.iter().fold(Vector3::zeros(), |s, p| s + p.coords) / n;
    let rows = points.len().max(3);
    let m = DMatrix::from_fn(rows, 3, |r, c| {
        points.get(r).map_or(0.0, |p| p[c] - centre[c])
    });
    let svd = m.svd(false, want_axes);
    let sv = &svd.singular_values;
    let get = |k: usize| if k < sv.len() { sv[k] } else { 0.0 };
    let values = Vector3::new(get(0), get(1), get(2));
    let axes = svd
        .v_t
        .as_ref()
        .filter(|vt| vt.nrows() == 3)
        .map(|vt| [0, 1, 2].map(|k| Vector3::new(vt[(k, 0)], vt[(k, 1)], vt[(k, 2)])));
    (values, axes)
}

/// The exact hull of `points`, corner points ascending; `None` without volume or as flat
/// as `flat_relative` counts flat (`kinmo.export.collision._hull`).
///
/// # Errors
/// [`GeometryError::NonFinite`] for a NaN or infinite point.
fn hull(points: &[Point3<f64>], flat_relative: f64) -> Result<Option<TriMesh>> {
    let Some(h) = convex_hull(points)? else {
        return Ok(None);
    };
    let mut slot = HashMap::with_capacity(h.vertices.len());
    let corners: Vec<Point3<f64>> = h
        .vertices
        .iter()
        .enumerate()
        .map(|(k, &i)| {
            slot.insert(i, k as u32);
            points[i]
        })
        .collect();
    let (sv, _) = principal(&corners, false);
    if flat(sv[2], sv[0], flat_relative) {
        return Ok(None);
    }
    let tris = h.faces.iter().map(|f| f.map(|i| slot[&i])).collect();
    Ok(Some(TriMesh::new(corners, tris, "piece")?))
}

/// The piece of one face set (`kinmo.export.collision._part_piece`): the hull of its
/// vertices `v`, or for a flat set the hull of the set thickened on both sides of its
/// plane; `None` for a point or a segment.
fn part_piece(v: &[Point3<f64>], p: &SplitParams) -> Result<Option<TriMesh>> {
    if let Some(h) = hull(v, p.flat_relative)? {
        return Ok(Some(h));
    }
    if v.len() < 2 {
        return Ok(None);
    }
    let (sv, axes) = principal(v, true);
    let Some(axes) = axes else {
        return Ok(None);
    };
    if flat(sv[1], sv[0], p.flat_relative) {
        return Ok(None);
    }
    let extent = Aabb::from_points(v.iter().copied()).extents().max();
    let offset = axes[2] * (p.slab_thickness * extent / 2.0);
    let thick: Vec<Point3<f64>> = v
        .iter()
        .map(|q| q - offset)
        .chain(v.iter().map(|q| q + offset))
        .collect();
    hull(&thick, p.flat_relative)
}

/// Whether a point of those sampled on `piece` lies farther than the tolerance from the
/// surface of the faces `sub`, whose vertex ids `used` (ascending) are at `local` (exact
/// distances).
fn concave(
    local: Vec<Point3<f64>>,
    faces: &[[u32; 3]],
    sub: &[u32],
    used: &[u32],
    piece: &TriMesh,
    p: &SplitParams,
) -> Result<bool> {
    let (on_hull, _) = sample_surface(piece, p.hull_samples, 0)?;
    let slot: HashMap<u32, u32> = used
        .iter()
        .enumerate()
        .map(|(k, &i)| (i, k as u32))
        .collect();
    let tris: Vec<[u32; 3]> = sub
        .iter()
        .map(|&f| faces[f as usize].map(|i| slot[&i]))
        .collect();
    let surface = TriMesh::new(local, tris, "faces")?;
    any_farther_than(&on_hull, &surface, p.tolerance)
}

/// Face ids of each connected component (faces sharing a vertex position), in order of
/// their first face, each ascending.
fn components(vertices: &[Point3<f64>], faces: &[[u32; 3]]) -> Vec<Vec<u32>> {
    // one id per vertex position (-0.0 and 0.0 alike)
    let key = |p: &Point3<f64>| [p.x + 0.0, p.y + 0.0, p.z + 0.0].map(f64::to_bits);
    let mut ids: HashMap<[u64; 3], usize> = HashMap::new();
    let mut of_vertex = vec![usize::MAX; vertices.len()];
    for f in faces {
        for &i in f {
            if of_vertex[i as usize] == usize::MAX {
                let n = ids.len();
                of_vertex[i as usize] = *ids.entry(key(&vertices[i as usize])).or_insert(n);
            }
        }
    }
    let mut parent: Vec<usize> = (0..ids.len()).collect();
    fn find(parent: &mut [usize], mut x: usize) -> usize {
        while parent[x] != x {
            parent[x] = parent[parent[x]];
            x = parent[x];
        }
        x
    }
    for f in faces {
        let a = find(&mut parent, of_vertex[f[0] as usize]);
        for &i in &f[1..] {
            let b = find(&mut parent, of_vertex[i as usize]);
            if a != b {
                parent[b] = a;
            }
        }
    }
    let mut order: HashMap<usize, usize> = HashMap::new();
    let mut out: Vec<Vec<u32>> = Vec::new();
    for (k, f) in faces.iter().enumerate() {
        let root = find(&mut parent, of_vertex[f[0] as usize]);
        let slot = *order.entry(root).or_insert_with(|| {
            out.push(Vec::new());
            out.len() - 1
        });
        out[slot].push(k as u32);
    }
    out
}

/// `sub` cut in two by the plane through the middle of its face centroids, across their
/// principal axis; `None` when no such plane separates them.
fn split(
    vertices: &[Point3<f64>],
    faces: &[[u32; 3]],
    sub: &[u32],
) -> Option<(Vec<u32>, Vec<u32>)> {
    let c: Vec<Point3<f64>> = sub
        .iter()
        .map(|&f| {
            let [a, b, d] = faces[f as usize].map(|i| vertices[i as usize].coords);
            Point3::from((a + b + d) / 3.0)
        })
        .collect();
    let (_, axes) = principal(&c, true);
    let axis = axes?[0];
    let t: Vec<f64> = c.iter().map(|q| q.coords.dot(&axis)).collect();
    let (lo, hi) = t
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &x| {
            (lo.min(x), hi.max(x))
        });
    let mid = 0.5 * (lo + hi);
    let (mut lower, mut upper) = (Vec::new(), Vec::new());
    for (&f, x) in sub.iter().zip(t) {
        if x < mid {
            lower.push(f);
        } else {
            upper.push(f);
        }
    }
    if lower.is_empty() || upper.is_empty() {
        return None;
    }
    Some((lower, upper))
}

#[cfg(test)]
#[path = "decompose_tests.rs"]
mod tests;
