//! Property-based tests (proptest) of the pure-Rust geometry core: random, degenerate and
//! extreme inputs never panic, errors name their argument, and results keep their
//! invariants (boxes contain their points, contact pairs agree with the exact distance,
//! masks agree with brute force, samples lie on the mesh). Few cases each, so `cargo test`
//! stays fast.

use kinmo_geometry::contact::{contact_pairs_of_meshes, mesh_distance_of_meshes};
use kinmo_geometry::interaction::interaction_region;
use kinmo_geometry::mesh::{load_obj, TriMesh};
use kinmo_geometry::motion::{motions, unit_direction};
use kinmo_geometry::obb::fit_obb;
use kinmo_geometry::sampling::sample_surface;
use kinmo_geometry::GeometryError;
use nalgebra::{Point3, Vector3};
use proptest::prelude::*;

/// Coordinates in `[-1, 1]`: ordinary values, exact zeros and repeated values (the
/// extreme magnitudes come from the scale factors of the set strategies).
fn coord() -> impl Strategy<Value = f64> {
    prop_oneof![
        6 => -1.0f64..1.0,
        1 => Just(0.0),
        1 => prop::sample::select(vec![0.5, 0.25, -1.0, 1e-12]),
    ]
}

fn point() -> impl Strategy<Value = Point3<f64>> {
    (coord(), coord(), coord()).prop_map(|(x, y, z)| Point3::new(x, y, z))
}

/// Point sets, sometimes flattened onto a plane or a line (exact degeneracies), scaled.
fn points(max: usize) -> impl Strategy<Value = Vec<Point3<f64>>> {
    (
        prop::collection::vec(point(), 1..max),
        0u8..3,
        prop::sample::select(vec![1.0, 1e-200, 1e200, 1e-300, 1e300]),
    )
        .prop_map(|(mut p, flat, s)| {
            for q in &mut p {
                if flat >= 1 {
                    q.z = 0.0;
                }
                if flat >= 2 {
                    q.y = 2.0 * q.x;
                }
                *q *= s;
            }
            p
        })
}

/// Small meshes with possibly degenerate triangles (repeated or collinear vertices).
fn mesh() -> impl Strategy<Value = TriMesh> {
    (
        prop::collection::vec(point(), 3..10),
        prop::collection::vec(any::<[u8; 3]>(), 0..8),
        prop::sample::select(vec![1.0, 1e-300, 1e300]),
    )
        .prop_map(|(v, f, s)| {
            let n = v.len() as u32;
            let v = v.into_iter().map(|p| p * s).collect();
            let f = f.into_iter().map(|t| t.map(|i| u32::from(i) % n)).collect();
            TriMesh::new(v, f, "mesh").expect("valid by construction")
        })
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 48, ..ProptestConfig::default() })]

    #[test]
    fn obb_contains_its_points_with_orthonormal_axes(p in points(40)) {
        let b = fit_obb(&p).expect("finite non-empty points always fit");
        let scale = p.iter().map(|q| q.coords.amax()).fold(0.0, f64::max);
        prop_assert!((b.axes * b.axes.transpose() - nalgebra::Matrix3::identity()).amax() < 1e-9);
        for q in &p {
            prop_assert!(b.contains(q, 1e-9 * scale.max(f64::MIN_POSITIVE)), "{q} outside");
        }
    }

    #[test]
    fn obb_errors_name_the_points(mut p in points(10), i in 0usize..10, bad in prop::sample::select(vec![f64::NAN, f64::INFINITY])) {
        let i = i % p.len();
        p[i].y = bad;
        match fit_obb(&p) {
            Err(GeometryError::NonFinite { what, index }) => {
                prop_assert_eq!(what, "points");
                prop_assert_eq!(index, 3 * i + 1);
            }
            other => prop_assert!(false, "expected NonFinite, got {:?}", other),
        }
    }

    #[test]
    fn contact_pairs_agree_with_mesh_distance(ms in prop::collection::vec(mesh(), 1..4), t in 0.0f64..0.5) {
        let scale = ms.iter().flat_map(|m| m.vertices()).map(|p| p.coords.amax()).fold(0.0, f64::max);
        let tol = t * scale;
        let pairs = contact_pairs_of_meshes(&ms, tol).expect("valid tolerance");
        for i in 0..ms.len() {
            for j in i + 1..ms.len() {
                let d = mesh_distance_of_meshes(&ms[i], &ms[j]);
                let found = pairs.iter().find(|p| (p.i, p.j) == (i, j));
                match d {
                    Ok(d) => {
                        prop_assert!(d.is_finite() && d >= 0.0);
                        if let Some(p) = found {
                            prop_assert!(p.distance <= tol && (p.distance - d).abs() <= 1e-12 * scale);
                        } else {
                            prop_assert!(d > tol * (1.0 - 1e-12), "missed pair at {d} <= {tol}");
                        }
                    }
                    Err(e) => {
                        prop_assert!(found.is_none());
                        prop_assert!(e.to_string().contains("mesh_"), "{e}");
                    }
                }
            }
        }
    }

    #[test]
    fn interaction_masks_match_brute_force(a in points(30), b in points(30), r in 0.01f64..1.0) {
        let scale = a.iter().chain(&b).map(|p| p.coords.amax()).fold(0.0, f64::max).max(1e-300);
        let radius = r * scale;
        let reg = interaction_region(&a, &b, radius).expect("valid input");
        let near = |p: &Point3<f64>, set: &[Point3<f64>]| {
            set.iter().any(|q| ((p - q) / scale).norm_squared() <= (radius / scale).powi(2))
        };
        // Squared distances of extreme sets may under/overflow in either computation:
        // compare on ordinary scales only.
        if (1e-100..1e100).contains(&scale) {
            for (p, &m) in a.iter().zip(&reg.mask_moving) {
                prop_assert_eq!(m, near(p, &b));
            }
        }
        prop_assert_eq!(reg.empty, !reg.mask_moving.iter().any(|&m| m));
    }

    #[test]
    fn samples_lie_in_the_mesh_bounds(m in mesh(), n in 1usize..64, seed in any::<u64>()) {
        match sample_surface(&m, n, seed) {
            Ok((p, f)) => {
                prop_assert_eq!(p.len(), n);
                let (lo, hi) = m.vertices().iter().fold(
                    (Point3::from([f64::INFINITY; 3]), Point3::from([f64::NEG_INFINITY; 3])),
                    |(lo, hi), q| (lo.inf(q), hi.sup(q)),
                );
                for (q, &fi) in p.iter().zip(&f) {
                    prop_assert!((fi as usize) < m.n_faces());
                    let slack = 1e-12 * (hi - lo).amax();
                    prop_assert!((0..3).all(|k| q[k] >= lo[k] - slack && q[k] <= hi[k] + slack));
                }
            }
            Err(e) => prop_assert!(matches!(e, GeometryError::Degenerate(_)), "{e}"),
        }
    }

    #[test]
    fn directions_of_any_scale_are_unit(d in (coord(), coord(), coord()), s in prop::sample::select(vec![1.0, 1e-300, 1e300, f64::MAX])) {
        let d = Vector3::new(d.0, d.1, d.2) * s;
        match unit_direction(&d) {
            Some(u) => prop_assert!((u.norm() - 1.0).abs() < 1e-12),
            None => prop_assert!(d.amax() == 0.0 || !d.amax().is_finite()),
        }
        let r = motions(&[Point3::origin()], &[d], &[0.3], &[0.0]);
        if let Err(e) = r {
            prop_assert!(e.to_string().starts_with("directions"), "{e}");
        }
    }

    #[test]
    fn load_obj_never_panics(bytes in prop::collection::vec(any::<u8>(), 0..200), text in "[vf0-9 .e+\\-\n#a-z]{0,200}") {
        let dir = std::env::temp_dir().join(format!("kinmo-prop-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("temp dir");
        for (k, content) in [bytes, text.into_bytes()].into_iter().enumerate() {
            let path = dir.join(format!("random{k}.obj"));
            std::fs::write(&path, &content).expect("write");
            match load_obj(&path) {
                Ok(m) => prop_assert!(m.vertices().iter().all(|p| p.coords.amax() <= f64::from(f32::MAX))),
                Err(e) => prop_assert!(e.to_string().contains("random"), "{e}"),
            }
        }
    }
}
