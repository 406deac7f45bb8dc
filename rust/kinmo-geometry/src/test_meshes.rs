//! Meshes shared by the unit tests of several modules (compiled for tests only).

use nalgebra::Point3;

/// Closed axis-aligned box `[lo, hi]`: 8 vertices (vertex `i` takes `hi` on axis `k` when bit
/// `k` of `i` is set) and 12 triangles with outward normals.
pub(crate) fn box_mesh(lo: [f64; 3], hi: [f64; 3]) -> (Vec<Point3<f64>>, Vec<[u32; 3]>) {
    let v = (0..8u32)
        .map(|i| {
            Point3::new(
                if i & 1 == 0 { lo[0] } else { hi[0] },
                if i & 2 == 0 { lo[1] } else { hi[1] },
                if i & 4 == 0 { lo[2] } else { hi[2] },
            )
        })
        .collect();
    let f = vec![
        [0, 2, 1],
        [1, 2, 3], // z = lo
        [4, 5, 6],
        [5, 7, 6], // z = hi
        [0, 1, 4],
        [1, 5, 4], // y = lo
        [2, 6, 3],
        [3, 6, 7], // y = hi
        [0, 4, 2],
        [2, 4, 6], // x = lo
        [1, 3, 5],
        [3, 7, 5], // x = hi
    ];
    (v, f)
}
