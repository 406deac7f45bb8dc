//! Tests of `sweep.rs`: swept collisions against brute-force references and proptest
//! properties, then extreme magnitudes.

use super::*;
use proptest::prelude::*;
use std::f64::consts::FRAC_PI_2;

use crate::test_meshes::box_mesh as boxed;

/// Concatenate boxes into one mesh.
fn mesh_of(boxes: &[([f64; 3], [f64; 3])]) -> TriMesh {
    let mut v = Vec::new();
    let mut f = Vec::new();
    for (lo, hi) in boxes {
        let (bv, bf) = boxed(*lo, *hi);
        let off = v.len() as u32;
        v.extend(bv);
        f.extend(bf.into_iter().map(|t| [t[0] + off, t[1] + off, t[2] + off]));
    }
    TriMesh::new(v, f, "test").unwrap()
}

/// `n x n` cell-centred points on each of the 6 faces of a box.
fn box_points(lo: [f64; 3], hi: [f64; 3], n: usize) -> Vec<Point3<f64>> {
    let mut out = Vec::new();
    for axis in 0..3 {
        let (a, b) = ((axis + 1) % 3, (axis + 2) % 3);
        for side in [lo[axis], hi[axis]] {
            for i in 0..n {
                for j in 0..n {
                    let mut p = [0.0; 3];
                    p[axis] = side;
                    p[a] = lo[a] + (hi[a] - lo[a]) * (i as f64 + 0.5) / n as f64;
                    p[b] = lo[b] + (hi[b] - lo[b]) * (j as f64 + 0.5) / n as f64;
                    out.push(Point3::new(p[0], p[1], p[2]));
                }
            }
        }
    }
    out
}

fn revolute(origin: [f64; 3], dir: [f64; 3], range: f64) -> SweepCandidate {
    SweepCandidate {
        origin: Point3::from(origin),
        direction: Vector3::from(dir),
        kind: MotionKind::Revolute,
        range,
    }
}

fn prismatic(dir: [f64; 3], range: f64) -> SweepCandidate {
    SweepCandidate {
        origin: Point3::origin(),
        direction: Vector3::from(dir),
        kind: MotionKind::Prismatic,
        range,
    }
}

/// A door `[0, 1] x [0, 1] x [0, 0.02]` lying on the front face (z = 0) of a body box.
fn door_and_body() -> (Vec<Point3<f64>>, TriMesh) {
    let door = box_points([0.0, 0.0, 0.0], [1.0, 1.0, 0.02], 8);
    let body = mesh_of(&[([0.0, 0.0, -0.5], [1.0, 1.0, 0.0])]);
    (door, body)
}

#[test]
fn door_hinge_side_is_free_and_the_opposite_edge_collides_early() {
    let (door, body) = door_and_body();
    // About -y, a positive angle swings x > pivot towards +z (out of the body).
    let cands = [
        revolute([0.0, 0.0, 0.02], [0.0, -1.0, 0.0], FRAC_PI_2),
        revolute([1.0, 0.0, 0.02], [0.0, -1.0, 0.0], FRAC_PI_2),
    ];
    let r = sweep_collisions(&door, &body, &cands, &SweepParams::default()).unwrap();
    // The hinge edge: positive sign free, no point collides (contact at rest ignored).
    assert_eq!(r[0].free_fraction[0], 1.0);
    assert_eq!(r[0].colliding_fraction[0], 0.0);
    // Its negative sign swings the door into the body at once.
    assert!(r[0].free_fraction[1] < 0.1, "{:?}", r[0]);
    assert!(r[0].colliding_fraction[1] > 0.3, "{:?}", r[0]);
    // The opposite edge with the same direction: positive collides early, negative free.
    assert!(r[1].free_fraction[0] < 0.1, "{:?}", r[1]);
    assert_eq!(r[1].free_fraction[1], 1.0);
    assert_eq!(r[1].colliding_fraction[1], 0.0);
}

#[test]
fn points_inside_the_obstacle_at_rest_do_not_block_the_motion() {
    // A plate sunk 0.05 into a wall (deeper than the skin): its back and the sunk part
    // of its sides are inside the wall at rest; pulling it out, their crossings are
    // exits, not collisions.
    let plate = box_points([0.0, 0.0, -0.05], [1.0, 1.0, 0.02], 8);
    let wall = mesh_of(&[([-1.0, -1.0, -0.5], [2.0, 2.0, 0.0])]);
    let pull = [prismatic([0.0, 0.0, 1.0], 0.5)];
    let on = SweepParams::default();
    let r = sweep_collisions(&plate, &wall, &pull, &on).unwrap();
    assert_eq!(r[0].free_fraction[0], 1.0, "{:?}", r[0]);
    assert_eq!(r[0].colliding_fraction[0], 0.0, "{:?}", r[0]);
    // Pushed in, the front (outside at rest) meets the wall after 0.02 of 0.5.
    assert!(r[0].free_fraction[1] <= 0.02 / 0.5 + 1e-9, "{:?}", r[0]);
    let off = SweepParams {
        skip_inside: false,
        ..on
    };
    let r = sweep_collisions(&plate, &wall, &pull, &off).unwrap();
    assert!(r[0].free_fraction[0] < 0.2, "{:?}", r[0]);
    assert!(r[0].colliding_fraction[0] > 0.2, "{:?}", r[0]);
}

#[test]
fn parity_tells_inside_from_outside_of_a_closed_mesh() {
    let (v, f) = boxed([0.0, 0.0, 0.0], [1.0, 1.0, 1.0]);
    let mesh = ParryMesh::new(v, f).unwrap();
    let diag = 3f64.sqrt();
    assert!(inside_by_parity(&mesh, &Point3::new(0.5, 0.5, 0.5), diag));
    assert!(inside_by_parity(&mesh, &Point3::new(0.9, 0.1, 0.2), diag));
    assert!(!inside_by_parity(&mesh, &Point3::new(1.5, 0.5, 0.5), diag));
    assert!(!inside_by_parity(
        &mesh,
        &Point3::new(-0.2, -0.3, 2.0),
        diag
    ));
    // Two nested boxes: inside the inner box means crossing both walls (even).
    let nested = mesh_of(&[([0.0; 3], [1.0; 3]), ([0.25; 3], [0.75; 3])]);
    let parry = ParryMesh::new(nested.vertices().to_vec(), nested.faces().to_vec()).unwrap();
    assert!(!inside_by_parity(&parry, &Point3::new(0.5, 0.5, 0.5), diag));
    assert!(inside_by_parity(&parry, &Point3::new(0.1, 0.5, 0.5), diag));
}

/// An open carcass (bottom, top, sides, back) around `[0, 1] x [0, 1] x [-0.45, 0]` and a
/// drawer `[0, 1] x [0, 1] x [-0.4, 0]` touching its bottom, top and sides, grown by
/// `grow` (> 0: interpenetrating the walls).
#[test]
fn rest_states_are_reused_with_the_same_results_and_refused_elsewhere() {
    let (door, body) = door_and_body();
    let obstacle = SweepObstacle::new(&body).unwrap();
    let params = SweepParams::default();
    let batches = [
        vec![revolute([0.0, 0.0, 0.02], [0.0, -1.0, 0.0], FRAC_PI_2)],
        vec![
            revolute([1.0, 0.0, 0.02], [0.0, -1.0, 0.0], FRAC_PI_2),
            prismatic([0.0, 0.0, 1.0], 0.5),
            prismatic([1.0, 0.0, 0.0], 0.5),
        ],
    ];
    let rest = obstacle.rest_states(&door, &params).unwrap();
    assert!(rest.matches(&door, &params));
    for cands in &batches {
        assert_eq!(
            obstacle.sweep_from_rest(&rest, cands, &params).unwrap(),
            obstacle.sweep(&door, cands, &params).unwrap()
        );
    }
    // other points, another skin or inside rule: not these states
    let mut moved = door.clone();
    moved[3].x = f64::from_bits(moved[3].x.to_bits() + 1);
    assert!(!rest.matches(&moved, &params));
    let thicker = SweepParams {
        skin: params.skin * 2.0,
        ..params
    };
    assert!(!rest.matches(&door, &thicker));
    let err = obstacle.sweep_from_rest(&rest, &batches[0], &thicker);
    assert!(matches!(err, Err(GeometryError::Invalid(m)) if m.contains("skin")));
    let all = SweepParams {
        skip_inside: false,
        ..params
    };
    assert!(!rest.matches(&door, &all));
    // another obstacle, even of the same mesh, refuses them
    let twin = SweepObstacle::new(&body).unwrap();
    let err = twin.sweep_from_rest(&rest, &batches[0], &params);
    assert!(matches!(err, Err(GeometryError::Invalid(m)) if m.contains("another obstacle")));
    // an empty obstacle's states: every motion free
    let empty = SweepObstacle::new(&mesh_of(&[])).unwrap();
    let free = empty.rest_states(&door, &params).unwrap();
    let r = empty.sweep_from_rest(&free, &batches[1], &params).unwrap();
    assert!(r.iter().all(|x| x.free_fraction == [1.0; 2]));
    // bad points are refused before any work
    assert!(obstacle.rest_states(&[], &params).is_err());
}

fn drawer_and_frame(grow: f64) -> (Vec<Point3<f64>>, TriMesh) {
    let t = 0.05;
    let frame = mesh_of(&[
        ([-t, -t, -0.45 - t], [1.0 + t, 0.0, 0.0]),
        ([-t, 1.0, -0.45 - t], [1.0 + t, 1.0 + t, 0.0]),
        ([-t, 0.0, -0.45 - t], [0.0, 1.0, 0.0]),
        ([1.0, 0.0, -0.45 - t], [1.0 + t, 1.0, 0.0]),
        ([0.0, 0.0, -0.45 - t], [1.0, 1.0, -0.45]),
    ]);
    let g = grow;
    let drawer = box_points([-g, -g, -0.4], [1.0 + g, 1.0 + g, 0.0], 8);
    (drawer, frame)
}

#[test]
fn drawer_slides_out_freely_and_collides_inwards() {
    for grow in [0.0, 0.001] {
        let (drawer, frame) = drawer_and_frame(grow);
        let cands = [prismatic([0.0, 0.0, 1.0], 0.4)];
        let r = sweep_collisions(&drawer, &frame, &cands, &SweepParams::default()).unwrap();
        assert_eq!(r[0].free_fraction[0], 1.0, "grow {grow}: {:?}", r[0]);
        assert_eq!(r[0].colliding_fraction[0], 0.0, "grow {grow}: {:?}", r[0]);
        // Inwards, the drawer back (z = -0.4) meets the back panel (z = -0.45) after
        // 0.05 of 0.4: the free fraction is 0.125.
        assert!((r[0].free_fraction[1] - 0.125).abs() < 1e-9, "{:?}", r[0]);
        // Its back face (1/6 of the points) and the front part collide.
        assert!(
            r[0].colliding_fraction[1] >= 1.0 / 6.0 - 1e-12,
            "{:?}",
            r[0]
        );
    }
}

#[test]
fn rotation_about_a_centre_axis_collides_with_the_frame() {
    let (drawer, frame) = drawer_and_frame(0.0);
    let cands = [revolute([0.5, 0.0, -0.2], [0.0, 1.0, 0.0], FRAC_PI_2)];
    let r = sweep_collisions(&drawer, &frame, &cands, &SweepParams::default()).unwrap();
    for s in 0..2 {
        assert!(r[0].free_fraction[s] < 0.25, "{:?}", r[0]);
        assert!(r[0].colliding_fraction[s] > 0.2, "{:?}", r[0]);
    }
}

#[test]
fn contact_at_rest_is_not_counted_but_free_points_are() {
    // A plate resting on a thick floor, lifted: free. Without the skin rule the contact
    // points would hit the floor at t = 0.
    let floor = mesh_of(&[([-1.0, -1.0, -1.0], [2.0, 0.0, 2.0])]);
    let plate = box_points([0.0, 0.0, 0.0], [1.0, 0.1, 1.0], 6);
    let up = [prismatic([0.0, 1.0, 0.0], 0.5)];
    let r = sweep_collisions(&plate, &floor, &up, &SweepParams::default()).unwrap();
    assert_eq!(r[0].free_fraction[0], 1.0);
    assert_eq!(r[0].colliding_fraction[0], 0.0);
    // Downwards the bottom (in contact) does not count, the sides and the top do; the
    // lowest side points (y = 0.1 / 12) hit first, at (0.1 / 12) / 0.5 of the range.
    assert!(
        (r[0].colliding_fraction[1] - 5.0 / 6.0).abs() < 1e-12,
        "{:?}",
        r[0]
    );
    assert!(
        (r[0].free_fraction[1] - 0.1 / 12.0 / 0.5).abs() < 1e-9,
        "{:?}",
        r[0]
    );
}

#[test]
fn first_hit_is_the_exact_motion_parameter() {
    // Points 0.3 in front of a wall, moved 1.0 towards it: every point hits at 0.3.
    let wall = mesh_of(&[([-1.0, -1.0, 0.0], [1.0, 1.0, 0.1])]);
    let pts: Vec<Point3<f64>> = (0..10)
        .map(|i| Point3::new(-0.5 + 0.1 * i as f64, 0.2, -0.3))
        .collect();
    let params = SweepParams {
        hit_tolerance: 0.0,
        ..SweepParams::default()
    };
    let r = sweep_collisions(&pts, &wall, &[prismatic([0.0, 0.0, 1.0], 1.0)], &params).unwrap();
    assert!((r[0].free_fraction[0] - 0.3).abs() < 1e-12, "{:?}", r[0]);
    assert_eq!(r[0].colliding_fraction, [1.0, 0.0]);
    // Rotated about the x axis through (0, -0.4, -0.3) (radius 0.6), the points reach
    // the wall (z = 0) at 30 degrees, 1/3 of a 90-degree range; the chord of the
    // 16-step path crosses it at 0.3337.
    let pivot = revolute([0.0, -0.4, -0.3], [1.0, 0.0, 0.0], FRAC_PI_2);
    let r = sweep_collisions(&pts, &wall, &[pivot], &params).unwrap();
    assert!(
        (r[0].free_fraction[0] - 1.0 / 3.0).abs() < 1e-3,
        "{:?}",
        r[0]
    );
    assert_eq!(r[0].colliding_fraction, [1.0, 0.0]);
}

#[test]
fn empty_obstacle_is_free_and_bad_input_is_an_error() {
    let empty = TriMesh::new(vec![], vec![], "empty").unwrap();
    let pts = vec![Point3::new(0.0, 0.0, 0.0)];
    let c = [prismatic([1.0, 0.0, 0.0], 1.0)];
    let p = SweepParams::default();
    let r = sweep_collisions(&pts, &empty, &c, &p).unwrap();
    assert_eq!(r[0].free_fraction, [1.0, 1.0]);
    assert_eq!(r[0].colliding_fraction, [0.0, 0.0]);
    let (_, body) = door_and_body();
    assert!(matches!(
        sweep_collisions(&[], &body, &c, &p),
        Err(GeometryError::Degenerate(_))
    ));
    assert!(matches!(
        sweep_collisions(&pts, &body, &[], &p),
        Err(GeometryError::Degenerate(_))
    ));
    assert!(matches!(
        sweep_collisions(&pts, &body, &[prismatic([0.0; 3], 1.0)], &p),
        Err(GeometryError::Degenerate(_))
    ));
    assert!(matches!(
        sweep_collisions(&pts, &body, &[prismatic([f64::NAN, 0.0, 0.0], 1.0)], &p),
        Err(GeometryError::NonFinite { .. })
    ));
    assert!(matches!(
        sweep_collisions(&[Point3::new(f64::INFINITY, 0.0, 0.0)], &body, &c, &p),
        Err(GeometryError::NonFinite { .. })
    ));
    assert!(matches!(
        sweep_collisions(&pts, &body, &[prismatic([1.0, 0.0, 0.0], -1.0)], &p),
        Err(GeometryError::Invalid(_))
    ));
    for bad in [
        SweepParams { n_steps: 0, ..p },
        SweepParams {
            n_steps: MAX_STEPS + 1,
            ..p
        },
        SweepParams { skin: -1.0, ..p },
        SweepParams {
            skin: f64::NAN,
            ..p
        },
        SweepParams {
            hit_tolerance: 1.0,
            ..p
        },
        SweepParams {
            hit_tolerance: f64::NAN,
            ..p
        },
    ] {
        assert!(
            matches!(
                sweep_collisions(&pts, &body, &c, &bad),
                Err(GeometryError::Invalid(_))
            ),
            "{bad:?}"
        );
    }
    assert!(matches!(
        line_mesh_distance(&[Point3::origin()], &[Vector3::x()], &empty),
        Err(GeometryError::Degenerate(_))
    ));
    assert!(matches!(
        line_mesh_distance(&[Point3::origin()], &[], &body),
        Err(GeometryError::Shape { .. })
    ));
}

#[test]
fn line_mesh_distance_of_lines_near_a_box() {
    let body = mesh_of(&[([0.0, 0.0, 0.0], [1.0, 1.0, 1.0])]);
    let origins = [
        Point3::new(0.0, 100.0, 0.0), // along an edge: 0
        Point3::new(0.5, 0.5, -3.0),  // through the box: 0
        Point3::new(-0.25, 7.0, 0.5), // parallel to a face at 0.25
        Point3::new(2.0, 3.0, 2.0),   // parallel to an edge at sqrt(2)
    ];
    let dirs = [
        Vector3::new(0.0, 2.0, 0.0),
        Vector3::new(0.0, 0.0, 1.0),
        Vector3::new(0.0, 1.0, 0.0),
        Vector3::new(0.0, -1.0, 0.0),
    ];
    let d = line_mesh_distance(&origins, &dirs, &body).unwrap();
    let want = [0.0, 0.0, 0.25, 2f64.sqrt()];
    for (g, w) in d.iter().zip(want) {
        assert!((g - w).abs() < 1e-9, "{d:?}");
    }
}

/// Mirror a point through the plane x = 0.
fn mirror(p: &Point3<f64>) -> Point3<f64> {
    Point3::new(-p.x, p.y, p.z)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    /// The projected line-to-mesh distance equals parry's segment-vs-BVH distance on
    /// random triangle soups and lines (the segment spans the mesh, so the two are the
    /// same quantity).
    #[test]
    fn line_mesh_distance_matches_parry(
        tris in prop::collection::vec(prop::array::uniform9(-1.0f64..1.0), 1..12),
        origin in prop::array::uniform3(-2.0f64..2.0),
        dir in prop::array::uniform3(-1.0f64..1.0),
    ) {
        prop_assume!(dir.iter().map(|x| x * x).sum::<f64>() > 1e-3);
        let v: Vec<Point3<f64>> = tris
            .iter()
            .flat_map(|t| (0..3).map(move |k| Point3::new(t[3 * k], t[3 * k + 1], t[3 * k + 2])))
            .collect();
        let f: Vec<[u32; 3]> = (0..tris.len() as u32).map(|i| [3 * i, 3 * i + 1, 3 * i + 2]).collect();
        let mesh = TriMesh::new(v, f, "soup").unwrap();
        let (o, d) = ([Point3::from(origin)], [Vector3::from(dir)]);
        let fast = line_mesh_distance(&o, &d, &mesh).unwrap();
        let parry = SweepObstacle::new(&mesh).unwrap().line_distance(&o, &d).unwrap();
        prop_assert!((fast[0] - parry[0]).abs() < 1e-7, "{} vs {}", fast[0], parry[0]);
    }

    /// Random boxes and motions: no panic, fractions in [0, 1], and the mirror image of
    /// the whole scene through x = 0 (rotations about mirrored axes change handedness,
    /// so the signs swap for revolute; prismatic along x also swaps) gives the same
    /// outputs.
    #[test]
    fn fractions_are_bounded_and_mirror_symmetric(
        lo in prop::array::uniform3(-1.0f64..0.0),
        size in prop::array::uniform3(0.05f64..1.0),
        plo in prop::array::uniform3(-1.0f64..0.5),
        psize in prop::array::uniform3(0.05f64..0.5),
        origin in prop::array::uniform3(-1.0f64..1.0),
        dir in prop::array::uniform3(-1.0f64..1.0),
        range in 0.0f64..3.0,
        revolute_kind in any::<bool>(),
        n_steps in 1usize..12,
        skin in 0.0f64..0.02,
    ) {
        prop_assume!(dir.iter().map(|x| x * x).sum::<f64>() > 1e-3);
        let hi = [lo[0] + size[0], lo[1] + size[1], lo[2] + size[2]];
        let phi = [plo[0] + psize[0], plo[1] + psize[1], plo[2] + psize[2]];
        let obstacle = mesh_of(&[(lo, hi)]);
        let points = box_points(plo, phi, 3);
        let kind = if revolute_kind { MotionKind::Revolute } else { MotionKind::Prismatic };
        let cand = SweepCandidate {
            origin: Point3::from(origin),
            direction: Vector3::from(dir),
            kind,
            range,
        };
        let params = SweepParams { n_steps, skin, hit_tolerance: 0.02, skip_inside: true };
        let r = sweep_collisions(&points, &obstacle, &[cand], &params).unwrap();
        for s in 0..2 {
            prop_assert!((0.0..=1.0).contains(&r[0].free_fraction[s]));
            prop_assert!((0.0..=1.0).contains(&r[0].colliding_fraction[s]));
            if r[0].colliding_fraction[s] == 0.0 {
                prop_assert_eq!(r[0].free_fraction[s], 1.0);
            }
        }
        // Mirror through x = 0.
        let (mv, mf): (Vec<Point3<f64>>, Vec<[u32; 3]>) = (
            obstacle.vertices().iter().map(mirror).collect(),
            obstacle.faces().iter().map(|t| [t[0], t[2], t[1]]).collect(),
        );
        let mobst = TriMesh::new(mv, mf, "mirror").unwrap();
        let mpoints: Vec<Point3<f64>> = points.iter().map(mirror).collect();
        // Mirroring reverses rotation handedness: keep the sign semantics by flipping
        // the axis as a pseudo-vector (d -> (dx, -dy, -dz)) for revolute; a polar
        // vector (d -> (-dx, dy, dz)) for prismatic.
        let mdir = match kind {
            MotionKind::Revolute => Vector3::new(dir[0], -dir[1], -dir[2]),
            MotionKind::Prismatic => Vector3::new(-dir[0], dir[1], dir[2]),
        };
        let mcand = SweepCandidate {
            origin: mirror(&Point3::from(origin)),
            direction: mdir,
            ..cand
        };
        let m = sweep_collisions(&mpoints, &mobst, &[mcand], &params).unwrap();
        for s in 0..2 {
            prop_assert!((m[0].free_fraction[s] - r[0].free_fraction[s]).abs() < 1e-6,
                "{:?} vs {:?}", r, m);
            prop_assert!((m[0].colliding_fraction[s] - r[0].colliding_fraction[s]).abs()
                < 1e-9, "{:?} vs {:?}", r, m);
        }
    }

    /// Swapping the direction swaps the two signs.
    #[test]
    fn reversing_the_direction_swaps_the_signs(
        origin in prop::array::uniform3(-1.0f64..1.0),
        dir in prop::array::uniform3(-1.0f64..1.0),
        range in 0.0f64..3.0,
        revolute_kind in any::<bool>(),
    ) {
        prop_assume!(dir.iter().map(|x| x * x).sum::<f64>() > 1e-3);
        let (door, body) = door_and_body();
        let kind = if revolute_kind { MotionKind::Revolute } else { MotionKind::Prismatic };
        let c = SweepCandidate {
            origin: Point3::from(origin), direction: Vector3::from(dir), kind, range,
        };
        let rc = SweepCandidate { direction: -Vector3::from(dir), ..c };
        let r = sweep_collisions(&door, &body, &[c, rc], &SweepParams::default()).unwrap();
        for s in 0..2 {
            prop_assert!((r[0].free_fraction[s] - r[1].free_fraction[1 - s]).abs() < 1e-6,
                "{:?}", r);
            prop_assert!((r[0].colliding_fraction[s] - r[1].colliding_fraction[1 - s]).abs()
                < 1e-9, "{:?}", r);
        }
    }
}

/// Extreme magnitudes and degenerate triangles: no panic.
mod extreme_tests {
    use super::super::*;

    #[test]
    fn extreme_magnitudes_do_not_panic() {
        for scale in [1e-300, 1e-12, 1e12, 1e150, 1e300, f64::MAX / 4.0] {
            let v = vec![
                Point3::new(0.0, 0.0, 0.0),
                Point3::new(scale, 0.0, 0.0),
                Point3::new(0.0, scale, 0.0),
                Point3::new(0.0, 0.0, -scale),
            ];
            let mesh = TriMesh::new(v, vec![[0, 1, 2], [0, 2, 3], [1, 2, 3]], "m").unwrap();
            let pts = vec![
                Point3::new(scale / 3.0, scale / 3.0, scale),
                Point3::origin(),
            ];
            for kind in [MotionKind::Revolute, MotionKind::Prismatic] {
                let cand = SweepCandidate {
                    origin: Point3::new(scale, -scale, 0.0),
                    direction: Vector3::new(scale, 1.0, -scale),
                    kind,
                    range: if kind == MotionKind::Revolute {
                        6.0
                    } else {
                        scale
                    },
                };
                for skin in [0.0, scale] {
                    let params = SweepParams {
                        skin,
                        ..SweepParams::default()
                    };
                    if let Ok(r) = sweep_collisions(&pts, &mesh, &[cand], &params) {
                        for s in 0..2 {
                            assert!((0.0..=1.0).contains(&r[0].free_fraction[s]));
                            assert!((0.0..=1.0).contains(&r[0].colliding_fraction[s]));
                        }
                    }
                }
            }
            let _ = line_mesh_distance(&[Point3::new(scale, scale, scale)], &[Vector3::x()], &mesh);
        }
    }
    #[test]
    fn degenerate_triangles_do_not_panic() {
        let v = vec![
            Point3::new(0.0, 0.0, 0.0),
            Point3::new(1.0, 0.0, 0.0),
            Point3::new(2.0, 0.0, 0.0),
            Point3::new(0.5, 0.0, 0.0),
        ];
        // A point-triangle, collinear triangles, a repeated index.
        let mesh = TriMesh::new(v, vec![[0, 0, 0], [0, 1, 2], [1, 3, 1]], "m").unwrap();
        let pts = vec![
            Point3::new(0.5, 0.0, 0.0),
            Point3::new(0.5, 1.0, 0.0),
            Point3::new(1.0, 0.0, 0.001),
        ];
        let cands = [
            SweepCandidate {
                origin: Point3::new(0.0, 0.5, 0.0),
                direction: Vector3::z(),
                kind: MotionKind::Revolute,
                range: 3.0,
            },
            SweepCandidate {
                origin: Point3::origin(),
                direction: -Vector3::y(),
                kind: MotionKind::Prismatic,
                range: 2.0,
            },
        ];
        let r = sweep_collisions(&pts, &mesh, &cands, &SweepParams::default()).unwrap();
        for x in &r {
            for s in 0..2 {
                assert!((0.0..=1.0).contains(&x.free_fraction[s]));
                assert!((0.0..=1.0).contains(&x.colliding_fraction[s]));
            }
        }
        let d = line_mesh_distance(&[Point3::new(0.0, 1.0, 0.0)], &[Vector3::z()], &mesh).unwrap();
        assert!((d[0] - 1.0).abs() < 1e-12, "{d:?}");
    }
}
