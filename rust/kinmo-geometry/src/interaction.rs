//! Interaction region between a moving part and its reference part.
//!
//! The interaction region of two parts is the set of points of each part that lie within a
//! radius of the other part (Hu et al., *Interaction Context (ICON): Towards a Geometric
//! Functionality Descriptor*, SIGGRAPH 2015). Its centroid is the pivot candidate of the
//! motion refinement stage of Liu et al., *Semi-Weakly Supervised Object Kinematic Motion
//! Prediction*, CVPR 2023, Sec. 3.3.
//!
//! Both point sets are indexed with a `kiddo` k-d tree (nearest-neighbour queries, squared
//! Euclidean distance): cost `O((Na + Nb) log(Na + Nb))`.

use kiddo::immutable::float::kdtree::ImmutableKdTree;
use kiddo::SquaredEuclidean;
use nalgebra::Point3;

use crate::error::{GeometryError, Result};

/// Points of two parts near each other; see the module documentation.
#[derive(Clone, Debug, PartialEq)]
pub struct InteractionRegion {
    /// `mask_moving[i]`: moving point `i` is within `radius` of a reference point.
    pub mask_moving: Vec<bool>,
    /// `mask_reference[j]`: reference point `j` is within `radius` of a moving point.
    pub mask_reference: Vec<bool>,
    /// Mean of all selected points of both parts; when none is selected, the midpoint of
    /// the closest pair of points (one of each part).
    pub centroid: Point3<f64>,
    /// True when no point is within `radius` of the other part.
    pub empty: bool,
}

/// A `kiddo` k-d tree over one part's points (item: the point's index).
type KdTree = ImmutableKdTree<f64, u32, 3, 32>;

fn kd_tree(points: &[Point3<f64>]) -> KdTree {
    let coords: Vec<[f64; 3]> = points.iter().map(|p| [p.x, p.y, p.z]).collect();
    ImmutableKdTree::new_from_slice(&coords)
}

fn check_points(points: &[Point3<f64>], what: &str) -> Result<()> {
    if points.is_empty() {
        return Err(GeometryError::Degenerate(format!("{what}: no points")));
    }
    for (i, p) in points.iter().enumerate() {
        if let Some(k) = (0..3).find(|&k| !p[k].is_finite()) {
            return Err(GeometryError::NonFinite {
                what: what.to_string(),
                index: 3 * i + k,
            });
        }
    }
    Ok(())
}

/// Mask of the points of `query` within squared distance `r2` of a point of `tree`, whose
/// points have the bounding box `(lo, hi)`: points farther than that from the box are
/// rejected without a tree query.
fn mask_within(
    query: &[Point3<f64>],
    tree: &KdTree,
    (lo, hi): (Point3<f64>, Point3<f64>),
    r2: f64,
) -> Vec<bool> {
    query
        .iter()
        .map(|p| {
            let mut d2 = 0.0;
            for k in 0..3 {
                let gap = (lo[k] - p[k]).max(p[k] - hi[k]);
                if gap > 0.0 {
                    d2 += gap * gap;
                }
            }
            d2 <= r2
                && tree
                    .nearest_one::<SquaredEuclidean>(&[p.x, p.y, p.z])
                    .distance
                    <= r2
        })
        .collect()
}

/// Component-wise bounding box of a non-empty point set.
fn bounds(points: &[Point3<f64>]) -> (Point3<f64>, Point3<f64>) {
    points.iter().fold(
        (
            Point3::from([f64::INFINITY; 3]),
            Point3::from([f64::NEG_INFINITY; 3]),
        ),
        |(lo, hi), p| (lo.inf(p), hi.sup(p)),
    )
}

/// Interaction region of a moving part and its reference part.
///
/// # Arguments
///
/// * `moving`, `reference` - point samples of the two parts (same frame and units).
/// * `radius` - absolute distance, finite and `> 0`; a point is selected when its distance
///   to the nearest point of the other part is `<= radius`.
///
/// # Errors
///
/// [`GeometryError::Invalid`] for a non-positive or non-finite radius,
/// [`GeometryError::Degenerate`] for an empty point set, [`GeometryError::NonFinite`] for a
/// NaN or infinite coordinate (`what` is `moving` or `reference`).
pub fn interaction_region(
    moving: &[Point3<f64>],
    reference: &[Point3<f64>],
    radius: f64,
) -> Result<InteractionRegion> {
    if !(radius.is_finite() && radius > 0.0) {
        return Err(GeometryError::Invalid(format!(
            "radius: expected a finite value > 0, got {radius}"
        )));
    }
    check_points(moving, "moving")?;
    check_points(reference, "reference")?;
    let r2 = radius * radius;
    let tree_ref = kd_tree(reference);
    let mask_moving = mask_within(moving, &tree_ref, bounds(reference), r2);
    if !mask_moving.iter().any(|&m| m) {
        // Nothing within radius: midpoint of the closest pair.
        let mut best: Option<(usize, u32, f64)> = None;
        for (i, p) in moving.iter().enumerate() {
            let nn = tree_ref.nearest_one::<SquaredEuclidean>(&[p.x, p.y, p.z]);
            if best.is_none_or(|b| nn.distance < b.2) {
                best = Some((i, nn.item, nn.distance));
            }
        }
        // Points are finite, so some pair has a finite distance; fall back to the first pair
        // if the squared distance overflowed.
        let (i, j) = best.map_or((0, 0), |b| (b.0, b.1 as usize));
        let centroid = nalgebra::center(&moving[i], &reference[j]);
        return Ok(InteractionRegion {
            mask_moving,
            mask_reference: vec![false; reference.len()],
            centroid,
            empty: true,
        });
    }
    let tree_mov = kd_tree(moving);
    let mask_reference = mask_within(reference, &tree_mov, bounds(moving), r2);
    let mut sum = nalgebra::Vector3::zeros();
    let mut count = 0usize;
    for (pts, mask) in [(moving, &mask_moving), (reference, &mask_reference)] {
        for (p, _) in pts.iter().zip(mask.iter()).filter(|(_, &m)| m) {
            sum += p.coords;
            count += 1;
        }
    }
    Ok(InteractionRegion {
        mask_moving,
        mask_reference,
        centroid: Point3::from(sum / count as f64),
        empty: false,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    struct Rng(u64);
    impl Rng {
        fn next(&mut self) -> f64 {
            self.0 ^= self.0 >> 12;
            self.0 ^= self.0 << 25;
            self.0 ^= self.0 >> 27;
            (self.0.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 11) as f64 / (1u64 << 53) as f64
        }
    }

    /// Points on the surface of the box `[min, min + size]` (random faces, uniform).
    fn box_surface(rng: &mut Rng, min: [f64; 3], size: [f64; 3], n: usize) -> Vec<Point3<f64>> {
        (0..n)
            .map(|_| {
                let face = (rng.next() * 6.0) as usize % 6;
                let axis = face / 2;
                let mut p = [0.0; 3];
                for k in 0..3 {
                    p[k] = min[k]
                        + size[k]
                            * if k == axis {
                                (face % 2) as f64
                            } else {
                                rng.next()
                            };
                }
                Point3::from(p)
            })
            .collect()
    }

    fn dist2(a: &[f64; 3], b: &[f64; 3]) -> f64 {
        let d = [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
        d[0] * d[0] + d[1] * d[1] + d[2] * d[2]
    }

    fn brute_mask(a: &[Point3<f64>], b: &[Point3<f64>], r: f64) -> Vec<bool> {
        // Plain arrays: fast enough in debug builds.
        let b: Vec<[f64; 3]> = b.iter().map(|q| [q.x, q.y, q.z]).collect();
        a.iter()
            .map(|p| {
                let p = [p.x, p.y, p.z];
                b.iter().any(|q| dist2(&p, q).sqrt() <= r)
            })
            .collect()
    }

    #[test]
    fn touching_boxes_centroid_on_contact_face() {
        let mut rng = Rng(1);
        // Moving box sits on top of the reference box (contact plane y = 1), centred.
        let reference = box_surface(&mut rng, [0.0, 0.0, 0.0], [2.0, 1.0, 2.0], 5_000);
        let moving = box_surface(&mut rng, [0.5, 1.0, 0.5], [1.0, 0.5, 1.0], 5_000);
        let r = 0.05;
        let reg = interaction_region(&moving, &reference, r).expect("ok");
        assert!(!reg.empty);
        assert_eq!(reg.mask_moving, brute_mask(&moving, &reference, r));
        assert_eq!(reg.mask_reference, brute_mask(&reference, &moving, r));
        // On the contact face: y = 1 up to the selection band, x and z at the centre.
        assert!((reg.centroid.y - 1.0).abs() < 0.01, "{}", reg.centroid);
        assert!((reg.centroid.x - 1.0).abs() < 0.02, "{}", reg.centroid);
        assert!((reg.centroid.z - 1.0).abs() < 0.02, "{}", reg.centroid);
        // Selected points all lie near the contact plane.
        for (p, _) in moving.iter().zip(&reg.mask_moving).filter(|(_, &m)| m) {
            assert!(p.y <= 1.0 + r);
        }
    }

    #[test]
    fn empty_region_is_midpoint_of_closest_pair() {
        let mut rng = Rng(2);
        let a: Vec<Point3<f64>> = (0..500)
            .map(|_| Point3::new(rng.next(), rng.next(), rng.next()))
            .collect();
        let b: Vec<Point3<f64>> = (0..700)
            .map(|_| Point3::new(3.0 + rng.next(), rng.next(), rng.next()))
            .collect();
        let reg = interaction_region(&a, &b, 0.5).expect("ok");
        assert!(reg.empty);
        assert!(reg.mask_moving.iter().all(|&m| !m));
        assert!(reg.mask_reference.iter().all(|&m| !m));
        let mut best = (f64::INFINITY, Point3::origin());
        for p in &a {
            for q in &b {
                let d = (p - q).norm();
                if d < best.0 {
                    best = (d, nalgebra::center(p, q));
                }
            }
        }
        assert_eq!(reg.centroid, best.1);
    }

    #[test]
    fn masks_match_brute_force_random() {
        let mut rng = Rng(3);
        let a: Vec<Point3<f64>> = (0..800)
            .map(|_| Point3::new(rng.next(), rng.next(), rng.next()))
            .collect();
        let b: Vec<Point3<f64>> = (0..600)
            .map(|_| Point3::new(0.8 + rng.next(), rng.next(), 0.5 * rng.next()))
            .collect();
        let mut n_empty = 0;
        for r in [0.01, 0.05, 0.2, 5.0] {
            let reg = interaction_region(&a, &b, r).expect("ok");
            let (ma, mb) = (brute_mask(&a, &b, r), brute_mask(&b, &a, r));
            assert_eq!(reg.mask_moving, ma);
            assert_eq!(reg.mask_reference, mb);
            let sel: Vec<&Point3<f64>> = a
                .iter()
                .zip(&ma)
                .chain(b.iter().zip(&mb))
                .filter(|(_, &m)| m)
                .map(|(p, _)| p)
                .collect();
            assert_eq!(reg.empty, sel.is_empty(), "r = {r}");
            if sel.is_empty() {
                n_empty += 1;
                continue;
            }
            let mean = sel
                .iter()
                .fold(nalgebra::Vector3::zeros(), |s, p| s + p.coords)
                / sel.len() as f64;
            assert!((reg.centroid.coords - mean).norm() < 1e-12, "r = {r}");
        }
        assert!(n_empty <= 1);
    }

    #[test]
    fn duplicate_points_and_single_points() {
        let a = vec![Point3::new(0.0, 0.0, 0.0); 50];
        let b = vec![Point3::new(1.0, 0.0, 0.0)];
        let reg = interaction_region(&a, &b, 0.5).expect("ok");
        assert!(reg.empty);
        assert_eq!(reg.centroid, Point3::new(0.5, 0.0, 0.0));
        let reg = interaction_region(&a, &b, 1.0).expect("ok");
        assert!(!reg.empty && reg.mask_moving.iter().all(|&m| m) && reg.mask_reference[0]);
        // 50 copies of the origin and one point at x = 1.
        assert!((reg.centroid.x - 1.0 / 51.0).abs() < 1e-15);
    }

    #[test]
    fn bad_inputs_are_errors() {
        let a = vec![Point3::new(0.0, 0.0, 0.0)];
        for r in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            assert!(matches!(
                interaction_region(&a, &a, r),
                Err(GeometryError::Invalid(_))
            ));
        }
        assert!(matches!(
            interaction_region(&[], &a, 1.0),
            Err(GeometryError::Degenerate(_))
        ));
        let bad = vec![Point3::new(0.0, f64::NAN, 0.0)];
        assert!(matches!(
            interaction_region(&a, &bad, 1.0),
            Err(GeometryError::NonFinite { index: 1, ref what } ) if what == "reference"
        ));
    }
}
