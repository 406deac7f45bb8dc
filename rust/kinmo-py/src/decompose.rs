//! Bindings of `kinmo_geometry::decompose`: `concave_pieces`.

use kinmo_geometry::decompose::{self, SplitParams};
use numpy::{PyArray1, PyArray2, PyReadonlyArray2};
use pyo3::prelude::*;

use crate::convert::{
    array1, faces_from_array, faces_to_array, points_from_array, points_to_array,
};
use crate::errors::detach;

type PieceArrays<'py> = (
    Bound<'py, PyArray2<f64>>,
    Bound<'py, PyArray2<i64>>,
    Bound<'py, PyArray1<i64>>,
);

/// The convex pieces of each leaf mesh of a link (`kinmo.export.collision.concave_parts`).
///
/// `vertices (V, 3) float64` shared by the leaves, `leaves`: a sequence of `faces (F, 3)
/// int64` (one per leaf); the settings are the module constants of
/// `kinmo.export.collision` (`tolerance` absolute, mesh units). Returns, per leaf, a list
/// of `(piece vertices (H, 3) float64, piece faces (T, 3) int64, face ids (K,) int64)` in
/// depth-first order; the face ids (ascending, into the leaf's faces) are the faces the
/// piece covers. `ValueError` on bad arrays or settings.
#[pyfunction]
#[allow(clippy::too_many_arguments)]
#[pyo3(signature = (vertices, leaves, tolerance, max_depth, max_components, hull_samples,
                    flat_relative, slab_thickness))]
fn concave_pieces<'py>(
    py: Python<'py>,
    vertices: PyReadonlyArray2<'py, f64>,
    leaves: Vec<PyReadonlyArray2<'py, i64>>,
    tolerance: f64,
    max_depth: u32,
    max_components: usize,
    hull_samples: usize,
    flat_relative: f64,
    slab_thickness: f64,
) -> PyResult<Vec<Vec<PieceArrays<'py>>>> {
    let v = points_from_array(&vertices, "vertices")?;
    let faces = leaves
        .iter()
        .enumerate()
        .map(|(k, f)| faces_from_array(f, v.len(), &format!("leaves[{k}]")))
        .collect::<PyResult<Vec<_>>>()?;
    let params = SplitParams {
        tolerance,
        max_depth,
        max_components,
        hull_samples,
        flat_relative,
        slab_thickness,
    };
    let pieces = detach(py, "concave_pieces", || {
        faces
            .iter()
            .map(|f| decompose::concave_pieces(&v, f, &params))
            .collect::<Result<Vec<_>, _>>()
    })?;
    Ok(pieces
        .into_iter()
        .map(|leaf| {
            leaf.into_iter()
                .map(|((pv, pf), ids)| {
                    (
                        points_to_array(py, &pv),
                        faces_to_array(py, &pf),
                        array1(py, ids.into_iter().map(i64::from).collect()),
                    )
                })
                .collect()
        })
        .collect())
}

/// Register this module's functions on `kinmo._core`.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(concave_pieces, m)?)?;
    Ok(())
}
