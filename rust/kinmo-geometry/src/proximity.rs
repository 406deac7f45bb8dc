//! Distance from points to a triangle mesh's surface.
//!
//! [`any_farther_than`] tells whether some point lies farther than a tolerance from every
//! triangle of a mesh (exact point-triangle distances, parry's `Triangle` projection). The
//! export's collision geometry uses it to test whether a convex hull strays from the
//! surface it wraps (a concave part's hull fills a slot another part moves into).

use nalgebra::Point3;
use parry3d_f64::bounding_volume::{Aabb, BoundingVolume};
use parry3d_f64::query::PointQuery;
use parry3d_f64::shape::Triangle;

use crate::error::{GeometryError, Result};
use crate::mesh::{check_finite, TriMesh};

/// Whether some point of `points` lies farther than `tolerance` from the surface of `mesh`
/// (the union of its triangles; degenerate triangles count as their edges): the same answer
/// as the smallest exact point-triangle distance of any point exceeding `tolerance`.
///
/// A triangle is projected on only when the point lies in its bounding box grown by twice
/// the tolerance (a triangle within the tolerance always passes, whatever the rounding), and
/// a point is done at its first triangle within the tolerance. No hierarchy is built: the
/// concavity test asks this of 64 points per convex piece, too few queries to pay for a
/// bounding volume hierarchy of the piece (on the 546 links of the 141 shared PartNet shapes,
/// the split took 3.37 s with parry's `TriMesh` queries and takes 2.23 s with this, every
/// piece the same: docs/results/collision.md).
///
/// # Errors
///
/// [`GeometryError::NonFinite`] if a point is NaN or infinite;
/// [`GeometryError::Degenerate`] if the mesh has no faces;
/// [`GeometryError::Invalid`] for a negative or NaN tolerance.
pub fn any_farther_than(points: &[Point3<f64>], mesh: &TriMesh, tolerance: f64) -> Result<bool> {
    check_finite(points, "points")?;
    if tolerance.is_nan() || tolerance < 0.0 {
        return Err(GeometryError::Invalid(format!(
            "any_farther_than: bad tolerance {tolerance}"
        )));
    }
    if mesh.n_faces() == 0 {
        return Err(GeometryError::Degenerate(
            "any_farther_than: the mesh has no faces".to_string(),
        ));
    }
    let v = mesh.vertices();
    let tris: Vec<(Triangle, Aabb)> = mesh
        .faces()
        .iter()
        .map(|t| {
            let tri = Triangle::new(v[t[0] as usize], v[t[1] as usize], v[t[2] as usize]);
            let grown = tri.local_aabb().loosened(2.0 * tolerance);
            (tri, grown)
        })
        .collect();
    let near = |p: &Point3<f64>| {
        tris.iter().any(|(t, b)| {
            b.contains_local_point(p)
                && (t.project_local_point(p, false).point - p).norm() <= tolerance
        })
    };
    Ok(points.iter().any(|p| !near(p)))
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

    /// The smallest exact distance from `p` to a triangle of `mesh`, every triangle tried.
    fn distance(p: &Point3<f64>, mesh: &TriMesh) -> f64 {
        let v = mesh.vertices();
        mesh.faces()
            .iter()
            .map(|t| Triangle::new(v[t[0] as usize], v[t[1] as usize], v[t[2] as usize]))
            .map(|t| (t.project_local_point(p, false).point - p).norm())
            .fold(f64::INFINITY, f64::min)
    }

    #[test]
    fn distances_to_a_square() {
        // above the face (2), on it (0), beside an edge (1), beyond a corner (sqrt 3)
        let cases = [
            (Point3::new(0.5, 0.5, 2.0), 2.0),
            (Point3::new(0.25, 0.5, 0.0), 0.0),
            (Point3::new(2.0, 0.5, 0.0), 1.0),
            (Point3::new(2.0, 2.0, 1.0), 3.0f64.sqrt()),
        ];
        for (p, d) in cases {
            let one = std::slice::from_ref(&p);
            if d > 0.0 {
                assert!(
                    any_farther_than(one, &square(), d - 1e-9).expect("query"),
                    "{p} at {d}"
                );
            }
            assert!(
                !any_farther_than(one, &square(), d + 1e-9).expect("query"),
                "{p} at {d}"
            );
        }
        let all: Vec<Point3<f64>> = cases.iter().map(|c| c.0).collect();
        // farthest: 2 above the face
        assert!(any_farther_than(&all, &square(), 1.9).expect("query"));
        assert!(!any_farther_than(&all, &square(), 2.0).expect("query"));
    }

    #[test]
    fn agrees_with_every_triangle_tried() {
        // a 20 x 20 grid of squares (800 triangles) and points around it, at tolerances
        // around each point's own distance
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
        let d: Vec<f64> = pts.iter().map(|p| distance(p, &grid)).collect();
        for (p, &dp) in pts.iter().zip(&d) {
            for tol in [0.0, 0.5 * dp, dp, 1.5 * dp, dp + 1.0] {
                let one = std::slice::from_ref(p);
                assert_eq!(
                    any_farther_than(one, &grid, tol).expect("query"),
                    dp > tol,
                    "{p} {tol}"
                );
            }
        }
        let far = d.iter().copied().fold(0.0, f64::max);
        for tol in [0.0, 0.25 * far, 0.5 * far, far, 2.0 * far] {
            let want = d.iter().any(|&x| x > tol);
            assert_eq!(
                any_farther_than(&pts, &grid, tol).expect("query"),
                want,
                "{tol}"
            );
        }
    }

    #[test]
    fn rejects_bad_input() {
        let nan = [Point3::new(f64::NAN, 0.0, 0.0)];
        assert!(matches!(
            any_farther_than(&nan, &square(), 0.1),
            Err(GeometryError::NonFinite { .. })
        ));
        let empty = TriMesh::new(vec![Point3::origin()], vec![], "empty").expect("valid");
        assert!(matches!(
            any_farther_than(&[Point3::origin()], &empty, 0.1),
            Err(GeometryError::Degenerate(_))
        ));
        for bad in [-1.0, f64::NAN] {
            assert!(matches!(
                any_farther_than(&[Point3::origin()], &square(), bad),
                Err(GeometryError::Invalid(_))
            ));
        }
    }
}
