//! Unit tests of the OBB fitting.

use super::*;
use nalgebra::{Rotation3, Unit};

fn lcg(seed: &mut u64) -> f64 {
    *seed = seed
        .wrapping_mul(6364136223846793005)
        .wrapping_add(1442695040888963407);
    ((*seed >> 11) as f64) / ((1u64 << 53) as f64)
}

fn random_rotation(seed: &mut u64) -> Rotation3<f64> {
    let axis = Vector3::new(lcg(seed) - 0.5, lcg(seed) - 0.5, lcg(seed) - 0.5);
    Rotation3::from_axis_angle(&Unit::new_normalize(axis), 0.3 + 2.5 * lcg(seed))
}

/// Points of an axis-aligned box `[-h, h]` moved by `rot` and `center`.
fn box_points(
    h: [f64; 3],
    rot: &Rotation3<f64>,
    center: Vector3<f64>,
    interior: usize,
    seed: &mut u64,
) -> Vec<Point3<f64>> {
    let mut local = Vec::new();
    for i in 0..8 {
        let s = |k: usize| if (i >> k) & 1 == 1 { 1.0 } else { -1.0 };
        local.push(Vector3::new(s(0) * h[0], s(1) * h[1], s(2) * h[2]));
    }
    for _ in 0..interior {
        local.push(Vector3::new(
            (2.0 * lcg(seed) - 1.0) * h[0],
            (2.0 * lcg(seed) - 1.0) * h[1],
            (2.0 * lcg(seed) - 1.0) * h[2],
        ));
    }
    local
        .iter()
        .map(|v| Point3::from(rot * v + center))
        .collect()
}

fn assert_frame(b: &Obb) {
    let a = b.axes;
    assert!(
        (a * a.transpose() - Matrix3::identity()).abs().max() < 1e-12,
        "not orthonormal: {a}"
    );
    let (r0, r1, r2) = (
        a.row(0).transpose(),
        a.row(1).transpose(),
        a.row(2).transpose(),
    );
    assert!((r0.cross(&r1) - r2).norm() < 1e-12, "not right-handed: {a}");
    assert!(b.half_extents.iter().all(|h| *h >= 0.0 && h.is_finite()));
    let h = b.half_extents;
    let tie = CANON_TIE * h[0];
    assert!(h[0] >= h[1] - tie && h[1] >= h[2] - tie);
    // Canonical signs of rows 0 and 1: the largest-magnitude component is positive.
    for r in [r0, r1] {
        assert!(r[dominant_axis(&r)] > 0.0, "row {r} not canonically signed");
    }
}

fn assert_contains(b: &Obb, pts: &[Point3<f64>]) {
    let size = pts
        .iter()
        .flat_map(|p| pts.iter().map(move |q| (p - q).norm()))
        .fold(0.0, f64::max)
        .max(1e-300);
    for p in pts {
        assert!(b.contains(p, 1e-9 * size), "{p} outside {b:?}");
    }
}

#[test]
fn rotated_box_gives_back_the_box() {
    let mut s = 1;
    for _ in 0..20 {
        let rot = random_rotation(&mut s);
        let c = Vector3::new(lcg(&mut s) * 10.0, -3.0, 2.0);
        for interior in [0, 50] {
            let pts = box_points([1.0, 3.0, 2.0], &rot, c, interior, &mut s);
            let b = fit_obb(&pts).unwrap();
            assert_frame(&b);
            assert_contains(&b, &pts);
            assert!(
                (b.half_extents - Vector3::new(3.0, 2.0, 1.0)).abs().max() < 1e-9,
                "{}",
                b.half_extents
            );
            assert!((b.center.coords - c).norm() < 1e-9);
            // Row k of the result is the rotated local axis of half-extent 3, 2, 1.
            for (k, local) in [1usize, 2, 0].iter().enumerate() {
                let mut e = Vector3::zeros();
                e[*local] = 1.0;
                let expected = rot * e;
                let got: Vector3<f64> = b.axes.row(k).transpose();
                assert!(
                    got.dot(&expected).abs() > 1.0 - 1e-12,
                    "{got} vs {expected}"
                );
            }
        }
    }
}

#[test]
fn random_clouds_are_contained_in_orthonormal_boxes() {
    let mut s = 2;
    for trial in 0..30 {
        let rot = random_rotation(&mut s);
        let n = 4 + trial * 7;
        let pts: Vec<Point3<f64>> = (0..n)
            .map(|_| {
                let v = Vector3::new(lcg(&mut s) * 5.0, lcg(&mut s), lcg(&mut s) * 0.2);
                Point3::from(rot * v + Vector3::new(100.0, 0.0, -50.0))
            })
            .collect();
        let b = fit_obb(&pts).unwrap();
        assert_frame(&b);
        assert_contains(&b, &pts);
        // Never looser than the PCA box or the axis-aligned box.
        let pca = pca_frame(&pts);
        assert!(b.volume() <= 1.01 * volume(&pca, &pts) * (1.0 + 1e-12));
        assert!(b.volume() <= 1.01 * volume(&identity(), &pts) * (1.0 + 1e-12));
    }
}

#[test]
fn result_does_not_depend_on_point_order() {
    let mut s = 3;
    let rot = random_rotation(&mut s);
    let mut pts: Vec<Point3<f64>> = (0..300)
        .map(|_| {
            let v = Vector3::new(lcg(&mut s), lcg(&mut s) * 0.5, lcg(&mut s) * 0.25);
            Point3::from(rot * v)
        })
        .collect();
    let a = fit_obb(&pts).unwrap();
    for _ in 0..5 {
        // Fisher-Yates with the test generator, plus duplicates.
        for i in (1..pts.len()).rev() {
            let j = (lcg(&mut s) * (i + 1) as f64) as usize;
            pts.swap(i, j.min(i));
        }
        let mut dup = pts.clone();
        dup.extend_from_slice(&pts[..10]);
        assert_eq!(fit_obb(&pts).unwrap(), a);
        assert_eq!(fit_obb(&dup).unwrap(), a);
    }
}

#[test]
fn degenerate_sets_do_not_fail() {
    let p = |x: f64, y: f64, z: f64| Point3::new(x, y, z);
    // One point, repeated.
    let b = fit_obb(&[p(1.0, 2.0, 3.0); 3]).unwrap();
    assert_frame(&b);
    assert_eq!(b.half_extents, Vector3::zeros());
    assert_eq!(b.center, p(1.0, 2.0, 3.0));
    // Exact ties of all half-extents: rows ordered y, x, then z = y x x.
    assert_eq!(
        b.axes,
        Matrix3::new(0.0, 1.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, -1.0)
    );
    // Collinear points (and a pair).
    let line: Vec<_> = (0..7)
        .map(|i| p(1.0 + i as f64, 2.0 * i as f64, -0.5 * i as f64))
        .collect();
    for pts in [&line[..], &line[..2]] {
        let b = fit_obb(pts).unwrap();
        assert_frame(&b);
        assert_contains(&b, pts);
        assert!(b.half_extents[0] > 0.0);
        assert_eq!((b.half_extents[1], b.half_extents[2]), (0.0, 0.0));
        let d = (pts[1] - pts[0]).normalize();
        assert!(b.axes.row(0).transpose().dot(&d).abs() > 1.0 - 1e-12);
        // The up axis is put in the frame: y projected across the line is row 1.
        let e = (Vector3::y() - d * d.y).normalize();
        assert!(b.axes.row(1).transpose().dot(&e).abs() > 1.0 - 1e-12);
    }
    // Coplanar points: a tilted rectangle with interior points, and a horizontal one.
    let mut s = 4;
    let rot = random_rotation(&mut s);
    let mut rect: Vec<_> = box_points(
        [2.0, 0.5, 0.0],
        &rot,
        Vector3::new(1.0, 1.0, 1.0),
        20,
        &mut s,
    );
    rect.dedup();
    let b = fit_obb(&rect).unwrap();
    assert_frame(&b);
    assert_contains(&b, &rect);
    assert!(
        (b.half_extents - Vector3::new(2.0, 0.5, 0.0)).abs().max() < 1e-9,
        "{}",
        b.half_extents
    );
    let flat: Vec<_> = (0..12)
        .map(|i| p((i % 4) as f64, 0.25, (i / 4) as f64 * 0.5))
        .collect();
    let b = fit_obb(&flat).unwrap();
    assert_frame(&b);
    assert_eq!(b.half_extents, Vector3::new(1.5, 0.5, 0.0));
    assert_eq!(b.axes.row(2).transpose().abs(), Vector3::y());
}

#[test]
fn cube_ties_follow_the_canonical_order() {
    let mut s = 5;
    let pts = box_points(
        [1.0, 1.0, 1.0],
        &Rotation3::identity(),
        Vector3::zeros(),
        10,
        &mut s,
    );
    let b = fit_obb(&pts).unwrap();
    assert_eq!(
        b.axes,
        Matrix3::new(0.0, 1.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, -1.0)
    );
    assert_eq!(b.half_extents, Vector3::new(1.0, 1.0, 1.0));
}

#[test]
fn canonicalize_sorts_and_signs_rows() {
    let v = Vector3::new(0.0, -0.6, 0.8);
    let f = [-Vector3::x(), v, (-Vector3::x()).cross(&v)];
    let (axes, half) = canonicalize(f, [1.0, 3.0, 2.0]);
    assert_eq!(half, [3.0, 2.0, 1.0]);
    assert_eq!(axes[0], v); // largest component (z) already positive
    assert_eq!(axes[1], Vector3::new(0.0, 0.8, 0.6)); // y made positive
    assert!((axes[2] - Vector3::new(-1.0, 0.0, 0.0)).norm() < 1e-15);
    // Ties (within 1e-6 relative) are ordered y, x, z.
    let (axes, half) = canonicalize(
        [-Vector3::x(), Vector3::y(), -Vector3::z()],
        [2.0, 2.0 + 1e-7, 1.0],
    );
    assert_eq!(axes, [Vector3::y(), Vector3::x(), -Vector3::z()]);
    assert_eq!(half, [2.0 + 1e-7, 2.0, 1.0]);
}

/// A prism along x whose cross-section is a regular 64-gon with vertices on the y and z
/// axes: the minimum box is flush with a polygon edge (tilted by 2.8 degrees), the
/// y-aligned box is 0.24% larger.
fn polygon_prism(n: usize) -> Vec<Point3<f64>> {
    let mut pts = Vec::new();
    for i in 0..n {
        let t = 2.0 * std::f64::consts::PI * i as f64 / n as f64;
        for x in [-2.0, 2.0] {
            pts.push(Point3::new(x, 0.5 * t.cos(), 0.5 * t.sin()));
        }
    }
    pts
}

#[test]
fn up_aligned_box_is_preferred_among_near_minimal_ones() {
    let pts = polygon_prism(64);
    let tight = fit_obb_with(
        &pts,
        &ObbParams {
            volume_tolerance: 0.0,
            ..Default::default()
        },
    )
    .unwrap();
    let b = fit_obb(&pts).unwrap();
    let up_dot = |b: &Obb| (0..3).map(|k| b.axes[(k, 1)].abs()).fold(0.0, f64::max);
    assert!(
        up_dot(&tight) < (1f64).to_radians().cos(),
        "minimum box is tilted"
    );
    assert!(
        up_dot(&b) >= 1.0 - 1e-12,
        "chosen box is y-aligned: {}",
        b.axes
    );
    assert!(b.volume() <= 1.01 * tight.volume());
    assert!(b.volume() > tight.volume() * (1.0 + 1e-4));
    assert_contains(&b, &pts);
}

#[test]
fn symmetric_box_is_preferred_among_equal_volume_ones() {
    // An isosceles triangle extruded along y: the three edge-flush boxes have the same
    // volume (twice the triangle area times the height); only the base-flush one has the
    // triangle's mirror plane as a mid-plane.
    let rot = Rotation3::from_axis_angle(&Vector3::y_axis(), 0.5);
    let tri = [(-1.0, 0.0), (1.0, 0.0), (0.0, 3.0)];
    let pts: Vec<Point3<f64>> = tri
        .iter()
        .flat_map(|&(x, z)| [0.0, 0.7].map(|y| Point3::from(rot * Vector3::new(x, y, z))))
        .collect();
    let mirror = rot * Vector3::x();
    for up in [Some(Vector3::y()), None] {
        let b = fit_obb_with(
            &pts,
            &ObbParams {
                up,
                ..Default::default()
            },
        )
        .unwrap();
        assert!((b.volume() - 2.0 * 3.0 * 0.7).abs() < 1e-9);
        let aligned = (0..3).any(|k| b.axes.row(k).transpose().dot(&mirror).abs() > 1.0 - 1e-9);
        assert!(aligned, "no axis normal to the mirror plane: {}", b.axes);
    }
}

#[test]
fn refinement_beats_the_face_flush_family() {
    // A regular tetrahedron: its minimum box (a cube of side 1 around the tetrahedron
    // with vertices on alternate cube corners) has no face flush with a tetrahedron face.
    let pts = [
        Point3::new(1.0, 1.0, 1.0),
        Point3::new(1.0, -1.0, -1.0),
        Point3::new(-1.0, 1.0, -1.0),
        Point3::new(-1.0, -1.0, 1.0),
    ];
    let rot = Rotation3::from_euler_angles(0.3, 0.2, 0.1);
    let pts: Vec<Point3<f64>> = pts.iter().map(|p| rot * p).collect();
    let no_refine = ObbParams {
        refine: false,
        up: None,
        ..Default::default()
    };
    let flush = fit_obb_with(&pts, &no_refine).unwrap();
    let b = fit_obb_with(
        &pts,
        &ObbParams {
            up: None,
            ..Default::default()
        },
    )
    .unwrap();
    assert!(
        b.volume() < flush.volume() * 0.99,
        "{} vs {}",
        b.volume(),
        flush.volume()
    );
    assert!(b.volume() <= 8.0 * (1.0 + 1e-6), "{}", b.volume());
    assert_contains(&b, &pts);
}

#[test]
fn bad_input_is_an_error() {
    assert!(matches!(fit_obb(&[]), Err(GeometryError::Degenerate(_))));
    let pts = [Point3::new(0.0, 0.0, 0.0), Point3::new(1.0, f64::NAN, 0.0)];
    assert_eq!(
        fit_obb(&pts),
        Err(GeometryError::NonFinite {
            what: "points".into(),
            index: 4
        })
    );
    let huge = [Point3::new(-1e308, 0.0, 0.0), Point3::new(1e308, 1.0, 0.0)];
    assert!(
        matches!(fit_obb(&huge), Err(GeometryError::Invalid(m)) if m.starts_with("points: coordinate range"))
    );
    let ok = [Point3::new(0.0, 0.0, 0.0)];
    for p in [
        ObbParams {
            volume_tolerance: -1.0,
            ..Default::default()
        },
        ObbParams {
            up: Some(Vector3::zeros()),
            ..Default::default()
        },
        ObbParams {
            up_angle_deg: f64::NAN,
            ..Default::default()
        },
    ] {
        assert!(matches!(
            fit_obb_with(&ok, &p),
            Err(GeometryError::Invalid(_))
        ));
    }
}

#[test]
fn batch_matches_single_fits_and_names_the_failing_set() {
    let mut s = 6;
    let sets: Vec<Vec<Point3<f64>>> = (0..10)
        .map(|i| {
            let rot = random_rotation(&mut s);
            box_points(
                [1.0 + i as f64, 0.5, 0.25],
                &rot,
                Vector3::zeros(),
                5 * i,
                &mut s,
            )
        })
        .collect();
    let p = ObbParams::default();
    let batch = fit_obb_batch(&sets, &p).unwrap();
    for (set, b) in sets.iter().zip(&batch) {
        assert_eq!(fit_obb(set).unwrap(), *b);
    }
    let mut bad = sets.clone();
    bad[3].clear();
    bad[7].clear();
    match fit_obb_batch(&bad, &p) {
        Err(GeometryError::Degenerate(msg)) => assert!(msg.starts_with("point_sets[3]"), "{msg}"),
        other => panic!("{other:?}"),
    }
}

#[test]
fn adversarial_sets_are_contained() {
    // Lattices (coplanar faces), nearly planar / collinear noise, tiny parts far from the
    // origin, rounded duplicates and wild anisotropy; containment within 1e-9 of the size
    // plus the rounding of the coordinates themselves.
    let mut s = 8;
    let rot = random_rotation(&mut s);
    for trial in 0..400 {
        let n = 1 + (lcg(&mut s) * 40.0) as usize;
        let pts: Vec<Point3<f64>> = (0..n)
            .map(|_| {
                let (a, b, c) = (lcg(&mut s) - 0.5, lcg(&mut s) - 0.5, lcg(&mut s) - 0.5);
                let v = match trial % 6 {
                    0 => Vector3::new((a * 5.0).round(), (b * 5.0).round(), (c * 5.0).round()),
                    1 => rot * Vector3::new(a, b, c * 1e-15),
                    2 => rot * Vector3::new(a, b * 1e-14, c * 1e-14),
                    3 => Vector3::new(a, b, c) * 1e-9 + Vector3::repeat(1e6),
                    4 => Vector3::new((a * 100.0).round(), (b * 100.0).round(), c) / 100.0,
                    _ => Vector3::new(a * 1e6, b, c * 1e-6),
                };
                Point3::from(v)
            })
            .collect();
        let b = fit_obb(&pts).unwrap();
        assert_frame(&b);
        let size = pts
            .iter()
            .flat_map(|p| pts.iter().map(move |q| (p - q).norm()))
            .fold(0.0, f64::max);
        let scale = pts.iter().map(|p| p.coords.amax()).fold(0.0, f64::max);
        let tol = 1e-9 * size + 8.0 * f64::EPSILON * scale;
        for p in &pts {
            assert!(b.contains(p, tol), "trial {trial}: {p} outside {b:?}");
        }
    }
}

#[test]
fn coplanar_nearly_collinear_points_get_a_thin_box() {
    // Three exactly coplanar points, 1e-14 off a line: the plane normal must stay
    // orthogonal to the line, or the zero half-extent along it would cut points off.
    let d = Vector3::new(0.3, -1.2, 0.8);
    let pts = [
        Point3::from(d * -0.7 + Vector3::new(1e-14, 0.0, 0.0)),
        Point3::from(d * 0.2),
        Point3::from(d * 0.9 + Vector3::new(0.0, 3e-14, 0.0)),
    ];
    let b = fit_obb(&pts).unwrap();
    assert_frame(&b);
    assert_contains(&b, &pts);
    assert!(
        b.half_extents[1] < 1e-13 && b.half_extents[2] < 1e-13,
        "{}",
        b.half_extents
    );
}

/// A prism of length 2 along `axis` (unit) whose cross-section is a regular `n`-gon of
/// radius 0.3, turned by `roll` about `axis`: a round part such as a knob, a cap or a nail.
fn round_prism(axis: Vector3<f64>, n: usize, roll: f64) -> Vec<Point3<f64>> {
    let a = axis.normalize();
    let (u, v) = plane_basis(&a);
    let mut pts = Vec::new();
    for i in 0..n {
        let t = roll + 2.0 * std::f64::consts::PI * i as f64 / n as f64;
        let r = (u * t.cos() + v * t.sin()) * 0.3;
        for s in [-1.0, 1.0] {
            pts.push(Point3::from(r + a * s));
        }
    }
    pts
}

/// `p` turned `q` quarter turns about the world axis `k`, exactly (coordinates permuted and
/// negated, no rounding).
fn quarter_turned(p: &Point3<f64>, k: usize, q: usize) -> Point3<f64> {
    let (i, j) = ((k + 1) % 3, (k + 2) % 3);
    let mut c = p.coords;
    for _ in 0..q {
        let (ci, cj) = (c[i], c[j]);
        c[i] = -cj;
        c[j] = ci;
    }
    Point3::from(c)
}

#[test]
fn round_part_is_rolled_into_world_alignment() {
    // lying along z and along x, standing along y, each at several rolls: the near-minimal
    // boxes of every roll compete, and the world-aligned one is chosen
    for axis in [Vector3::z(), Vector3::x(), Vector3::y()] {
        for roll in [0.0, 0.3, 0.77, 1.1] {
            let pts = round_prism(axis, 96, roll);
            let b = fit_obb(&pts).unwrap();
            let rows: Frame = [0, 1, 2].map(|k| b.axes.row(k).transpose());
            assert!(
                world_alignment(&rows) > 3.0 - 1e-9,
                "axis {axis:?}, roll {roll}: box not world-aligned: {}",
                b.axes
            );
            assert_frame(&b);
            assert_contains(&b, &pts);
        }
    }
}

#[test]
fn quarter_turns_about_world_axes_turn_the_box() {
    // Round parts slightly tilted (as a nail of a MuJoCo model, 0.001 off horizontal): the
    // box of the turned points is the turned box, so a quarter turn of an asset changes
    // no part's box (issue 36's rotation criterion).
    let tilted = |d: Vector3<f64>| (d + Vector3::new(0.0, 1e-3, 0.0)).normalize();
    for axis in [tilted(Vector3::z()), tilted(Vector3::x()), Vector3::y()] {
        for (n, roll) in [(96, 0.3), (32, 0.77), (12, 0.1)] {
            let pts = round_prism(axis, n, roll);
            let b0 = fit_obb(&pts).unwrap();
            for q in 1..4 {
                let turned: Vec<Point3<f64>> =
                    pts.iter().map(|p| quarter_turned(p, 1, q)).collect();
                let b = fit_obb(&turned).unwrap();
                assert!(
                    (b.half_extents - b0.half_extents).abs().max() < 1e-9,
                    "n {n}, turn {q}: extents {} vs {}",
                    b.half_extents,
                    b0.half_extents
                );
                // the same box: every row parallel to a turned row of equal half-extent
                // (tied rows may come in another order)
                for k in 0..3 {
                    let got = b.axes.row(k).transpose();
                    let found = (0..3).any(|m| {
                        let r0 = Point3::from(b0.axes.row(m).transpose());
                        (b.half_extents[k] - b0.half_extents[m]).abs() < 1e-9
                            && got.dot(&quarter_turned(&r0, 1, q).coords).abs() > 1.0 - 1e-9
                    });
                    assert!(
                        found,
                        "n {n}, turn {q}, row {k}: {got:?} is no turned row of {}",
                        b0.axes
                    );
                }
            }
        }
    }
}
