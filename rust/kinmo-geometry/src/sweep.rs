//! Swept-collision feasibility of candidate motions on parry, and line-to-mesh distance.
//!
//! Source: Liu et al., "Semi-Weakly Supervised Object Kinematic Motion Prediction", CVPR
//! 2023, Sec. 3.3 (a candidate axis is feasible when the part can move along it without
//! colliding with the rest of the object); the swept test below is kinmo's geometric
//! extension of that check.
//!
//! # Swept test
//! The moving part is given by `P` surface points, the obstacle by one triangle mesh (the
//! caller concatenates every part not rigidly attached to the moving part). Each candidate
//! motion is a line `(origin, unit direction)`, a kind (revolute: rotation about the line,
//! right-hand rule; prismatic: translation along the direction) and a range (radians or
//! mesh units). For each sign `s` in `(+1, -1)` the motion is stepped in `n_steps` equal
//! increments up to `s * range`. Between consecutive steps each point follows a straight
//! segment (the chord of its arc for rotations; for translations the steps are collinear,
//! so one segment of the whole range is cast, which is the same test). A segment is cast
//! against the obstacle with parry's [`TriMesh`](parry3d_f64::shape::TriMesh) BVH ray cast
//! (`cast_local_ray_and_get_normal`, max time of impact = segment length). A point's
//! *first hit* is the motion parameter `u = (k - 1 + t / len) / n_steps` in `[0, 1]` of its
//! first counted crossing (step `k`, distance `t` along a segment of length `len`).
//!
//! ## Contact at rest (the exact rule)
//! Let `d_i` be the rest distance of point `i` to the obstacle surface. A point with
//! `d_i <= skin` is *in contact at rest*. For such a point, a crossing is **not** counted
//! when
//! 1. it lies on the first step at distance `t < skin` from the rest position, or
//! 2. the crossed triangle's plane passes within `skin` of the rest position (a surface the
//!    point touches at rest: it is leaving, grazing or sliding along it; the plane, not the
//!    triangle, so that the rule does not depend on how a flat face is triangulated, which
//!    the mirror-symmetry property test found), or
//! 3. the crossing point lies within `skin` of the tangent plane at the rest contact (the
//!    plane through the closest obstacle point, normal to the direction from it to the
//!    point; the closest triangle's normal for a point on the surface): a point
//!    sliding along the surface it touches (a drawer side along the frame) may cross the
//!    frame's rim or a coplanar neighbour triangle there.
//!
//! After an uncounted crossing the cast continues just past it (at most
//! [`MAX_RECASTS`] times per segment). Points farther than `skin` at rest count every
//! crossing (rule 1 cannot apply to them: they cannot reach the surface within `skin`).
//! Contact points thus never flag their own contact, while the rest of the part (which
//! does not touch the obstacle) still detects a motion into it.
//! 4. **Inside at rest.** A point farther than `skin` from the obstacle surface that lies
//!    *inside* the obstacle at rest (interpenetrating parts: a door frame modelled into the
//!    body's rim, common in PartNet meshes) never counts: whichever way it moves it leaves
//!    or stays in the solid, so its crossings say nothing about the candidate motion, while
//!    with a few percent of such points every motion would look blocked at once. Inside
//!    means: most of five fixed generic rays from the point cross the obstacle surface an
//!    odd number of times (parity; needs no consistent triangle orientation). Switched by
//!    [`SweepParams::skip_inside`].
//!
//! ## Outputs, per candidate and sign
//! - `free_fraction`: the motion parameter at which the number of points that have hit
//!   first exceeds `hit_tolerance * P` (the `m`-th smallest first hit, `m = floor(tol P) +
//!   1`), i.e. the fraction of the range swept freely; `1.0` if that never happens.
//! - `colliding_fraction`: the fraction of points whose path hits the obstacle anywhere
//!   within the range.
//!
//! An empty obstacle mesh (no faces) is valid: every motion is free.
//!
//! ## Cost
//! One parry BVH per obstacle (shared by the rayon tasks: candidates x signs x blocks of
//! points) and one closest-point query per point, its *rest state*
//! ([`SweepObstacle::rest_states`]), which later sweeps of the same points with other
//! candidates reuse ([`SweepObstacle::sweep_from_rest`]). Steps that end within a point's
//! rest distance to the obstacle are not cast (the path so far is shorter than that
//! distance, so no crossing is possible: exact). A ray running exactly along a triangle edge
//! (a moving face flush with an obstacle face) is not a crossing for parry; trimesh's
//! inclusive test counts it (`bench/bench_sweep.py` measures both).

use std::sync::atomic::{AtomicU64, Ordering};

use nalgebra::{Point3, Unit, Vector3};
use parry3d_f64::math::Isometry;
use parry3d_f64::query::PointQuery;
use parry3d_f64::query::{self, Ray, RayCast};
use parry3d_f64::shape::{FeatureId, Segment, TriMesh as ParryMesh};
use rayon::prelude::*;

use crate::error::{GeometryError, Result};
use crate::mesh::TriMesh;
use crate::motion::Motion;

/// Most uncounted (contact) crossings skipped on one segment before the segment is taken
/// as free; grazing casts along a finely tessellated surface can cross many edges.
pub const MAX_RECASTS: usize = 32;

/// Most steps per motion accepted by [`SweepParams`].
pub const MAX_STEPS: usize = 4096;

/// Most ray casts (`P * C * 2 * n_steps`) accepted by one call (guards absurd inputs).
pub const MAX_CASTS: u128 = 1 << 34;

/// Largest coordinate magnitude accepted (mesh units): beyond it squared distances overflow
/// and parry's queries are no longer defined.
pub const MAX_COORDINATE: f64 = 1e12;

/// Points per parallel work item inside one candidate sign.
const POINT_CHUNK: usize = 64;

/// Kind of a candidate motion.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MotionKind {
    /// Rotation about the line (right-hand rule), range in radians.
    Revolute,
    /// Translation along the direction, range in mesh units.
    Prismatic,
}

impl MotionKind {
    /// `0` revolute, `1` prismatic (the binding's integer code).
    ///
    /// # Errors
    /// [`GeometryError::Invalid`] for any other code, naming candidate `index`.
    pub fn from_code(code: i64, index: usize) -> Result<Self> {
        match code {
            0 => Ok(Self::Revolute),
            1 => Ok(Self::Prismatic),
            other => Err(GeometryError::Invalid(format!(
                "kinds[{index}]: {other} is not a motion kind (0 revolute, 1 prismatic)"
            ))),
        }
    }
}

/// One candidate motion of the swept test.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SweepCandidate {
    /// A point on the axis line.
    pub origin: Point3<f64>,
    /// Axis direction (normalised internally; must be non-zero).
    pub direction: Vector3<f64>,
    /// Revolute or prismatic.
    pub kind: MotionKind,
    /// Motion range per sign, `>= 0`: radians (revolute, at most `2 pi`) or mesh units.
    pub range: f64,
}

/// Parameters of the swept test.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SweepParams {
    /// Equal increments per sign, in `1..=MAX_STEPS`.
    pub n_steps: usize,
    /// Contact skin in mesh units, finite and `>= 0` (see the module rule).
    pub skin: f64,
    /// Fraction of points, in `[0, 1)`, that may hit before a motion counts as blocked.
    pub hit_tolerance: f64,
    /// Points inside the obstacle at rest never count (see the module's rule 4).
    pub skip_inside: bool,
}

impl Default for SweepParams {
    /// 16 steps, skin `0.005`, hit tolerance `0.02`, points inside at rest skipped.
    fn default() -> Self {
        Self {
            n_steps: 16,
            skin: 0.005,
            hit_tolerance: 0.02,
            skip_inside: true,
        }
    }
}

/// Result of one candidate: index 0 the positive sign, 1 the negative sign.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SweepResult {
    /// Fraction of the range swept before more than `hit_tolerance * P` points have hit.
    pub free_fraction: [f64; 2],
    /// Fraction of points whose path hits the obstacle within the range.
    pub colliding_fraction: [f64; 2],
}

/// Rest state of a point: its clearance and, within `skin`, its contact.
#[derive(Debug, Clone, Copy)]
struct Rest {
    /// Distance to the obstacle surface at rest (no crossing before the point has moved
    /// this far: steps inside that ball are not cast).
    clearance: f64,
    /// The contact, when `clearance <= skin`.
    contact: Option<Contact>,
    /// Inside the obstacle at rest (rule 4): the point never counts.
    inside: bool,
}

/// Rest state of a point in contact with the obstacle.
#[derive(Debug, Clone, Copy)]
struct Contact {
    /// Closest obstacle point at rest.
    closest: Point3<f64>,
    /// Normal of the tangent plane there (None: degenerate triangle and zero distance).
    normal: Option<Unit<Vector3<f64>>>,
}

/// The rest states of a moving part's points against one [`SweepObstacle`]
/// ([`SweepObstacle::rest_states`]), for [`SweepObstacle::sweep_from_rest`].
#[derive(Debug, Clone)]
pub struct RestStates {
    obstacle: u64,
    points: Vec<Point3<f64>>,
    skin: f64,
    skip_inside: bool,
    rests: Vec<Rest>,
}

impl RestStates {
    /// True when these are the states of exactly `points` (bit for bit) under `params`' skin
    /// and inside rule.
    pub fn matches(&self, points: &[Point3<f64>], params: &SweepParams) -> bool {
        self.skin.to_bits() == params.skin.to_bits()
            && self.skip_inside == params.skip_inside
            && self.points.len() == points.len()
            && self.points.iter().zip(points).all(|(a, b)| {
                a.coords
                    .iter()
                    .zip(b.coords.iter())
                    .all(|(x, y)| x.to_bits() == y.to_bits())
            })
    }
}

/// An obstacle mesh prepared once (parry BVH) for many swept tests and line distances.
///
/// Build it once per obstacle and reuse it for every candidate of a moving part; it is
/// `Sync`, so rayon tasks share it.
#[derive(Clone)]
pub struct SweepObstacle {
    mesh: Option<ParryMesh>,
    /// Diagonal of the obstacle's bounding box (0 when empty).
    diagonal: f64,
    /// Distinct per [`SweepObstacle::new`] (clones share it, and their mesh): the rest states
    /// of one obstacle are refused by another.
    id: u64,
}

/// Source of [`SweepObstacle`] ids.
static NEXT_OBSTACLE: AtomicU64 = AtomicU64::new(0);

impl std::fmt::Debug for SweepObstacle {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SweepObstacle")
            .field("n_faces", &self.n_faces())
            .field("diagonal", &self.diagonal)
            .finish()
    }
}

impl SweepObstacle {
    /// Prepare an obstacle (builds parry's BVH). A mesh without faces is a valid, empty
    /// obstacle.
    ///
    /// # Errors
    /// [`GeometryError::Invalid`] for a vertex coordinate beyond [`MAX_COORDINATE`].
    pub fn new(mesh: &TriMesh) -> Result<Self> {
        check_magnitude(mesh.vertices(), "obstacle vertices")?;
        if mesh.n_faces() == 0 {
            return Ok(Self {
                mesh: None,
                diagonal: 0.0,
                id: NEXT_OBSTACLE.fetch_add(1, Ordering::Relaxed),
            });
        }
        let diagonal = mesh
            .bounds()
            .map(|(lo, hi)| (hi - lo).norm())
            .unwrap_or(0.0);
        // `TriMesh::new` guarantees finite vertices and in-range indices; parry only
        // refuses an empty index buffer, excluded above.
        let flushed = mesh
            .vertices()
            .iter()
            .map(crate::mesh::flush_tiny)
            .collect();
        let mesh = ParryMesh::new(flushed, mesh.faces().to_vec()).ok();
        Ok(Self {
            mesh,
            diagonal,
            id: NEXT_OBSTACLE.fetch_add(1, Ordering::Relaxed),
        })
    }

    /// Number of obstacle triangles.
    pub fn n_faces(&self) -> usize {
        self.mesh.as_ref().map_or(0, |m| m.indices().len())
    }

    /// True when the obstacle has no faces (every motion is free).
    pub fn is_empty(&self) -> bool {
        self.mesh.is_none()
    }

    /// Swept test of C candidates (see the module documentation), parallel over candidates,
    /// signs and blocks of points: [`Self::rest_states`] of the points, then
    /// [`Self::sweep_from_rest`].
    ///
    /// # Errors
    /// [`GeometryError::Degenerate`] for `P = 0`, `C = 0` or a zero-length direction;
    /// [`GeometryError::NonFinite`] for NaN/inf points, origins, directions or ranges;
    /// [`GeometryError::Invalid`] for a negative range, a revolute range above `2 pi`, or
    /// bad parameters (steps outside `1..=MAX_STEPS`, negative/non-finite skin, tolerance
    /// outside `[0, 1)`, more than [`MAX_CASTS`] casts).
    pub fn sweep(
        &self,
        points: &[Point3<f64>],
        candidates: &[SweepCandidate],
        params: &SweepParams,
    ) -> Result<Vec<SweepResult>> {
        self.check(points, candidates, params)?;
        let rest = self.rest_states(points, params)?;
        self.sweep_from_rest(&rest, candidates, params)
    }

    /// Validate the inputs of [`Self::sweep`] without sweeping (cheap: before paying for
    /// [`Self::rest_states`]).
    ///
    /// # Errors
    /// As [`Self::sweep`].
    pub fn check(
        &self,
        points: &[Point3<f64>],
        candidates: &[SweepCandidate],
        params: &SweepParams,
    ) -> Result<()> {
        check_params(points, candidates, params)?;
        candidate_axes(candidates).map(|_| ())
    }

    /// The rest state of every point against this obstacle (its clearance, its contact within
    /// the skin, and rule 4's inside test): the part of a sweep that depends on the points and
    /// on `params.skin` / `params.skip_inside`, not on the candidates. One closest-point query
    /// and, outside the skin, five parity rays per point; parallel over points.
    ///
    /// # Errors
    /// [`GeometryError::Degenerate`] for `P = 0`; [`GeometryError::NonFinite`] for NaN/inf
    /// points; [`GeometryError::Invalid`] for a coordinate beyond [`MAX_COORDINATE`] or a
    /// negative/non-finite skin.
    pub fn rest_states(&self, points: &[Point3<f64>], params: &SweepParams) -> Result<RestStates> {
        check_points(points, params)?;
        let skin = params.skin;
        let rests = match &self.mesh {
            None => Vec::new(),
            Some(mesh) => points
                .par_iter()
                .map(|p| {
                    let mut rest = rest_state(mesh, p, skin);
                    rest.inside = params.skip_inside
                        && rest.clearance > skin
                        && inside_by_parity(mesh, p, self.diagonal);
                    rest
                })
                .collect(),
        };
        Ok(RestStates {
            obstacle: self.id,
            points: points.to_vec(),
            skin,
            skip_inside: params.skip_inside,
            rests,
        })
    }

    /// [`Self::sweep`] of the points of `rest` (computed by [`Self::rest_states`] of this
    /// obstacle): the same results, without recomputing the rest states. The refinement sweeps
    /// one moving part against one obstacle once per edge, each time with other candidates.
    ///
    /// # Errors
    /// As [`Self::sweep`]; [`GeometryError::Invalid`] when `params` has another skin or
    /// inside rule than `rest` was computed with, or `rest` is of another obstacle.
    pub fn sweep_from_rest(
        &self,
        rest: &RestStates,
        candidates: &[SweepCandidate],
        params: &SweepParams,
    ) -> Result<Vec<SweepResult>> {
        let points = &rest.points[..];
        check_params(points, candidates, params)?;
        if rest.obstacle != self.id {
            return Err(GeometryError::Invalid(
                "sweep_from_rest: the rest states are of another obstacle".to_string(),
            ));
        }
        if rest.skin.to_bits() != params.skin.to_bits() || rest.skip_inside != params.skip_inside {
            return Err(GeometryError::Invalid(format!(
                "sweep_from_rest: the rest states were computed with skin {} / skip_inside {}, \
                 not {} / {}",
                rest.skin, rest.skip_inside, params.skin, params.skip_inside
            )));
        }
        let axes = candidate_axes(candidates)?;
        let Some(mesh) = &self.mesh else {
            return Ok(vec![
                SweepResult {
                    free_fraction: [1.0; 2],
                    colliding_fraction: [0.0; 2],
                };
                candidates.len()
            ]);
        };
        let skin = params.skin;
        let rests = &rest.rests;
        let eps = 1e-9 * self.diagonal.max(1e-12);
        let tasks: Vec<(usize, usize)> = (0..candidates.len())
            .flat_map(|c| [(c, 0), (c, 1)])
            .collect();
        let first_hits: Vec<Vec<f64>> = tasks
            .par_iter()
            .map(|&(c, s)| {
                let cand = &candidates[c];
                let sign = if s == 0 { 1.0 } else { -1.0 };
                let path = Path::new(cand, &axes[c], sign, params.n_steps);
                points
                    .par_chunks(POINT_CHUNK)
                    .zip(rests.par_chunks(POINT_CHUNK))
                    .flat_map_iter(|(ps, rs)| {
                        ps.iter()
                            .zip(rs)
                            .map(|(p, rest)| path.first_hit(mesh, p, rest, skin, eps))
                            .collect::<Vec<f64>>()
                    })
                    .collect()
            })
            .collect();
        let n = points.len();
        // Number of hits that must be exceeded: count > tol * P  <=>  count >= m.
        let m = (params.hit_tolerance * n as f64).floor() as usize + 1;
        let mut out = Vec::with_capacity(candidates.len());
        for c in 0..candidates.len() {
            let mut res = SweepResult {
                free_fraction: [1.0; 2],
                colliding_fraction: [0.0; 2],
            };
            for s in 0..2 {
                let mut hits: Vec<f64> = first_hits[2 * c + s]
                    .iter()
                    .copied()
                    .filter(|u| u.is_finite())
                    .collect();
                res.colliding_fraction[s] = hits.len() as f64 / n as f64;
                if hits.len() >= m {
                    let (_, kth, _) = hits.select_nth_unstable_by(m - 1, f64::total_cmp);
                    res.free_fraction[s] = kth.clamp(0.0, 1.0);
                }
            }
            out.push(res);
        }
        Ok(out)
    }

    /// Distance from each infinite line `(origins[c], directions[c])` to the obstacle
    /// surface, parallel over lines.
    ///
    /// The line is clipped to a segment centred on the projection of the mesh's bounding-box
    /// centre, of half-length the box diagonal (the closest point of the line always lies
    /// within half a diagonal of that projection), and measured with parry's
    /// `query::distance` of the segment against the mesh (0 when it crosses the surface).
    ///
    /// # Errors
    /// [`GeometryError::Degenerate`] for an empty obstacle or a zero-length direction;
    /// [`GeometryError::Shape`] when the lengths differ; [`GeometryError::NonFinite`].
    pub fn line_distance(
        &self,
        origins: &[Point3<f64>],
        directions: &[Vector3<f64>],
    ) -> Result<Vec<f64>> {
        let Some(mesh) = &self.mesh else {
            return Err(GeometryError::Degenerate(
                "line_mesh_distance: the mesh has no faces".to_string(),
            ));
        };
        let axes = line_axes(origins, directions)?;
        let aabb = mesh.local_aabb();
        let centre = aabb.center();
        let half = self.diagonal.max(1e-9);
        let id = Isometry::identity();
        origins
            .par_iter()
            .zip(axes.par_iter())
            .map(|(o, u)| {
                let mid = o + u.as_ref() * (centre - o).dot(u);
                let seg = Segment::new(mid - u.as_ref() * half, mid + u.as_ref() * half);
                query::distance(&id, &seg, &id, mesh).map_err(|e| {
                    GeometryError::Invalid(format!("line_mesh_distance: parry query failed: {e}"))
                })
            })
            .collect()
    }
}

/// Swept test of C candidates against one obstacle mesh (see the module documentation).
///
/// Convenience wrapper building a [`SweepObstacle`]; reuse one obstacle for many calls.
///
/// # Errors
/// As [`SweepObstacle::sweep`].
pub fn sweep_collisions(
    points: &[Point3<f64>],
    obstacle: &TriMesh,
    candidates: &[SweepCandidate],
    params: &SweepParams,
) -> Result<Vec<SweepResult>> {
    // Validate before paying for the BVH.
    check_params(points, candidates, params)?;
    candidate_axes(candidates)?;
    SweepObstacle::new(obstacle)?.sweep(points, candidates, params)
}

/// Distance from each infinite line to a mesh surface: `(C,)` mesh units.
///
/// The "attachment" term of refinement: a hinge must lie on or near its reference part.
///
/// Exact, by projection: the distance between an infinite line and a triangle equals the
/// distance, in the plane orthogonal to the line, from the line's trace to the triangle
/// projected along the line. Each line projects the mesh's vertices once (`V` dot
/// products), then takes the 2D point-to-triangle distance of every face, stopping at 0:
/// `O(V + F)` per line without any acceleration structure, parallel over lines (rayon).
/// For the tens of lines and tens of thousands of faces of one refinement edge this is
/// several times faster than a BVH query of a segment spanning the mesh
/// ([`SweepObstacle::line_distance`], whose long segment defeats the BVH's pruning), and
/// builds nothing.
///
/// # Errors
/// [`GeometryError::Degenerate`] for a mesh without faces or a zero-length direction;
/// [`GeometryError::Shape`] when the lengths differ; [`GeometryError::NonFinite`];
/// [`GeometryError::Invalid`] for coordinates beyond [`MAX_COORDINATE`].
pub fn line_mesh_distance(
    origins: &[Point3<f64>],
    directions: &[Vector3<f64>],
    mesh: &TriMesh,
) -> Result<Vec<f64>> {
    let axes = line_axes(origins, directions)?;
    check_magnitude(mesh.vertices(), "mesh vertices")?;
    if mesh.n_faces() == 0 {
        return Err(GeometryError::Degenerate(
            "line_mesh_distance: the mesh has no faces".to_string(),
        ));
    }
    let (verts, faces) = (mesh.vertices(), mesh.faces());
    Ok(origins
        .par_iter()
        .zip(axes.par_iter())
        .map(|(o, u)| {
            let (e1, e2) = orthonormal_pair(u);
            let proj: Vec<[f64; 2]> = verts
                .iter()
                .map(|v| {
                    let r = v - o;
                    [r.dot(&e1), r.dot(&e2)]
                })
                .collect();
            let mut best = f64::INFINITY;
            for f in faces {
                let d2 = origin_triangle_dist2(
                    proj[f[0] as usize],
                    proj[f[1] as usize],
                    proj[f[2] as usize],
                );
                if d2 < best {
                    best = d2;
                    if best == 0.0 {
                        break;
                    }
                }
            }
            best.sqrt()
        })
        .collect())
}

/// Two unit vectors completing `u` to an orthonormal basis.
fn orthonormal_pair(u: &Unit<Vector3<f64>>) -> (Vector3<f64>, Vector3<f64>) {
    // The coordinate axis least aligned with u keeps the cross product well conditioned.
    let a = if u.x.abs() <= u.y.abs() && u.x.abs() <= u.z.abs() {
        Vector3::x()
    } else if u.y.abs() <= u.z.abs() {
        Vector3::y()
    } else {
        Vector3::z()
    };
    let e1 = u.cross(&a).normalize();
    let e2 = u.cross(&e1);
    (e1, e2)
}

/// Squared 2D distance from the origin to the closed triangle `(a, b, c)` (0 inside;
/// a degenerate triangle is its edges).
fn origin_triangle_dist2(a: [f64; 2], b: [f64; 2], c: [f64; 2]) -> f64 {
    let cross = |p: [f64; 2], q: [f64; 2]| p[0] * q[1] - p[1] * q[0];
    let (s0, s1, s2) = (cross(a, b), cross(b, c), cross(c, a));
    let area2 = s0 + s1 + s2;
    if area2 != 0.0 {
        let inside = if area2 > 0.0 {
            s0 >= 0.0 && s1 >= 0.0 && s2 >= 0.0
        } else {
            s0 <= 0.0 && s1 <= 0.0 && s2 <= 0.0
        };
        if inside {
            return 0.0;
        }
    }
    origin_segment_dist2(a, b)
        .min(origin_segment_dist2(b, c))
        .min(origin_segment_dist2(c, a))
}

/// Squared 2D distance from the origin to the segment `[a, b]`.
fn origin_segment_dist2(a: [f64; 2], b: [f64; 2]) -> f64 {
    let d = [b[0] - a[0], b[1] - a[1]];
    let len2 = d[0] * d[0] + d[1] * d[1];
    let t = if len2 > 0.0 {
        (-(a[0] * d[0] + a[1] * d[1]) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let p = [a[0] + t * d[0], a[1] + t * d[1]];
    p[0] * p[0] + p[1] * p[1]
}

/// The stepped path of one candidate sign.
struct Path {
    kind: MotionKind,
    origin: Point3<f64>,
    axis: Unit<Vector3<f64>>,
    /// Signed motion per step (radians or mesh units).
    step: f64,
    n_steps: usize,
    /// Rotation by one step (revolute only).
    step_motion: Motion,
}

impl Path {
    fn new(cand: &SweepCandidate, axis: &Unit<Vector3<f64>>, sign: f64, n_steps: usize) -> Self {
        let step = sign * cand.range / n_steps as f64;
        let step_motion = match cand.kind {
            MotionKind::Revolute => Motion::about_axis(&cand.origin, axis, step, 0.0),
            MotionKind::Prismatic => Motion::about_axis(&cand.origin, axis, 0.0, step),
        };
        Self {
            kind: cand.kind,
            origin: cand.origin,
            axis: *axis,
            step,
            n_steps,
            step_motion,
        }
    }

    /// Motion parameter in `[0, 1]` of the first counted hit of point `p`, `inf` if none.
    fn first_hit(
        &self,
        mesh: &ParryMesh,
        p: &Point3<f64>,
        rest: &Rest,
        skin: f64,
        eps: f64,
    ) -> f64 {
        if rest.inside {
            return f64::INFINITY;
        }
        let n = self.n_steps as f64;
        let contact = rest.contact.as_ref();
        match self.kind {
            MotionKind::Prismatic => {
                // Collinear steps: one segment over the whole range is the same test.
                if (self.step * n).abs() < rest.clearance {
                    return f64::INFINITY;
                }
                let end = p + self.axis.as_ref() * (self.step * n);
                cast_segment(mesh, p, &end, p, contact, skin, true, eps).unwrap_or(f64::INFINITY)
            }
            MotionKind::Revolute => {
                // Arc length per step; segments ending within the rest clearance (path
                // length so far below it) cannot cross the obstacle and are not cast.
                let v = p - self.origin;
                let radius = (v - self.axis.as_ref() * v.dot(&self.axis)).norm();
                let arc = radius * self.step.abs();
                let mut a = *p;
                for k in 0..self.n_steps {
                    let b = self.step_motion.apply(&a);
                    if (k + 1) as f64 * arc >= rest.clearance {
                        if let Some(f) = cast_segment(mesh, &a, &b, p, contact, skin, k == 0, eps) {
                            return (k as f64 + f) / n;
                        }
                    }
                    a = b;
                }
                f64::INFINITY
            }
        }
    }
}

/// Fraction `t / len` in `[0, 1]` along segment `a -> b` of its first counted crossing.
#[allow(clippy::too_many_arguments)]
fn cast_segment(
    mesh: &ParryMesh,
    a: &Point3<f64>,
    b: &Point3<f64>,
    rest: &Point3<f64>,
    contact: Option<&Contact>,
    skin: f64,
    first_step: bool,
    eps: f64,
) -> Option<f64> {
    let v = b - a;
    let len = v.norm();
    if len.is_nan() || len <= 0.0 {
        return None;
    }
    let dir = v / len;
    let n_tris = mesh.indices().len() as u32;
    // Rule 1: on the first step, contact points ignore crossings closer than `skin`.
    let mut t0 = if first_step && contact.is_some() {
        skin
    } else {
        0.0
    };
    for _ in 0..=MAX_RECASTS {
        if t0 >= len {
            return None;
        }
        let ray = Ray::new(a + dir * t0, dir);
        let hit = mesh.cast_local_ray_and_get_normal(&ray, len - t0, false)?;
        let t = t0 + hit.time_of_impact;
        let Some(c) = contact else {
            return Some(t / len);
        };
        let tri = match hit.feature {
            FeatureId::Face(id) if id >= n_tris => id - n_tris,
            FeatureId::Face(id) => id,
            _ => u32::MAX,
        };
        let point = a + dir * t;
        // Rule 2: a surface touched at rest (the triangle's plane, so that the rule does
        // not depend on how a flat face is triangulated).
        let touched = tri < n_tris && {
            let t = mesh.triangle(tri);
            match t.normal() {
                Some(nrm) => (rest - t.a).dot(&nrm).abs() <= skin,
                None => t.distance_to_local_point(rest, true) <= skin,
            }
        };
        // Rule 3: the tangent slab of the rest contact.
        let in_slab = match c.normal {
            Some(nrm) => (point - c.closest).dot(&nrm).abs() <= skin,
            None => (point - c.closest).norm() <= skin,
        };
        if !(touched || in_slab) {
            return Some(t / len);
        }
        t0 = t + eps;
    }
    None
}

/// The rest clearance of a point, and its contact when within `skin` of the obstacle.
fn rest_state(mesh: &ParryMesh, p: &Point3<f64>, skin: f64) -> Rest {
    let (proj, feature) = mesh.project_local_point_and_get_feature(p);
    let clearance = (p - proj.point).norm();
    if clearance > skin {
        return Rest {
            clearance,
            contact: None,
            inside: false,
        };
    }
    // The direction from the closest point to the point is the tangent plane's normal
    // wherever the point is off the surface: on a face it is the face normal, at an edge or
    // a vertex it is the one normal that does not depend on which adjacent triangle parry
    // reports (which the mirror-symmetry property test found). A point on the surface
    // takes the reported triangle's normal.
    let face_normal = || match feature {
        FeatureId::Face(id) if (id as usize) < mesh.indices().len() => mesh.triangle(id).normal(),
        _ => None,
    };
    let normal = if clearance > 1e-9 * skin.max(f64::MIN_POSITIVE) {
        Unit::try_new(p - proj.point, 0.0).or_else(face_normal)
    } else {
        face_normal().or_else(|| Unit::try_new(p - proj.point, 1e-12))
    };
    Rest {
        clearance,
        contact: Some(Contact {
            closest: proj.point,
            normal,
        }),
        inside: false,
    }
}

/// Fixed, generic directions of the parity rays of rule 4 (normalised where used; none
/// parallel to a coordinate plane, so rays do not run along the faces of axis-aligned parts).
const PARITY_DIRECTIONS: [[f64; 3]; 5] = [
    [0.57, 0.58, 0.59],
    [-0.31, 0.93, 0.32],
    [0.72, -0.21, -0.67],
    [0.11, -0.42, 0.9],
    [-0.88, -0.36, 0.33],
];

/// Most crossings counted along one parity ray (a ray grazing a finely tessellated surface
/// can meet many triangles; beyond this the ray abstains).
const MAX_PARITY_CROSSINGS: usize = 256;

/// Rule 4: `p` lies inside the obstacle when most of the [`PARITY_DIRECTIONS`] rays from it
/// cross the obstacle's surface an odd number of times.
///
/// The test needs no consistent triangle orientation and tolerates small holes (a ray
/// through a hole miscounts; the majority of five outvotes it); for an open surface (a
/// single panel) the rays disagree and the majority decides.
fn inside_by_parity(mesh: &ParryMesh, p: &Point3<f64>, diagonal: f64) -> bool {
    let aabb = mesh.local_aabb();
    // Every ray leaves the obstacle's box within this length.
    let reach = (p - aabb.center()).norm() + diagonal + 1.0;
    let eps = 1e-9 * diagonal.max(1e-12);
    let mut odd = 0;
    let mut votes = 0;
    for d in PARITY_DIRECTIONS {
        let dir = Vector3::from(d).normalize();
        let mut t0 = 0.0;
        let mut n = 0usize;
        let mut done = true;
        loop {
            let ray = Ray::new(p + dir * t0, dir);
            match mesh.cast_local_ray(&ray, reach - t0, false) {
                Some(t) => {
                    n += 1;
                    t0 += t + eps;
                    if n >= MAX_PARITY_CROSSINGS {
                        done = false;
                        break;
                    }
                }
                None => break,
            }
        }
        if done {
            votes += 1;
            odd += n % 2;
        }
    }
    votes > 0 && 2 * odd > votes
}

/// `P = 0` is an error (moving points).
fn check_some_points(points: &[Point3<f64>]) -> Result<()> {
    if points.is_empty() {
        return Err(GeometryError::Degenerate(
            "moving_points: no points (P = 0)".to_string(),
        ));
    }
    Ok(())
}

/// The skin is finite and `>= 0`.
fn check_skin(params: &SweepParams) -> Result<()> {
    if !(params.skin.is_finite() && params.skin >= 0.0) {
        return Err(GeometryError::Invalid(format!(
            "skin: {} must be finite and >= 0",
            params.skin
        )));
    }
    Ok(())
}

/// Validate the points and the skin of a sweep's rest states.
fn check_points(points: &[Point3<f64>], params: &SweepParams) -> Result<()> {
    check_some_points(points)?;
    crate::mesh::check_finite(points, "moving_points")?;
    check_magnitude(points, "moving_points")?;
    check_skin(params)
}

/// Validate the points, candidates and parameters of a sweep.
fn check_params(
    points: &[Point3<f64>],
    candidates: &[SweepCandidate],
    params: &SweepParams,
) -> Result<()> {
    check_some_points(points)?;
    if candidates.is_empty() {
        return Err(GeometryError::Degenerate(
            "origins: no candidate motions (C = 0)".to_string(),
        ));
    }
    crate::mesh::check_finite(points, "moving_points")?;
    check_magnitude(points, "moving_points")?;
    if params.n_steps == 0 || params.n_steps > MAX_STEPS {
        return Err(GeometryError::Invalid(format!(
            "n_steps: {} is outside 1..={MAX_STEPS}",
            params.n_steps
        )));
    }
    check_skin(params)?;
    if !(params.hit_tolerance >= 0.0 && params.hit_tolerance < 1.0) {
        return Err(GeometryError::Invalid(format!(
            "hit_tolerance: {} must be in [0, 1)",
            params.hit_tolerance
        )));
    }
    let casts = points.len() as u128 * candidates.len() as u128 * 2 * params.n_steps as u128;
    if casts > MAX_CASTS {
        return Err(GeometryError::Invalid(format!(
            "sweep_collisions: {casts} segment casts (P * C * 2 * n_steps) exceed the limit \
             {MAX_CASTS}"
        )));
    }
    for (i, c) in candidates.iter().enumerate() {
        if !c.range.is_finite() {
            return Err(GeometryError::NonFinite {
                what: "ranges".to_string(),
                index: i,
            });
        }
        if c.range < 0.0 {
            return Err(GeometryError::Invalid(format!(
                "ranges[{i}]: {} is negative (both signs are swept)",
                c.range
            )));
        }
        if c.kind == MotionKind::Prismatic && c.range > MAX_COORDINATE {
            return Err(GeometryError::Invalid(format!(
                "ranges[{i}]: prismatic range {} exceeds {MAX_COORDINATE:e} mesh units",
                c.range
            )));
        }
        if c.kind == MotionKind::Revolute && c.range > std::f64::consts::TAU + 1e-9 {
            return Err(GeometryError::Invalid(format!(
                "ranges[{i}]: revolute range {} rad exceeds 2 pi",
                c.range
            )));
        }
    }
    Ok(())
}

/// Unit axes of the candidates.
fn candidate_axes(candidates: &[SweepCandidate]) -> Result<Vec<Unit<Vector3<f64>>>> {
    let origins: Vec<Point3<f64>> = candidates.iter().map(|c| c.origin).collect();
    let dirs: Vec<Vector3<f64>> = candidates.iter().map(|c| c.direction).collect();
    line_axes(&origins, &dirs)
}

/// Validate lines (same count, finite, non-zero directions) and return unit directions.
fn line_axes(
    origins: &[Point3<f64>],
    directions: &[Vector3<f64>],
) -> Result<Vec<Unit<Vector3<f64>>>> {
    if directions.len() != origins.len() {
        return Err(GeometryError::Shape {
            what: "directions".to_string(),
            expected: format!("(C, 3) with C = {} (the number of origins)", origins.len()),
            got: format!("({}, 3)", directions.len()),
        });
    }
    crate::mesh::check_finite(origins, "origins")?;
    check_magnitude(origins, "origins")?;
    for (i, d) in directions.iter().enumerate() {
        if let Some(k) = d.iter().position(|x| !x.is_finite()) {
            return Err(GeometryError::NonFinite {
                what: "directions".to_string(),
                index: 3 * i + k,
            });
        }
    }
    directions
        .iter()
        .enumerate()
        .map(|(i, d)| {
            // Scale by the largest component first: any finite non-zero vector normalises.
            let big = d.amax();
            let u = if big > 0.0 { d / big } else { *d };
            match Unit::try_new(u, 0.0) {
                Some(u) => Ok(u),
                None => Err(GeometryError::Degenerate(format!(
                    "directions[{i}]: zero-length axis direction of candidate {i}"
                ))),
            }
        })
        .collect()
}

/// Error when a coordinate of `points` exceeds [`MAX_COORDINATE`] in magnitude.
fn check_magnitude(points: &[Point3<f64>], what: &str) -> Result<()> {
    match points
        .iter()
        .flat_map(|p| p.coords.iter().copied())
        .position(|x| x.abs() > MAX_COORDINATE)
    {
        Some(index) => Err(GeometryError::Invalid(format!(
            "{what}: coordinate at flat index {index} exceeds {MAX_COORDINATE:e} in magnitude"
        ))),
        None => Ok(()),
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
#[path = "sweep_tests.rs"]
mod tests;
