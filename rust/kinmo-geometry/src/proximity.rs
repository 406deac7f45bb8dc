//! Distance from points to a triangle mesh's surface.
//!
//! [`point_mesh_distance`] projects each point on the mesh with parry's `TriMesh` point
//! query (its bounding volume hierarchy over the triangles), in parallel over the points;
//! on a small mesh with few points it projects on every parry `Triangle` instead.
//! The export's collision geometry uses it to measure how far a convex hull strays from the
//! surface it wraps (a concave part's hull fills a slot another part moves into).

use nalgebra::Point3;
use parry3d_f64::query::PointQuery;
use parry3d_f64::shape::{TriMesh as ParryMesh, Triangle};
use rayon::prelude::*;

use crate::error::{GeometryError, Result};
use crate::mesh::{check_finite, TriMesh};

/// Below this many points the queries run on the calling thread (a thread pool costs more).
const PARALLEL_MIN_POINTS: usize = 256;
/// Up to this many point-triangle pairs every triangle is tried (building the hierarchy
/// costs more).
const BRUTE_FORCE_PAIRS: usize = 4096;

/// Unsigned distance from each point to the surface of `mesh` (0 on the surface).
///
/// The surface is the union of the triangles; a point inside a closed mesh gets its
/// distance to the nearest triangle, not 0. Degenerate triangles count as their edges.
///
/// # Errors
///
/// [`GeometryError::NonFinite`] if a point is NaN or infinite;
/// [`GeometryError::Degenerate`] if the mesh has no faces.
pub fn point_mesh_distance(points: &[Point3<f64>], mesh: &TriMesh) -> Result<Vec<f64>> {
    check_finite(points, "points")?;
    if mesh.n_faces() == 0 {
        return Err(GeometryError::Degenerate(
            "point_mesh_distance: the mesh has no faces".to_string(),
        ));
    }
    let (v, f) = (mesh.vertices(), mesh.faces());
    if points.len() * f.len() <= BRUTE_FORCE_PAIRS {
        let tris: Vec<Triangle> = f
            .iter()
            .map(|t| Triangle::new(v[t[0] as usize], v[t[1] as usize], v[t[2] as usize]))
            .collect();
        return Ok(points
            .iter()
            .map(|p| {
                tris.iter()
                    .map(|t| (t.project_local_point(p, false).point - p).norm())
                    .fold(f64::INFINITY, f64::min)
            })
            .collect());
    }
    let parry = ParryMesh::new(v.to_vec(), f.to_vec()).map_err(|e| {
        GeometryError::Degenerate(format!("point_mesh_distance: the mesh is invalid ({e})"))
    })?;
    let distance = |p: &Point3<f64>| (parry.project_local_point(p, false).point - p).norm();
    Ok(if points.len() < PARALLEL_MIN_POINTS {
        points.iter().map(distance).collect()
    } else {
        points.par_iter().map(distance).collect()
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square() -> TriMesh {
        // the unit square in the z = 0 plane, two triangles
        let v = vec![
            Point3::new(0.0, 0.0, 0.0),
            Point3::new(1.0, 0.0, 0.0),
            Point3::new(1.0, 1.0, 0.0),
            Point3::new(0.0, 1.0, 0.0),
        ];
        TriMesh::new(v, vec![[0, 1, 2], [0, 2, 3]], "square").expect("valid")
    }

    #[test]
    fn distances_to_a_square() {
        let pts = [
            Point3::new(0.5, 0.5, 2.0),  // above the face
            Point3::new(0.25, 0.5, 0.0), // on it
            Point3::new(2.0, 0.5, 0.0),  // beside an edge
            Point3::new(2.0, 2.0, 1.0),  // beyond a corner
        ];
        let d = point_mesh_distance(&pts, &square()).expect("distances");
        let want = [2.0, 0.0, 1.0, 3.0f64.sqrt()];
        for (got, want) in d.iter().zip(want) {
            assert!((got - want).abs() < 1e-12, "{got} vs {want}");
        }
    }

    #[test]
    fn parallel_and_serial_agree() {
        let pts: Vec<Point3<f64>> = (0..1000)
            .map(|i| {
                let t = i as f64 / 1000.0;
                Point3::new(3.0 * t - 1.0, (7.0 * t).sin(), (5.0 * t).cos())
            })
            .collect();
        let many = point_mesh_distance(&pts, &square()).expect("distances");
        for (p, d) in pts.iter().zip(&many).step_by(97) {
            let one = point_mesh_distance(std::slice::from_ref(p), &square()).expect("one");
            assert_eq!(one[0], *d);
        }
    }

    #[test]
    fn small_and_large_queries_agree() {
        // a 20 x 20 grid of squares (800 triangles): 1 point tries every triangle, 64 use
        // the hierarchy
        let n = 21;
        let v: Vec<Point3<f64>> = (0..n * n)
            .map(|k| Point3::new((k % n) as f64, ((k / n) as f64).sin(), (k / n) as f64))
            .collect();
        let mut f = Vec::new();
        for r in 0..n - 1 {
            for c in 0..n - 1 {
                let k = (r * n + c) as u32;
                f.push([k, k + 1, k + n as u32 + 1]);
                f.push([k, k + n as u32 + 1, k + n as u32]);
            }
        }
        let grid = TriMesh::new(v, f, "grid").expect("valid");
        let pts: Vec<Point3<f64>> = (0..64)
            .map(|i| Point3::new(0.3 * i as f64, 2.0 - 0.05 * i as f64, 0.31 * i as f64))
            .collect();
        let all = point_mesh_distance(&pts, &grid).expect("hierarchy");
        assert!(pts.len() * grid.n_faces() > BRUTE_FORCE_PAIRS);
        for (p, d) in pts.iter().zip(&all) {
            let one = point_mesh_distance(std::slice::from_ref(p), &grid).expect("brute force");
            assert!((one[0] - d).abs() < 1e-12, "{} vs {d}", one[0]);
        }
    }

    #[test]
    fn rejects_bad_input() {
        let nan = [Point3::new(f64::NAN, 0.0, 0.0)];
        assert!(matches!(
            point_mesh_distance(&nan, &square()),
            Err(GeometryError::NonFinite { .. })
        ));
        let empty = TriMesh::new(vec![Point3::origin()], vec![], "empty").expect("valid");
        assert!(matches!(
            point_mesh_distance(&[Point3::origin()], &empty),
            Err(GeometryError::Degenerate(_))
        ));
    }
}
