//! Bindings of `kinmo_geometry::sweep`: `sweep_collisions`, `SweepObstacle`, `line_mesh_distance`.

use std::sync::{Arc, Mutex};

use kinmo_geometry::sweep::{self, MotionKind, RestStates, SweepCandidate, SweepParams};
use kinmo_geometry::GeometryError;
use numpy::{PyArray1, PyArray2, PyReadonlyArray1, PyReadonlyArray2};
use pyo3::prelude::*;

use crate::convert::{
    array1, array2, directions_from_array, floats_from_array, mesh_from_arrays, points_from_array,
};
use crate::errors::{detach, to_py};

type Fractions<'py> = (Bound<'py, PyArray2<f64>>, Bound<'py, PyArray2<f64>>);

/// The candidates and parameters of one swept test, checked.
#[allow(clippy::too_many_arguments)]
fn sweep_inputs(
    origins: &PyReadonlyArray2<'_, f64>,
    directions: &PyReadonlyArray2<'_, f64>,
    kinds: &PyReadonlyArray1<'_, i64>,
    ranges: &PyReadonlyArray1<'_, f64>,
    n_steps: i64,
    skin: f64,
    hit_tolerance: f64,
    skip_inside: bool,
) -> PyResult<(Vec<SweepCandidate>, SweepParams)> {
    let o = points_from_array(origins, "origins")?;
    let c = o.len();
    let d = directions_from_array(directions, c, "directions")?;
    let kind_view = kinds.as_array();
    if kind_view.len() != c {
        return Err(to_py(GeometryError::Shape {
            what: "kinds".to_string(),
            expected: format!("({c},)"),
            got: format!("({},)", kind_view.len()),
        }));
    }
    let kinds: Vec<MotionKind> = kind_view
        .iter()
        .enumerate()
        .map(|(i, &k)| MotionKind::from_code(k, i))
        .collect::<Result<_, _>>()
        .map_err(to_py)?;
    let r = floats_from_array(ranges, Some(c), "ranges")?;
    let n_steps = usize::try_from(n_steps)
        .ok()
        .filter(|&n| n > 0 && n <= sweep::MAX_STEPS)
        .ok_or_else(|| {
            to_py(GeometryError::Invalid(format!(
                "n_steps: {n_steps} is outside 1..={}",
                sweep::MAX_STEPS
            )))
        })?;
    let candidates: Vec<SweepCandidate> = (0..c)
        .map(|i| SweepCandidate {
            origin: o[i],
            direction: d[i],
            kind: kinds[i],
            range: r[i],
        })
        .collect();
    let params = SweepParams {
        n_steps,
        skin,
        hit_tolerance,
        skip_inside,
    };
    Ok((candidates, params))
}

/// The `(free (C, 2), colliding (C, 2))` arrays of sweep results.
fn fractions<'py>(py: Python<'py>, results: &[sweep::SweepResult]) -> Fractions<'py> {
    let c = results.len();
    let free: Vec<f64> = results.iter().flat_map(|x| x.free_fraction).collect();
    let colliding: Vec<f64> = results.iter().flat_map(|x| x.colliding_fraction).collect();
    (array2(py, free, c, 2), array2(py, colliding, c, 2))
}

/// Swept-collision feasibility of C candidate motions of one moving part, both signs.
///
/// Returns `(free_fraction (C, 2), colliding_fraction (C, 2))` float64, column 0 the
/// positive sign. `kinds (C,)` int64: 0 revolute, 1 prismatic. See
/// `kinmo_geometry::sweep` for the exact rule. `ValueError` on bad input.
#[pyfunction]
#[pyo3(signature = (
    moving_points, obstacle_vertices, obstacle_faces, origins, directions, kinds, ranges,
    n_steps=16, skin=0.005, hit_tolerance=0.02, skip_inside=true
))]
#[allow(clippy::too_many_arguments)]
fn sweep_collisions<'py>(
    py: Python<'py>,
    moving_points: PyReadonlyArray2<'py, f64>,
    obstacle_vertices: PyReadonlyArray2<'py, f64>,
    obstacle_faces: PyReadonlyArray2<'py, i64>,
    origins: PyReadonlyArray2<'py, f64>,
    directions: PyReadonlyArray2<'py, f64>,
    kinds: PyReadonlyArray1<'py, i64>,
    ranges: PyReadonlyArray1<'py, f64>,
    n_steps: i64,
    skin: f64,
    hit_tolerance: f64,
    skip_inside: bool,
) -> PyResult<Fractions<'py>> {
    let points = points_from_array(&moving_points, "moving_points")?;
    let obstacle = mesh_from_arrays(&obstacle_vertices, &obstacle_faces, "obstacle")?;
    let (candidates, params) = sweep_inputs(
        &origins,
        &directions,
        &kinds,
        &ranges,
        n_steps,
        skin,
        hit_tolerance,
        skip_inside,
    )?;
    let results = detach(py, "sweep_collisions", || {
        sweep::sweep_collisions(&points, &obstacle, &candidates, &params)
    })?;
    Ok(fractions(py, &results))
}

/// An obstacle mesh prepared once (its BVH built) for many swept tests.
///
/// `SweepObstacle(vertices (V, 3) float64, faces (F, 3) int64)`; `F = 0` is a valid, empty
/// obstacle. `ValueError` on bad input. It keeps the rest states of the last moving points
/// it swept: a call with the same points (bit for bit), skin and inside rule reuses them.
#[pyclass(frozen, module = "kinmo._core")]
struct SweepObstacle {
    inner: sweep::SweepObstacle,
    last_rest: Mutex<Option<Arc<RestStates>>>,
}

#[pymethods]
impl SweepObstacle {
    #[new]
    fn new(
        py: Python<'_>,
        vertices: PyReadonlyArray2<'_, f64>,
        faces: PyReadonlyArray2<'_, i64>,
    ) -> PyResult<Self> {
        let mesh = mesh_from_arrays(&vertices, &faces, "obstacle")?;
        let inner = detach(py, "SweepObstacle", || sweep::SweepObstacle::new(&mesh))?;
        Ok(Self {
            inner,
            last_rest: Mutex::new(None),
        })
    }

    /// Number of obstacle triangles.
    #[getter]
    fn n_faces(&self) -> usize {
        self.inner.n_faces()
    }

    /// `sweep_collisions` of `moving_points` against this obstacle: the same results, the
    /// BVH not rebuilt.
    #[pyo3(signature = (
        moving_points, origins, directions, kinds, ranges,
        n_steps=16, skin=0.005, hit_tolerance=0.02, skip_inside=true
    ))]
    #[allow(clippy::too_many_arguments)]
    fn sweep<'py>(
        &self,
        py: Python<'py>,
        moving_points: PyReadonlyArray2<'py, f64>,
        origins: PyReadonlyArray2<'py, f64>,
        directions: PyReadonlyArray2<'py, f64>,
        kinds: PyReadonlyArray1<'py, i64>,
        ranges: PyReadonlyArray1<'py, f64>,
        n_steps: i64,
        skin: f64,
        hit_tolerance: f64,
        skip_inside: bool,
    ) -> PyResult<Fractions<'py>> {
        let points = points_from_array(&moving_points, "moving_points")?;
        let (candidates, params) = sweep_inputs(
            &origins,
            &directions,
            &kinds,
            &ranges,
            n_steps,
            skin,
            hit_tolerance,
            skip_inside,
        )?;
        let obstacle = &self.inner;
        // a poisoned lock only loses the memo (a panic is an error to Python either way)
        let reused = self
            .last_rest
            .lock()
            .ok()
            .and_then(|last| last.clone())
            .filter(|rest| rest.matches(&points, &params));
        let (results, rest) = detach(py, "SweepObstacle.sweep", || {
            let rest = match reused {
                Some(rest) => rest,
                None => {
                    // candidates checked before the rest states are paid for
                    obstacle.check(&points, &candidates, &params)?;
                    Arc::new(obstacle.rest_states(&points, &params)?)
                }
            };
            Ok((obstacle.sweep_from_rest(&rest, &candidates, &params)?, rest))
        })?;
        if let Ok(mut last) = self.last_rest.lock() {
            *last = Some(rest);
        }
        Ok(fractions(py, &results))
    }
}

/// Distance `(C,)` float64 from each infinite line to the surface of a mesh.
///
/// `ValueError` on bad input, a zero-length direction or a mesh without faces.
#[pyfunction]
fn line_mesh_distance<'py>(
    py: Python<'py>,
    origins: PyReadonlyArray2<'py, f64>,
    directions: PyReadonlyArray2<'py, f64>,
    vertices: PyReadonlyArray2<'py, f64>,
    faces: PyReadonlyArray2<'py, i64>,
) -> PyResult<Bound<'py, PyArray1<f64>>> {
    let o = points_from_array(&origins, "origins")?;
    let d = directions_from_array(&directions, o.len(), "directions")?;
    let mesh = mesh_from_arrays(&vertices, &faces, "mesh")?;
    let dist = detach(py, "line_mesh_distance", || {
        sweep::line_mesh_distance(&o, &d, &mesh)
    })?;
    Ok(array1(py, dist))
}

/// Register this module's functions on `kinmo._core`.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(sweep_collisions, m)?)?;
    m.add_class::<SweepObstacle>()?;
    m.add_function(wrap_pyfunction!(line_mesh_distance, m)?)?;
    Ok(())
}
