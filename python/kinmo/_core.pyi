"""Type stubs of :mod:`kinmo._core`, the native (Rust, pyo3) module.

Hand-written: keep in step with ``rust/kinmo-py/src``. The public, documented API is
:mod:`kinmo.geometry`; these functions take exactly-typed, C-compatible numpy arrays
(float64 coordinates, int64 faces) and raise ``ValueError`` (bad input) or ``OSError``
(files) naming the problem. The GIL is released while the Rust code runs.

Size bound: every array a function copies or creates has at most ``2**30`` values (8 GiB
of float64); a larger input (e.g. a broadcast view of ``2**31`` rows) or requested output
(``n = 2**40`` points, ``apply_motions`` with 1e5 x 1e5) is a ``ValueError`` naming the
argument, checked before any copy. An allocation numpy refuses below that bound is a
``MemoryError``. A Rust panic (a bug) never crosses: it becomes ``RuntimeError("<function>:
internal error in kinmo._core ...")``, an ordinary ``Exception``.
"""

from collections.abc import Sequence

import numpy as np
import numpy.typing as npt

__version__: str

F64 = npt.NDArray[np.float64]
F32 = npt.NDArray[np.float32]
I64 = npt.NDArray[np.int64]
Mesh = tuple[F64, I64]

# --- mesh (rust/kinmo-py/src/mesh.rs) ---------------------------------------------------

def load_obj(path: str, max_bytes: int = 1 << 32) -> Mesh:
    """Read one OBJ file: ``(vertices (V, 3) float64, faces (F, 3) int64)``.

    Triangulated, all objects/groups merged, materials ignored; a UTF-8 byte order mark is
    skipped. ``OSError`` naming the file when it is missing, unreadable, not a regular file
    (directory, ``/dev/zero``, FIFO) or larger than ``max_bytes`` (kinmo's ``file_bytes``
    limit); ``ValueError`` naming it when it is malformed, binary, a text file without vertices whose lines are no OBJ statements,
    has non-finite vertices or vertices beyond the float32 range (``|x| > 3.4e38``), or
    out-of-range face indices. An empty or comment-only file is an empty mesh.
    """

def load_objs(paths: Sequence[str], max_bytes: int = 1 << 32) -> list[Mesh]:
    """Read many OBJ files in parallel (input order); the first failing file raises."""

# --- sampling (rust/kinmo-py/src/sampling.rs) -------------------------------------------

def sample_surface(vertices: F64, faces: I64, n: int, seed: int) -> tuple[F64, I64]:
    """``n >= 1`` area-weighted points ``(n, 3)`` and their face indices ``(n,)``.

    ``0 <= seed < 2**64``; xoshiro256++ stream, bit-identical on every machine.
    """

def sample_surface_groups(
    meshes: Sequence[Mesh], groups: Sequence[Sequence[int]], n: int, seed: int
) -> F64:
    """``(G, n, 3)``: ``n`` points on the union of each group of meshes (parallel)."""

# --- obb (rust/kinmo-py/src/obb.rs) ------------------------------------------------------

def fit_obb(
    points: F64,
    *,
    volume_tolerance: float = 0.01,
    up: tuple[float, float, float] | None = (0.0, 1.0, 0.0),
    symmetry: bool = True,
) -> tuple[F64, F64, F64]:
    """``(center (3,), axes (3, 3) rows, half_extents (3,))`` of a point set ``(N, 3)``.

    Tight, up- and symmetry-aligned, canonical rows (see :mod:`kinmo.geometry.obb`).
    ``O(N log N)`` (exact hull, then at most 256 face-flush candidates measured on the hull
    vertices): 100 000 points on a sphere take about 3 s. ``ValueError`` on empty input,
    bad shape, NaN/inf or bad options.
    """

def fit_obb_batch(
    point_sets: Sequence[F64],
    *,
    volume_tolerance: float = 0.01,
    up: tuple[float, float, float] | None = (0.0, 1.0, 0.0),
    symmetry: bool = True,
) -> tuple[F64, F64, F64]:
    """``(centers (B, 3), axes (B, 3, 3), half_extents (B, 3))``, parallel; set ``i`` is
    named ``point_sets[i]`` in errors."""

# --- hull (rust/kinmo-py/src/hull.rs) ----------------------------------------------------

def convex_hull(points: F64) -> tuple[I64, I64] | None:
    """The exact convex hull of ``points (N, 3)``: ``(vertices (H,) int64, faces (F, 3)
    int64)``, indices into ``points``, faces counter-clockwise seen from outside; None when
    it has no volume (fewer than 4 points, or all on a plane). ``ValueError`` on a bad shape
    or NaN/inf."""

# --- contact (rust/kinmo-py/src/contact.rs) ----------------------------------------------

def contact_pairs(meshes: Sequence[Mesh], tolerance: float) -> tuple[I64, F64]:
    """``(pairs (K, 2) int64 with i < j, distances (K,) float64)`` within ``tolerance``.

    Exact surface distances (triangles); ``tolerance`` finite, >= 0. Meshes without faces
    pair with nothing. Mesh ``i`` is named ``meshes[i]`` in errors.
    """

def mesh_distance(vertices_a: F64, faces_a: I64, vertices_b: F64, faces_b: I64) -> float:
    """Exact minimum distance between two triangle-mesh surfaces (0 when touching).

    Scale-robust (coordinates scaled by a power of two first): exact at ``1e200`` and at
    ``1e-300``. ``ValueError`` when a mesh has no faces.
    """

# --- decompose (rust/kinmo-py/src/decompose.rs) ------------------------------------------

def concave_pieces(
    vertices: F64,
    leaves: Sequence[I64],
    tolerance: float,
    max_depth: int,
    max_components: int,
    hull_samples: int,
    flat_relative: float,
    slab_thickness: float,
) -> list[list[tuple[F64, I64, I64]]]:
    """Per leaf ``(F, 3)`` faces of ``vertices``: its convex pieces ``(vertices (H, 3),
    faces (T, 3), face ids (K,))`` (``kinmo.export.collision.concave_parts``).

    ``ValueError`` on bad arrays or settings.
    """

# --- interaction (rust/kinmo-py/src/interaction.rs) --------------------------------------

def interaction_region(
    moving: F64, reference: F64, radius: float
) -> tuple[npt.NDArray[np.bool_], npt.NDArray[np.bool_], F64, bool]:
    """``(mask_moving (Na,), mask_reference (Nb,), centroid (3,), empty)``.

    ``radius`` finite, > 0 (a point is selected at distance <= radius); both point sets
    non-empty and finite.
    """

# --- motion (rust/kinmo-py/src/motion.rs) ------------------------------------------------

def motion_transforms(origins: F64, directions: F64, angles: F64, translations: F64) -> F64:
    """``(C, 4, 4)`` homogeneous matrices: rotate ``angles[c]`` rad about the line
    ``(origins[c], directions[c])`` (right-hand rule), then translate ``translations[c]``
    along the unit direction (normalised scale-robustly: ``(1e300, 1e300, 0)`` is valid).
    Zero-length direction: ``ValueError`` naming the candidate."""

def apply_motions(
    points: F64, origins: F64, directions: F64, angles: F64, translations: F64
) -> F64:
    """``(C, N, 3)``: every candidate motion applied to ``points (N, 3)``, parallel.

    ``ValueError`` naming ``origins x points`` when ``C * N * 3`` exceeds ``2**30``."""

# --- pointnet (rust/kinmo-py/src/pointnet.rs) --------------------------------------------

def farthest_point_sample(points: F32, m: int) -> I64:
    """``(B, m)`` indices: farthest point sampling of each cloud of ``points (B, N, 3)``
    float32, starting at point 0, distances in float32 as PyTorch evaluates them, the first
    point of largest distance next. ``ValueError`` for ``m`` outside ``[1, N]`` or NaN/inf."""

def ball_query(points: F32, centers: F32, radius: float, k: int) -> I64:
    """``(B, M, k)`` indices into ``points (B, N, 3)``: for each centre of ``centers
    (B, M, 3)``, the first ``k`` points in index order within ``radius`` (squared distances in
    float64), padded with the first; the nearest point ``k`` times when none is within it."""

def k_nearest(points: F32, queries: F32, k: int) -> tuple[I64, F32]:
    """``(indices (B, N, k), distances (B, N, k) float32)``: the ``k`` nearest of ``points
    (B, M, 3)`` to each of ``queries (B, N, 3)``, by distance (float64) then index.
    ``ValueError`` for ``k`` outside ``[1, M]``."""

# --- sweep (rust/kinmo-py/src/sweep.rs) --------------------------------------------------

def sweep_collisions(
    moving_points: F64,
    obstacle_vertices: F64,
    obstacle_faces: I64,
    origins: F64,
    directions: F64,
    kinds: I64,
    ranges: F64,
    n_steps: int = 16,
    skin: float = 0.005,
    hit_tolerance: float = 0.02,
    skip_inside: bool = True,
) -> tuple[F64, F64]:
    """``(free_fraction (C, 2), colliding_fraction (C, 2))`` float64, column 0 the positive
    sign: swept-collision feasibility of C candidate motions (``kinds (C,)``: 0 revolute, 1
    prismatic; ``ranges (C,)`` radians / mesh units) of ``moving_points (P, 3)`` against one
    obstacle mesh (``F = 0``: all free). Rule: :mod:`kinmo.geometry.sweep`. ``ValueError``
    on bad input (``P = 0``, ``C = 0``, zero direction, bad kind/range/parameters)."""

class SweepObstacle:
    """An obstacle mesh (``vertices (V, 3)`` float64, ``faces (F, 3)`` int64, ``F = 0``
    valid) with its parry BVH built once, for many swept tests. ``ValueError`` on bad
    input. It keeps the rest states (clearance, contact, inside test) of the last moving
    points it swept: a sweep of the same points (bit for bit) with the same ``skin`` and
    ``skip_inside`` reuses them, with the same results."""

    def __init__(self, vertices: F64, faces: I64) -> None: ...
    @property
    def n_faces(self) -> int:
        """Number of obstacle triangles."""
    def sweep(
        self,
        moving_points: F64,
        origins: F64,
        directions: F64,
        kinds: I64,
        ranges: F64,
        n_steps: int = 16,
        skin: float = 0.005,
        hit_tolerance: float = 0.02,
        skip_inside: bool = True,
    ) -> tuple[F64, F64]:
        """``sweep_collisions`` of ``moving_points`` against this obstacle: the same
        results, the BVH not rebuilt."""

def line_mesh_distance(origins: F64, directions: F64, vertices: F64, faces: I64) -> F64:
    """``(C,)`` float64: distance from each infinite line to the mesh surface (exact, by
    projecting the mesh along the line).
    ``ValueError`` on bad input, a zero-length direction or a mesh without faces."""
