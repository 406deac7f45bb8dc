//! Exact convex hulls of point sets, for collision geometry.
//!
//! The hull is the one [`crate::obb`] fits boxes on (`obb/hull.rs`: incremental Quickhull
//! with Shewchuk's exact predicates, so coplanar, collinear or duplicated points never
//! corrupt it). Here it is public for the convex collision pieces of the exporters: one
//! hull per leaf mesh (`kinmo.export.collision`, method `hull`).

use nalgebra::Point3;

use crate::error::{GeometryError, Result};

/// A full-dimensional convex hull, in indices of the input points.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ConvexHull {
    /// Indices of the hull vertices in the input, ascending. Points on a face's plane (not
    /// at a corner) and repeated points are not hull vertices.
    pub vertices: Vec<usize>,
    /// Triangles (input indices), counter-clockwise seen from outside, so every face
    /// normal `(b - a) x (c - a)` points outwards.
    pub faces: Vec<[usize; 3]>,
}

/// The exact convex hull of `points`, or `None` when it has no volume (fewer than four
/// points, or all of them on one plane, line or point: exact tests).
///
/// # Errors
/// [`GeometryError::NonFinite`] for a NaN or infinite coordinate (flat index into the
/// `(N, 3)` coordinates).
pub fn convex_hull(points: &[Point3<f64>]) -> Result<Option<ConvexHull>> {
    for (i, p) in points.iter().enumerate() {
        if let Some(k) = p.coords.iter().position(|x| !x.is_finite()) {
            return Err(GeometryError::NonFinite {
                what: "points".to_string(),
                index: 3 * i + k,
            });
        }
    }
    Ok(match crate::obb::hull::convex_hull(points) {
        Some(crate::obb::hull::HullShape::Solid(h)) => Some(ConvexHull {
            vertices: h.vertices,
            faces: h.faces,
        }),
        _ => None,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_cube_with_inner_face_and_edge_points_is_its_eight_corners() {
        let mut pts = Vec::new();
        for i in 0..8 {
            pts.push(Point3::new(
                f64::from(i & 1),
                f64::from((i >> 1) & 1),
                f64::from((i >> 2) & 1),
            ));
        }
        pts.push(Point3::new(0.5, 0.5, 0.5)); // inside
        pts.push(Point3::new(0.5, 0.5, 1.0)); // on a face
        pts.push(Point3::new(0.5, 0.0, 0.0)); // on an edge
        pts.push(Point3::new(1.0, 1.0, 1.0)); // a repeated corner
        let h = convex_hull(&pts).unwrap().unwrap();
        assert_eq!(h.vertices.len(), 8);
        assert!(h.vertices.iter().all(|&v| v < 8 || v == 11));
        assert_eq!(h.faces.len(), 12); // V - E + F = 2 with E = 18
        let c = Point3::new(0.5, 0.5, 0.5);
        for f in &h.faces {
            let (a, b, d) = (pts[f[0]], pts[f[1]], pts[f[2]]);
            let n = (b - a).cross(&(d - a));
            assert!(n.dot(&(a - c)) > 0.0, "face {f:?} points inwards");
        }
    }

    #[test]
    fn flat_or_short_inputs_have_no_hull_and_nan_is_an_error() {
        let square: Vec<_> = (0..9)
            .map(|i| Point3::new(f64::from(i % 3), f64::from(i / 3), 0.0))
            .collect();
        assert_eq!(convex_hull(&square).unwrap(), None);
        assert_eq!(convex_hull(&square[..3]).unwrap(), None);
        assert_eq!(convex_hull(&[]).unwrap(), None);
        let bad = [Point3::new(0.0, f64::NAN, 0.0)];
        assert!(matches!(
            convex_hull(&bad),
            Err(GeometryError::NonFinite { index: 1, .. })
        ));
    }
}
