//! Tests of [`super::concave_pieces`].

use nalgebra::Point3;
use proptest::prelude::*;

use super::*;
use crate::test_meshes::box_mesh;

fn params(tolerance: f64) -> SplitParams {
    SplitParams {
        tolerance,
        max_depth: 4,
        max_components: 16,
        hull_samples: 64,
        flat_relative: 1e-9,
        slab_thickness: 1e-3,
    }
}

/// Several meshes as one vertex and face list.
fn soup(meshes: &[Piece]) -> Piece {
    let (mut v, mut f) = (Vec::new(), Vec::new());
    for (mv, mf) in meshes {
        let base = v.len() as u32;
        v.extend(mv.iter().copied());
        f.extend(mf.iter().map(|t| t.map(|i| i + base)));
    }
    (v, f)
}

/// A U of three boxes (two posts on a base, the slot between them 1 wide and 3 deep), as one
/// connected mesh: the posts' bottom corners are the base's top corners.
fn u_shape() -> Piece {
    soup(&[
        box_mesh([0.0, 0.0, 0.0], [3.0, 1.0, 1.0]),
        box_mesh([0.0, 1.0, 0.0], [1.0, 4.0, 1.0]),
        box_mesh([2.0, 1.0, 0.0], [3.0, 4.0, 1.0]),
    ])
}

/// Every face id appears in exactly one piece.
fn assert_partition(pieces: &[(Piece, Vec<u32>)], n_faces: usize) {
    let mut seen = vec![0usize; n_faces];
    for (_, ids) in pieces {
        assert!(ids.windows(2).all(|w| w[0] < w[1]), "face ids ascending");
        for &i in ids {
            seen[i as usize] += 1;
        }
    }
    assert!(seen.iter().all(|&n| n == 1), "{seen:?}");
}

#[test]
fn a_box_is_one_piece_its_hull() {
    let (v, f) = box_mesh([0.0, 0.0, 0.0], [1.0, 2.0, 3.0]);
    let pieces = concave_pieces(&v, &f, &params(0.05)).expect("pieces");
    assert_eq!(pieces.len(), 1);
    let ((pv, pf), ids) = &pieces[0];
    assert_eq!(pv, &v, "corners in vertex order");
    assert_eq!(pf.len(), 12);
    assert_eq!(ids.len(), 12);
}

#[test]
fn two_apart_boxes_split_into_their_components() {
    let (v, f) = soup(&[
        box_mesh([0.0, 0.0, 0.0], [1.0, 1.0, 1.0]),
        box_mesh([5.0, 0.0, 0.0], [6.0, 1.0, 1.0]),
    ]);
    let pieces = concave_pieces(&v, &f, &params(0.1)).expect("pieces");
    assert_eq!(pieces.len(), 2);
    assert_eq!(
        pieces[0].1,
        (0..12).collect::<Vec<u32>>(),
        "first component first"
    );
    assert_partition(&pieces, f.len());
}

#[test]
fn a_u_is_cut_so_no_piece_fills_its_slot() {
    let (v, f) = u_shape();
    let pieces = concave_pieces(&v, &f, &params(0.1)).expect("pieces");
    assert!(pieces.len() > 1);
    assert_partition(&pieces, f.len());
    // the middle of the slot lies outside every piece
    let slot = Point3::new(1.5, 2.5, 0.5);
    for ((pv, pf), _) in &pieces {
        let inside = pf.iter().all(|t| {
            let [a, b, c] = t.map(|i| pv[i as usize]);
            (b - a).cross(&(c - a)).dot(&(slot - a)) <= 1e-12
        });
        assert!(!inside, "a piece fills the slot");
    }
    // without a tolerance nothing is split
    let whole = concave_pieces(&v, &f, &params(0.0)).expect("pieces");
    assert_eq!(whole.len(), 1);
    // the same input gives the same pieces
    assert_eq!(concave_pieces(&v, &f, &params(0.1)).expect("again"), pieces);
}

#[test]
fn a_flat_mesh_becomes_a_thin_prism() {
    // a 2 x 1 rectangle in the z = 0 plane
    let v: Vec<Point3<f64>> = [(0.0, 0.0), (2.0, 0.0), (2.0, 1.0), (0.0, 1.0)]
        .iter()
        .map(|&(x, y)| Point3::new(x, y, 0.0))
        .collect();
    let f = vec![[0, 1, 2], [0, 2, 3]];
    let pieces = concave_pieces(&v, &f, &params(0.05)).expect("pieces");
    assert_eq!(pieces.len(), 1);
    let ((pv, _), _) = &pieces[0];
    assert_eq!(pv.len(), 8);
    let z: Vec<f64> = pv.iter().map(|p| p.z.abs()).collect();
    // half of 1e-3 times the largest extent (2) on each side
    assert!(z.iter().all(|&d| (d - 1e-3).abs() < 1e-12), "{z:?}");
}

#[test]
fn bad_input_is_an_error() {
    let (v, mut f) = box_mesh([0.0, 0.0, 0.0], [1.0, 1.0, 1.0]);
    assert!(matches!(
        concave_pieces(
            &v,
            &f,
            &SplitParams {
                hull_samples: 0,
                ..params(0.1)
            }
        ),
        Err(GeometryError::Invalid(_))
    ));
    assert!(matches!(
        concave_pieces(&v, &f, &params(-1.0)),
        Err(GeometryError::Invalid(_))
    ));
    let mut nan = v.clone();
    nan[3].x = f64::NAN;
    assert!(matches!(
        concave_pieces(&nan, &f, &params(0.1)),
        Err(GeometryError::NonFinite { .. })
    ));
    f[5][1] = 8;
    assert!(matches!(
        concave_pieces(&v, &f, &params(0.1)),
        Err(GeometryError::IndexOutOfRange { face: 5, .. })
    ));
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// Any soup of boxes: the pieces' face ids cover every face exactly once, and every
    /// piece is a closed convex mesh (each corner on or behind every face).
    #[test]
    fn pieces_partition_the_faces_and_are_convex(
        boxes in prop::collection::vec(
            (prop::array::uniform3(-3.0f64..3.0), prop::array::uniform3(0.1f64..2.0)), 1..6),
        tol in 0.0f64..0.3,
    ) {
        let meshes: Vec<_> = boxes
            .iter()
            .map(|(lo, size)| box_mesh(*lo, [lo[0] + size[0], lo[1] + size[1], lo[2] + size[2]]))
            .collect();
        let (v, f) = soup(&meshes);
        let pieces = concave_pieces(&v, &f, &params(tol)).expect("pieces");
        assert_partition(&pieces, f.len());
        for ((pv, pf), _) in &pieces {
            let scale = pv.iter().map(|p| p.coords.amax()).fold(1.0, f64::max);
            for t in pf {
                let [a, b, c] = t.map(|i| pv[i as usize]);
                let n = (b - a).cross(&(c - a));
                for p in pv {
                    prop_assert!(n.dot(&(p - a)) <= 1e-9 * scale * scale * scale);
                }
            }
        }
    }
}
