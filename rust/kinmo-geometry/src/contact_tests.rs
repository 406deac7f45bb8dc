//! Tests of `contact.rs` on box meshes and seeded random triangles.

use super::*;

/// Axis-aligned box mesh from its lowest corner and size (12 triangles, outward normals).
fn cube(min: [f64; 3], size: [f64; 3]) -> (Vec<Point3<f64>>, Vec<[u32; 3]>) {
    crate::test_meshes::box_mesh(min, [min[0] + size[0], min[1] + size[1], min[2] + size[2]])
}

fn bvh(m: &(Vec<Point3<f64>>, Vec<[u32; 3]>)) -> MeshBvh {
    MeshBvh::new(&m.0, &m.1).expect("valid mesh")
}

/// Tiny deterministic generator (xorshift64*), values in [0, 1).
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        (self.0.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 11) as f64 / (1u64 << 53) as f64
    }
    fn point(&mut self, s: f64) -> Point3<f64> {
        Point3::new(self.next() * s, self.next() * s, self.next() * s)
    }
}

#[test]
fn cubes_at_gap_pair_iff_gap_within_tolerance() {
    // Dyadic values: `1 + gap` is exact, so `gap == tol` is on the boundary.
    let tol = 0.25;
    for &gap in &[0.0, 0.125, 0.2421875, 0.25, 0.2578125, 0.5, 3.0] {
        let a = bvh(&cube([0.0, 0.0, 0.0], [1.0, 1.0, 1.0]));
        let b = bvh(&cube([1.0 + gap, 0.3, -0.2], [1.0, 1.0, 1.0]));
        let pairs = contact_pairs(&[a.clone(), b.clone()], tol).expect("ok");
        assert_eq!(pairs.len(), usize::from(gap <= tol), "gap {gap}");
        if let Some(p) = pairs.first() {
            assert_eq!((p.i, p.j), (0, 1));
            assert!((p.distance - gap).abs() < 1e-12, "{} vs {gap}", p.distance);
        }
        let d = mesh_distance(&a, &b).expect("ok");
        assert!((d - gap).abs() < 1e-12, "{d} vs {gap}");
    }
}

#[test]
fn touching_and_intersecting_are_zero() {
    let a = bvh(&cube([0.0, 0.0, 0.0], [1.0, 1.0, 1.0]));
    // Shares a face patch.
    let touching = bvh(&cube([1.0, 0.5, 0.5], [1.0, 1.0, 1.0]));
    // Overlaps: surfaces cross.
    let crossing = bvh(&cube([0.5, 0.5, 0.5], [1.0, 1.0, 1.0]));
    // Touches only along an edge.
    let edge = bvh(&cube([1.0, 1.0, 0.2], [1.0, 1.0, 0.5]));
    for m in [&touching, &crossing, &edge] {
        assert_eq!(mesh_distance(&a, m).expect("ok"), 0.0);
        assert_eq!(distance_within(&a, m, 0.0), Some(0.0));
    }
    let pairs = contact_pairs(&[a, touching, crossing], 0.0).expect("ok");
    let ij: Vec<_> = pairs.iter().map(|p| (p.i, p.j)).collect();
    assert_eq!(ij, vec![(0, 1), (0, 2), (1, 2)]);
    assert!(pairs.iter().all(|p| p.distance == 0.0));
}

#[test]
fn nested_box_is_at_surface_distance() {
    let outer = bvh(&cube([0.0, 0.0, 0.0], [1.0, 1.0, 1.0]));
    let inner = bvh(&cube([0.3, 0.4, 0.2], [0.2, 0.2, 0.2]));
    let d = mesh_distance(&outer, &inner).expect("ok");
    assert!((d - 0.2).abs() < 1e-12, "{d}");
}

#[test]
fn far_apart_is_absent() {
    let a = bvh(&cube([0.0, 0.0, 0.0], [1.0, 1.0, 1.0]));
    let b = bvh(&cube([10.0, 10.0, 10.0], [1.0, 1.0, 1.0]));
    assert!(contact_pairs(&[a.clone(), b.clone()], 1.0)
        .expect("ok")
        .is_empty());
    assert_eq!(distance_within(&a, &b, 1.0), None);
    let d = mesh_distance(&a, &b).expect("ok");
    assert!((d - 9.0 * 3f64.sqrt()).abs() < 1e-12);
    // `tolerance²` overflows: no pair is reported beyond the tolerance.
    let huge = bvh(&cube([0.0; 3], [1e200; 3]));
    let huge_far = bvh(&cube([3e200, 0.0, 0.0], [1e200; 3]));
    assert!(contact_pairs(&[huge, huge_far], 1e160)
        .expect("ok")
        .is_empty());
}

#[test]
fn diagonal_gap_between_corners() {
    let a = bvh(&cube([0.0, 0.0, 0.0], [1.0, 1.0, 1.0]));
    let b = bvh(&cube([1.1, 1.2, 1.3], [1.0, 1.0, 1.0]));
    let want = (0.01f64 + 0.04 + 0.09).sqrt();
    assert!((mesh_distance(&a, &b).expect("ok") - want).abs() < 1e-12);
}

#[test]
fn broad_phase_matches_brute_force_on_random_boxes() {
    let mut rng = Rng(0x9E37_79B9_7F4A_7C15);
    let boxes: Vec<Aabb> = (0..300)
        .map(|_| {
            let c = rng.point(10.0);
            let s = rng.point(1.0);
            Aabb::new(c, c + s.coords)
        })
        .collect();
    for &tol in &[0.0, 0.1, 0.7] {
        let refs: Vec<Option<Aabb>> = boxes.iter().copied().map(Some).collect();
        let mut got = broad_phase(&refs, tol);
        got.sort_unstable();
        let mut want = Vec::new();
        for i in 0..boxes.len() {
            for j in i + 1..boxes.len() {
                if box_distance2(&boxes[i], &boxes[j]) <= tol * tol {
                    want.push((i, j));
                }
            }
        }
        assert!(!want.is_empty());
        assert_eq!(got, want, "tol {tol}");
    }
}

#[test]
fn contact_pairs_match_brute_force_on_random_boxes() {
    let mut rng = Rng(42);
    let meshes: Vec<_> = (0..60)
        .map(|_| {
            let c = rng.point(4.0);
            let s = rng.point(0.8);
            cube([c.x, c.y, c.z], [s.x + 0.05, s.y + 0.05, s.z + 0.05])
        })
        .collect();
    let bvhs: Vec<MeshBvh> = meshes.iter().map(bvh).collect();
    let tris: Vec<TriMesh> = meshes
        .iter()
        .map(|(v, f)| TriMesh::new(v.clone(), f.clone(), "m").expect("valid"))
        .collect();
    let tol = 0.1;
    let got = contact_pairs_of_meshes(&tris, tol).expect("ok");
    assert_eq!(got, contact_pairs(&bvhs, tol).expect("ok"));
    let mut want = Vec::new();
    for i in 0..bvhs.len() {
        for j in i + 1..bvhs.len() {
            let d = mesh_distance(&bvhs[i], &bvhs[j]).expect("ok");
            if d <= tol {
                want.push((i, j, d));
            }
        }
    }
    assert!(want.len() > 5);
    assert_eq!(got.len(), want.len());
    for (g, w) in got.iter().zip(&want) {
        assert_eq!((g.i, g.j), (w.0, w.1));
        assert!((g.distance - w.2).abs() < 1e-12);
    }
}

#[test]
fn broad_phase_boxes_are_the_hierarchy_root_boxes() {
    // contact_pairs_of_meshes decides which hierarchies to build from these boxes: they
    // must be exactly the root boxes, unreferenced vertices and tiny coordinates included.
    let mut rng = Rng(7);
    for n in [0usize, 1, 2, 17, 300] {
        let mut v: Vec<Point3<f64>> = (0..n + 3).map(|_| rng.point(3.0)).collect();
        v.push(Point3::new(1e-200, -1e-170, 50.0)); // never referenced
        v[0] = Point3::new(1e-160, 2.0, -1e-155);
        let f: Vec<[u32; 3]> = (0..n)
            .map(|k| [k as u32, (k + 1) as u32, (k + 2) as u32])
            .collect();
        let m = TriMesh::new(v, f, "m").expect("valid");
        for scale in [1.0, 0.25, 1024.0] {
            let root = MeshBvh::from_mesh_scaled(&m, scale).root_aabb();
            assert_eq!(scaled_aabb(&m, scale), root, "n = {n}, scale = {scale}");
        }
    }
}

#[test]
fn bvh_distance_matches_triangle_brute_force_and_parry() {
    use parry3d_f64::query;
    use parry3d_f64::shape::TriMesh;
    let mut rng = Rng(7);
    for trial in 0..20 {
        let soup = |rng: &mut Rng, off: f64| {
            let mut v = Vec::new();
            let mut f = Vec::new();
            for k in 0..40u32 {
                let c = rng.point(1.0) + Vector3::new(off, 0.0, 0.0);
                for _ in 0..3 {
                    v.push(c + (rng.point(0.3) - Point3::new(0.15, 0.15, 0.15)));
                }
                f.push([3 * k, 3 * k + 1, 3 * k + 2]);
            }
            (v, f)
        };
        let ma = soup(&mut rng, 0.0);
        let mb = soup(&mut rng, 0.6 + 0.05 * f64::from(trial));
        let (a, b) = (bvh(&ma), bvh(&mb));
        let got = mesh_distance(&a, &b).expect("ok");
        let mut brute = f64::INFINITY;
        let tris =
            |m: &MeshBvh| -> Vec<[Point3<f64>; 3]> { m.triangles.iter().map(|t| t.0).collect() };
        for ta in &tris(&a) {
            for tb in &tris(&b) {
                brute = brute.min(triangle_distance2(ta, tb).sqrt());
            }
        }
        assert_eq!(got, brute);
        let pa = TriMesh::new(ma.0.clone(), ma.1.clone()).expect("parry mesh");
        let pb = TriMesh::new(mb.0.clone(), mb.1.clone()).expect("parry mesh");
        let id = nalgebra::Isometry3::identity();
        let want = query::distance(&id, &pa, &id, &pb).expect("supported");
        assert!(
            (got - want).abs() < 1e-9,
            "trial {trial}: {got} vs parry {want}"
        );
    }
}

#[test]
fn triangle_distance_cases() {
    let t = [
        Point3::new(0.0, 0.0, 0.0),
        Point3::new(1.0, 0.0, 0.0),
        Point3::new(0.0, 1.0, 0.0),
    ];
    // Parallel triangle above: vertex-face distance.
    let up = t.map(|p| p + Vector3::new(0.1, 0.1, 0.5));
    assert!((triangle_distance2(&t, &up) - 0.25).abs() < 1e-15);
    // Piercing triangle: 0.
    let pierce = [
        Point3::new(0.2, 0.2, -1.0),
        Point3::new(0.3, 0.2, 1.0),
        Point3::new(0.2, 0.3, 1.0),
    ];
    assert_eq!(triangle_distance2(&t, &pierce), 0.0);
    // Coplanar, one inside the other: 0.
    let inner = [
        Point3::new(0.1, 0.1, 0.0),
        Point3::new(0.2, 0.1, 0.0),
        Point3::new(0.1, 0.2, 0.0),
    ];
    assert_eq!(triangle_distance2(&t, &inner), 0.0);
    // Degenerate (a segment, a point) triangles.
    let seg = [
        Point3::new(2.0, 0.0, 0.0),
        Point3::new(3.0, 0.0, 0.0),
        Point3::new(2.5, 0.0, 0.0),
    ];
    assert!((triangle_distance2(&t, &seg) - 1.0).abs() < 1e-15);
    let pt = [Point3::new(0.2, 0.2, 0.7); 3];
    assert!((triangle_distance2(&t, &pt) - 0.49).abs() < 1e-15);
    assert!((triangle_distance2(&pt, &t) - 0.49).abs() < 1e-15);
}

#[test]
fn degenerate_meshes_do_not_panic() {
    let p = Point3::new(0.5, 0.5, 0.5);
    // Zero-area triangles and duplicate vertices only.
    let v = vec![p, p, p, Point3::new(1.5, 0.5, 0.5)];
    let f = vec![[0, 1, 2], [0, 0, 3], [3, 3, 3]];
    let m = MeshBvh::new(&v, &f).expect("accepted");
    let c = bvh(&cube([0.0, 0.0, 0.0], [1.0, 1.0, 1.0]));
    assert_eq!(mesh_distance(&c, &m).expect("ok"), 0.0);
    let far = MeshBvh::new(&[p; 3], &[[0, 1, 2]]).expect("accepted");
    assert!((mesh_distance(&c, &far).expect("ok") - 0.5).abs() < 1e-15);
    // Many identical triangles: the build must terminate with leaves > LEAF_SIZE.
    let same = MeshBvh::new(&v, &vec![[0, 1, 3]; 100]).expect("accepted");
    assert_eq!(same.num_triangles(), 100);
    assert_eq!(mesh_distance(&same, &c).expect("ok"), 0.0);
    // Empty meshes pair with nothing; mesh_distance refuses them.
    let empty = MeshBvh::new(&[], &[]).expect("accepted");
    assert!(empty.is_empty());
    assert!(contact_pairs(&[empty.clone(), c.clone()], 1.0)
        .expect("ok")
        .is_empty());
    assert!(matches!(
        mesh_distance(&empty, &c),
        Err(GeometryError::Degenerate(_))
    ));
}

#[test]
fn bad_inputs_are_errors() {
    let (v, f) = cube([0.0; 3], [1.0; 3]);
    let mut bad = v.clone();
    bad[2].y = f64::NAN;
    assert!(matches!(
        MeshBvh::new(&bad, &f),
        Err(GeometryError::NonFinite { index: 7, .. })
    ));
    assert!(matches!(
        MeshBvh::new(&v, &[[0, 1, 8]]),
        Err(GeometryError::IndexOutOfRange {
            face: 0,
            vertex: 8,
            ..
        })
    ));
    let m = bvh(&(v, f));
    for tol in [-1.0, f64::NAN, f64::INFINITY] {
        assert!(matches!(
            contact_pairs(std::slice::from_ref(&m), tol),
            Err(GeometryError::Invalid(_))
        ));
    }
    let err = MeshBvh::with_name(&bad, &[[0, 1, 2]], "meshes[3]");
    assert!(err
        .expect_err("NaN")
        .to_string()
        .contains("meshes[3] vertices"));
}

#[test]
fn distances_are_scale_robust() {
    let tri = |m: &(Vec<Point3<f64>>, Vec<[u32; 3]>), s: f64| {
        let v = m.0.iter().map(|p| p * s).collect();
        TriMesh::new(v, m.1.clone(), "m").expect("valid")
    };
    let a = cube([0.0; 3], [1.0; 3]);
    let b = cube([1.5, 0.0, 0.0], [1.0; 3]);
    for s in [1.0, 1e200, 1e-300, 1e300, 3e-310] {
        let (ta, tb) = (tri(&a, s), tri(&b, s));
        let d = mesh_distance_of_meshes(&ta, &tb).expect("ok");
        assert!((d / (0.5 * s) - 1.0).abs() < 1e-9, "scale {s}: {d}");
        let pairs = contact_pairs_of_meshes(&[ta.clone(), tb.clone()], 0.6 * s).expect("ok");
        assert_eq!(pairs.len(), 1, "scale {s}");
        assert!((pairs[0].distance / (0.5 * s) - 1.0).abs() < 1e-9);
        assert!(contact_pairs_of_meshes(&[ta, tb], 0.4 * s)
            .expect("ok")
            .is_empty());
    }
}
