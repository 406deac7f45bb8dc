//! Reflective-symmetry error of a box's three mid-planes.
//!
//! For a candidate frame (center `c`, orthonormal rows `a_k`), the points are reflected
//! through each mid-plane `{x : (x - c) . a_k = 0}` and the mean distance from a reflected
//! point to its nearest original point is measured (the same measure as the symmetry
//! transform scores of Mitra et al., *Partial and approximate symmetry detection for 3D
//! geometry*, SIGGRAPH 2006, used by Fish et al. 2014 to align part boxes). The error is
//! the mean over the three planes, divided by the box diagonal, so it is dimensionless:
//! `0` for a set that is mirror-symmetric about all three mid-planes.
//!
//! To stay cheap, at most `max_samples` points are used: a permutation-independent
//! subsample (the points with the smallest SplitMix64 hash of their coordinate bits),
//! with a `kiddo` k-d tree for the nearest-neighbour queries.

use kiddo::immutable::float::kdtree::ImmutableKdTree;
use kiddo::SquaredEuclidean;
use nalgebra::{Point3, Vector3};

/// SplitMix64 finaliser (Steele, Lea & Flood 2014) of one word.
fn mix(x: u64) -> u64 {
    let mut z = x.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// The subsampled points with a `kiddo` k-d tree for nearest-neighbour queries.
#[derive(Debug, Clone)]
pub(crate) struct KdTree {
    pts: Vec<Point3<f64>>,
    tree: ImmutableKdTree<f64, u32, 3, 32>,
}

impl KdTree {
    /// Build the tree over `pts`.
    pub fn new(pts: Vec<Point3<f64>>) -> Self {
        let coords: Vec<[f64; 3]> = pts.iter().map(|p| [p.x, p.y, p.z]).collect();
        let tree = ImmutableKdTree::new_from_slice(&coords);
        KdTree { pts, tree }
    }

    /// Squared distance from `q` to the nearest point (infinity when empty).
    pub fn nearest_sq(&self, q: &Point3<f64>) -> f64 {
        if self.pts.is_empty() {
            return f64::INFINITY;
        }
        self.tree
            .nearest_one::<SquaredEuclidean>(&[q.x, q.y, q.z])
            .distance
    }

    /// The points.
    pub fn points(&self) -> &[Point3<f64>] {
        &self.pts
    }
}

/// At most about `max` points of `pts`, chosen independently of their order and of the
/// frame's quarter turns: point `i` is keyed by a hash of the sorted absolute coordinates of
/// `keys[i]` (the input point before centring), and the points whose key is among the `max`
/// smallest are kept, with every point tied with the last one (mirror images share a key),
/// so the same points are kept for the set turned by quarter turns about the world axes or
/// mirrored through them. `keys` and `pts` have the same length.
pub(crate) fn subsample(keys: &[Point3<f64>], pts: &[Point3<f64>], max: usize) -> Vec<Point3<f64>> {
    debug_assert_eq!(keys.len(), pts.len());
    if pts.len() <= max {
        return pts.to_vec();
    }
    if max == 0 {
        return Vec::new();
    }
    let hash = |p: &Point3<f64>| {
        let mut c = [p.x.abs(), p.y.abs(), p.z.abs()];
        c.sort_by(f64::total_cmp);
        mix(mix(mix(c[0].to_bits()) ^ c[1].to_bits()) ^ c[2].to_bits())
    };
    let mut keyed: Vec<(u64, usize)> = keys.iter().enumerate().map(|(i, p)| (hash(p), i)).collect();
    keyed.select_nth_unstable_by_key(max - 1, |k| k.0);
    let last = keyed[max - 1].0;
    let mut kept: Vec<(u64, usize)> = keyed.into_iter().filter(|k| k.0 <= last).collect();
    kept.sort_unstable();
    kept.into_iter().map(|(_, i)| pts[i]).collect()
}

/// Mean (over the three mid-planes of the frame) of the mean nearest-neighbour distance
/// of the reflected samples, divided by `diag` (the box diagonal).
pub(crate) fn symmetry_error(
    tree: &KdTree,
    center: &Point3<f64>,
    axes: &[Vector3<f64>; 3],
    diag: f64,
) -> f64 {
    let pts = tree.points();
    if pts.is_empty() || diag <= 0.0 {
        return 0.0;
    }
    let mut total = 0.0;
    for a in axes {
        let mut sum = 0.0;
        for p in pts {
            let r = p - a * (2.0 * (p - center).dot(a));
            sum += tree.nearest_sq(&r).sqrt();
        }
        total += sum / pts.len() as f64;
    }
    total / (3.0 * diag)
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

    #[test]
    fn kdtree_matches_brute_force() {
        let mut s = 11;
        let pts: Vec<Point3<f64>> = (0..300)
            .map(|_| Point3::new(lcg(&mut s), lcg(&mut s), lcg(&mut s)))
            .collect();
        let tree = KdTree::new(pts.clone());
        for _ in 0..100 {
            let q = Point3::new(lcg(&mut s), lcg(&mut s), lcg(&mut s));
            let brute = pts
                .iter()
                .map(|p| (p - q).norm_squared())
                .fold(f64::INFINITY, f64::min);
            assert_eq!(tree.nearest_sq(&q), brute);
        }
        // Many duplicates (a coarse grid repeated) stay exact.
        let dup: Vec<Point3<f64>> = (0..400)
            .map(|i| Point3::new(f64::from(i % 3), 0.0, f64::from(i % 2)))
            .collect();
        let tree = KdTree::new(dup);
        assert_eq!(tree.nearest_sq(&Point3::new(2.0, 0.5, 1.0)), 0.25);
        assert_eq!(
            KdTree::new(Vec::new()).nearest_sq(&Point3::origin()),
            f64::INFINITY
        );
    }

    #[test]
    fn mirror_symmetric_set_has_zero_error_on_its_planes() {
        // A set symmetric about x = 0 only.
        let mut s = 5;
        let mut pts = Vec::new();
        for _ in 0..50 {
            let (x, y, z) = (lcg(&mut s), lcg(&mut s), lcg(&mut s));
            pts.push(Point3::new(x, y, z));
            pts.push(Point3::new(-x, y, z));
        }
        let tree = KdTree::new(pts.clone());
        let c = Point3::origin();
        let x = Vector3::x();
        let e_x = symmetry_error(&tree, &c, &[x, x, x], 1.0);
        assert!(e_x < 1e-15, "{e_x}");
        let axes = [Vector3::y(), Vector3::y(), Vector3::y()];
        assert!(symmetry_error(&tree, &Point3::new(0.0, 0.5, 0.0), &axes, 1.0) > 1e-3);
    }

    #[test]
    fn subsample_is_order_independent() {
        let mut s = 9;
        let pts: Vec<Point3<f64>> = (0..1000)
            .map(|_| Point3::new(lcg(&mut s), lcg(&mut s), lcg(&mut s)))
            .collect();
        let mut rev = pts.clone();
        rev.reverse();
        let mut a = subsample(&pts, &pts, 64);
        assert_eq!(a.len(), 64);
        let mut b = subsample(&rev, &rev, 64);
        let key = |p: &Point3<f64>| (p.x.to_bits(), p.y.to_bits(), p.z.to_bits());
        a.sort_by_key(key);
        b.sort_by_key(key);
        assert_eq!(a, b);
    }

    #[test]
    fn subsample_commutes_with_quarter_turns() {
        let mut s = 5;
        let pts: Vec<Point3<f64>> = (0..1000)
            .map(|_| Point3::new(lcg(&mut s) - 0.3, lcg(&mut s), lcg(&mut s) - 0.6))
            .collect();
        // a quarter turn about y, exactly: (x, y, z) -> (z, y, -x)
        let turn = |p: &Point3<f64>| Point3::new(p.z, p.y, -p.x);
        let turned: Vec<Point3<f64>> = pts.iter().map(turn).collect();
        let key = |p: &Point3<f64>| (p.x.to_bits(), p.y.to_bits(), p.z.to_bits());
        let mut a: Vec<Point3<f64>> = subsample(&pts, &pts, 64).iter().map(turn).collect();
        let mut b = subsample(&turned, &turned, 64);
        assert!(a.len() >= 64);
        a.sort_by_key(key);
        b.sort_by_key(key);
        assert_eq!(a, b);
    }
}
