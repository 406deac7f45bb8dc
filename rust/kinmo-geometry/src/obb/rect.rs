//! Planar tools: exact 2D convex hull and minimum-area enclosing rectangle.
//!
//! The hull is Andrew's monotone chain (A. M. Andrew, *Another efficient algorithm for
//! convex hulls in two dimensions*, IPL 9, 1979) with Shewchuk's exact `orient2d`, so it
//! is strictly convex (no collinear vertices) for any finite input. The minimum-area
//! rectangle has one side flush with a hull edge (H. Freeman & R. Shapira, CACM 18,
//! 1975) and is found in linear time by rotating calipers (G. Toussaint, *Solving
//! geometric problems with the rotating calipers*, MELECON 1983).

use robust::{orient2d, Coord};

/// A 2D point.
pub(crate) type P2 = [f64; 2];

#[inline]
fn co(p: &P2) -> Coord<f64> {
    Coord { x: p[0], y: p[1] }
}

#[inline]
fn dot(a: &P2, b: &P2) -> f64 {
    a[0] * b[0] + a[1] * b[1]
}

/// Convex hull of `pts` in counter-clockwise order without collinear vertices.
///
/// `pts` is sorted and deduplicated in place. One point gives one vertex, collinear
/// points give the two extreme points.
pub(crate) fn hull_2d(pts: &mut Vec<P2>) -> Vec<P2> {
    pts.sort_unstable_by(|a, b| a[0].total_cmp(&b[0]).then(a[1].total_cmp(&b[1])));
    pts.dedup();
    let n = pts.len();
    if n <= 1 {
        return pts.to_vec();
    }
    let mut h: Vec<P2> = Vec::with_capacity(n + 1);
    for p in pts.iter() {
        while h.len() >= 2 && orient2d(co(&h[h.len() - 2]), co(&h[h.len() - 1]), co(p)) <= 0.0 {
            h.pop();
        }
        h.push(*p);
    }
    let lower = h.len() + 1;
    for p in pts.iter().rev().skip(1) {
        while h.len() >= lower && orient2d(co(&h[h.len() - 2]), co(&h[h.len() - 1]), co(p)) <= 0.0 {
            h.pop();
        }
        h.push(*p);
    }
    h.pop(); // the first point again
    h
}

/// A rectangle enclosing a planar point set.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Rect {
    /// Unit direction of the first side.
    pub u: P2,
    /// Side lengths along `u` and along its left perpendicular `(-u[1], u[0])`.
    pub size: P2,
}

impl Rect {
    /// The area.
    pub fn area(&self) -> f64 {
        self.size[0] * self.size[1]
    }
}

/// Minimum-area enclosing rectangle of a convex polygon given counter-clockwise.
///
/// Degenerate hulls (one point, a segment) give a zero-area rectangle aligned with the
/// segment (or with the first coordinate axis).
pub(crate) fn min_area_rect(hull: &[P2]) -> Rect {
    let n = hull.len();
    if n < 2 {
        return Rect {
            u: [1.0, 0.0],
            size: [0.0, 0.0],
        };
    }
    if n == 2 {
        let d = [hull[1][0] - hull[0][0], hull[1][1] - hull[0][1]];
        let len = dot(&d, &d).sqrt();
        if len == 0.0 {
            return Rect {
                u: [1.0, 0.0],
                size: [0.0, 0.0],
            };
        }
        return Rect {
            u: [d[0] / len, d[1] / len],
            size: [len, 0.0],
        };
    }
    let edge = |i: usize| -> Option<P2> {
        let (a, b) = (hull[i], hull[(i + 1) % n]);
        let d = [b[0] - a[0], b[1] - a[1]];
        let len = dot(&d, &d).sqrt();
        (len > 0.0).then(|| [d[0] / len, d[1] / len])
    };
    // Calipers: index of the max along u, of the max along w (left normal) and of the
    // min along u, advanced monotonically counter-clockwise.
    let (mut jmax_u, mut jmax_w, mut jmin_u) = (0usize, 0usize, 0usize);
    let mut best: Option<Rect> = None;
    let mut initialised = false;
    for i in 0..n {
        let Some(u) = edge(i) else { continue };
        let w = [-u[1], u[0]];
        if !initialised {
            let arg = |f: &dyn Fn(&P2) -> f64| {
                let mut k = 0;
                for j in 1..n {
                    if f(&hull[j]) > f(&hull[k]) {
                        k = j;
                    }
                }
                k
            };
            jmax_u = arg(&|p| dot(p, &u));
            jmax_w = arg(&|p| dot(p, &w));
            jmin_u = arg(&|p| -dot(p, &u));
            initialised = true;
        } else {
            for _ in 0..n {
                let nx = (jmax_u + 1) % n;
                if dot(&hull[nx], &u) >= dot(&hull[jmax_u], &u) {
                    jmax_u = nx;
                } else {
                    break;
                }
            }
            for _ in 0..n {
                let nx = (jmax_w + 1) % n;
                if dot(&hull[nx], &w) >= dot(&hull[jmax_w], &w) {
                    jmax_w = nx;
                } else {
                    break;
                }
            }
            for _ in 0..n {
                let nx = (jmin_u + 1) % n;
                if dot(&hull[nx], &u) <= dot(&hull[jmin_u], &u) {
                    jmin_u = nx;
                } else {
                    break;
                }
            }
        }
        let su = dot(&hull[jmax_u], &u) - dot(&hull[jmin_u], &u);
        let sw = dot(&hull[jmax_w], &w) - dot(&hull[i], &w);
        let r = Rect {
            u,
            size: [su.max(0.0), sw.max(0.0)],
        };
        if best.is_none_or(|b| r.area() < b.area()) {
            best = Some(r);
        }
    }
    best.unwrap_or(Rect {
        u: [1.0, 0.0],
        size: [0.0, 0.0],
    })
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

    /// Brute force over all hull edges.
    fn brute(hull: &[P2]) -> f64 {
        let n = hull.len();
        let mut best = f64::INFINITY;
        for i in 0..n {
            let (a, b) = (hull[i], hull[(i + 1) % n]);
            let d = [b[0] - a[0], b[1] - a[1]];
            let l = dot(&d, &d).sqrt();
            let u = [d[0] / l, d[1] / l];
            let w = [-u[1], u[0]];
            let pu: Vec<f64> = hull.iter().map(|p| dot(p, &u)).collect();
            let pw: Vec<f64> = hull.iter().map(|p| dot(p, &w)).collect();
            let span = |v: &[f64]| {
                v.iter().cloned().fold(f64::MIN, f64::max)
                    - v.iter().cloned().fold(f64::MAX, f64::min)
            };
            best = best.min(span(&pu) * span(&pw));
        }
        best
    }

    #[test]
    fn calipers_match_brute_force() {
        let mut s = 3;
        for trial in 0..200 {
            let n = 3 + trial % 40;
            let mut pts: Vec<P2> = (0..n)
                .map(|_| [lcg(&mut s) * 3.0 - 1.0, lcg(&mut s) - 0.5])
                .collect();
            let h = hull_2d(&mut pts);
            let r = min_area_rect(&h);
            let b = brute(&h);
            assert!(
                (r.area() - b).abs() <= 1e-12 * b.max(1.0),
                "{} vs {}",
                r.area(),
                b
            );
        }
    }

    #[test]
    fn hull_drops_collinear_and_duplicate_points() {
        let mut pts = vec![
            [0.0, 0.0],
            [1.0, 0.0],
            [2.0, 0.0],
            [2.0, 1.0],
            [0.0, 1.0],
            [1.0, 1.0],
            [1.0, 0.5],
            [0.0, 0.0],
        ];
        let h = hull_2d(&mut pts);
        assert_eq!(h.len(), 4);
        let r = min_area_rect(&h);
        assert!((r.area() - 2.0).abs() < 1e-15);
        let mut seg = vec![[0.0, 0.0], [1.0, 1.0], [2.0, 2.0], [1.0, 1.0]];
        let h = hull_2d(&mut seg);
        assert_eq!(h.len(), 2);
        let r = min_area_rect(&h);
        assert_eq!(r.area(), 0.0);
        assert!((r.size[0] - 8f64.sqrt()).abs() < 1e-15);
        let mut one = vec![[3.0, 4.0], [3.0, 4.0]];
        assert_eq!(hull_2d(&mut one).len(), 1);
    }
}
