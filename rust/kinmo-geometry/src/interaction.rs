//! Interaction region between a moving part and its reference part.
//!
//! The interaction region of two parts is the set of points of each part that lie within a
//! radius of the other part (Hu et al., *Interaction Context (ICON): Towards a Geometric
//! Functionality Descriptor*, SIGGRAPH 2015). Its centroid is the pivot candidate of the
//! motion refinement stage of Liu et al., *Semi-Weakly Supervised Object Kinematic Motion
//! Prediction*, CVPR 2023, Sec. 3.3.
//!
//! Both point sets are indexed with a k-d tree (median split on the widest axis, bounding
//! box per node), queried with early exit: cost `O((Na + Nb) log(Na + Nb))`.

use nalgebra::Point3;

use crate::error::{GeometryError, Result};

/// Most points in one leaf of a [`KdTree`].
const LEAF_SIZE: usize = 8;

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

/// Node of a [`KdTree`]: a leaf holds points `first..first + count` of the permuted array;
/// an inner node has `count == 0` and children `first`, `first + 1`.
#[derive(Clone, Copy, Debug)]
struct KdNode {
    mins: [f64; 3],
    maxs: [f64; 3],
    first: u32,
    count: u32,
}

impl KdNode {
    #[inline]
    fn distance2(&self, q: &[f64; 3]) -> f64 {
        let mut d2 = 0.0;
        for ((lo, hi), x) in self.mins.iter().zip(&self.maxs).zip(q) {
            let gap = (lo - x).max(x - hi);
            if gap > 0.0 {
                d2 += gap * gap;
            }
        }
        d2
    }
}

/// Static k-d tree over 3D points with per-node bounding boxes.
#[derive(Clone, Debug)]
struct KdTree {
    /// Points in leaf order.
    points: Vec<[f64; 3]>,
    /// `index[k]`: original index of `points[k]`.
    index: Vec<u32>,
    nodes: Vec<KdNode>,
}

impl KdTree {
    /// Build the tree; `points` must be non-empty and finite.
    fn new(points: &[Point3<f64>]) -> KdTree {
        let mut index: Vec<u32> = (0..points.len() as u32).collect();
        let coords: Vec<[f64; 3]> = points.iter().map(|p| [p.x, p.y, p.z]).collect();
        let mut nodes = vec![KdNode {
            mins: [0.0; 3],
            maxs: [0.0; 3],
            first: 0,
            count: 0,
        }];
        let mut stack = vec![(0usize, 0usize, points.len())];
        while let Some((node, lo, hi)) = stack.pop() {
            let mut mins = [f64::INFINITY; 3];
            let mut maxs = [f64::NEG_INFINITY; 3];
            for &i in &index[lo..hi] {
                let p = coords[i as usize];
                for k in 0..3 {
                    mins[k] = mins[k].min(p[k]);
                    maxs[k] = maxs[k].max(p[k]);
                }
            }
            nodes[node].mins = mins;
            nodes[node].maxs = maxs;
            let ext = [maxs[0] - mins[0], maxs[1] - mins[1], maxs[2] - mins[2]];
            let axis = if ext[0] >= ext[1] && ext[0] >= ext[2] {
                0
            } else if ext[1] >= ext[2] {
                1
            } else {
                2
            };
            if hi - lo <= LEAF_SIZE || ext[axis] <= 0.0 {
                nodes[node].first = lo as u32;
                nodes[node].count = (hi - lo) as u32;
                continue;
            }
            let mid = lo + (hi - lo) / 2;
            index[lo..hi].select_nth_unstable_by(mid - lo, |&a, &b| {
                coords[a as usize][axis].total_cmp(&coords[b as usize][axis])
            });
            let left = nodes.len();
            nodes[node].first = left as u32;
            nodes[node].count = 0;
            let blank = nodes[node];
            nodes.push(blank);
            nodes.push(blank);
            stack.push((left, lo, mid));
            stack.push((left + 1, mid, hi));
        }
        let points = index.iter().map(|&i| coords[i as usize]).collect();
        KdTree {
            points,
            index,
            nodes,
        }
    }

    /// Whether some point is within squared distance `r2` of `q`.
    fn any_within(&self, q: &[f64; 3], r2: f64, stack: &mut Vec<u32>) -> bool {
        stack.clear();
        stack.push(0);
        while let Some(n) = stack.pop() {
            let node = &self.nodes[n as usize];
            if node.distance2(q) > r2 {
                continue;
            }
            if node.count > 0 {
                let s = node.first as usize;
                if self.points[s..s + node.count as usize]
                    .iter()
                    .any(|p| dist2(p, q) <= r2)
                {
                    return true;
                }
            } else {
                stack.push(node.first);
                stack.push(node.first + 1);
            }
        }
        false
    }

    /// Nearest point to `q` strictly closer than `sqrt(bound2)`: `(original index, d²)`.
    fn nearest(
        &self,
        q: &[f64; 3],
        bound2: f64,
        stack: &mut Vec<(u32, f64)>,
    ) -> Option<(u32, f64)> {
        let mut best: Option<(u32, f64)> = None;
        let mut best2 = bound2;
        stack.clear();
        stack.push((0, self.nodes[0].distance2(q)));
        while let Some((n, d2)) = stack.pop() {
            if d2 >= best2 {
                continue;
            }
            let node = &self.nodes[n as usize];
            if node.count > 0 {
                let s = node.first as usize;
                for (k, p) in self.points[s..s + node.count as usize].iter().enumerate() {
                    let e = dist2(p, q);
                    if e < best2 {
                        best2 = e;
                        best = Some((self.index[s + k], e));
                    }
                }
            } else {
                let (a, b) = (node.first, node.first + 1);
                let da = self.nodes[a as usize].distance2(q);
                let db = self.nodes[b as usize].distance2(q);
                let (near, far) = if da <= db {
                    ((a, da), (b, db))
                } else {
                    ((b, db), (a, da))
                };
                stack.push(far);
                stack.push(near);
            }
        }
        best
    }
}

#[inline]
fn dist2(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    let d = [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    d[0] * d[0] + d[1] * d[1] + d[2] * d[2]
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

/// Mask of the points of `query` within squared distance `r2` of a point of `tree`.
fn mask_within(query: &[Point3<f64>], tree: &KdTree, r2: f64) -> Vec<bool> {
    let mut stack = Vec::with_capacity(64);
    query
        .iter()
        .map(|p| tree.any_within(&[p.x, p.y, p.z], r2, &mut stack))
        .collect()
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
    let tree_ref = KdTree::new(reference);
    let mask_moving = mask_within(moving, &tree_ref, r2);
    if !mask_moving.iter().any(|&m| m) {
        // Nothing within radius: midpoint of the closest pair.
        let mut stack = Vec::with_capacity(64);
        let mut best: Option<(usize, u32, f64)> = None;
        for (i, p) in moving.iter().enumerate() {
            let bound = best.map_or(f64::INFINITY, |b| b.2);
            if let Some((j, d2)) = tree_ref.nearest(&[p.x, p.y, p.z], bound, &mut stack) {
                best = Some((i, j, d2));
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
    let tree_mov = KdTree::new(moving);
    let mask_reference = mask_within(reference, &tree_mov, r2);
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
