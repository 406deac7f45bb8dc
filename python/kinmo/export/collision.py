"""Collision geometry of exported links: a registry of convex decompositions.

Simulators collide convex shapes (MuJoCo only those; PyBullet turns every URDF collision
mesh into its convex hull), and the hull of a whole link fills the space its children move
in (a cabinet's hull swallows its drawers). So each link's collision geometry is a list of
convex pieces, written one OBJ file per piece (``<dest>_<k>.obj``, the link's mesh frame
and units). The methods (``kinmo export/predict/pseudo-label --collision NAME``):

- ``parts`` (default, issue 35): the hull of every leaf mesh, as ``hull``, except where that
  hull is concave, i.e. fills a slot, a shell or the inside of a frame that another part may
  move into (a bucket's body around which its handle turns, a stapler's channel, a cabinet
  frame modelled as one leaf of separate boards). A leaf is concave when a point of its hull
  lies farther than :data:`CONCAVITY` times the link's diagonal from the leaf's surface
  (seeded samples); it is then split into its connected components, or in two by planes
  (:func:`concave_parts`). Milliseconds per object; deterministic.
- ``hull``: the exact convex hull of every leaf mesh of the link (its PartNet
  ``textured_objs/*.obj`` parts, which are panels, handles, knobs: mostly convex already),
  kinmo's exact hull (:func:`kinmo.geometry.convex_hull`, the one the OBB fit uses; it
  replaced qhull, ``scipy.spatial.ConvexHull``, in issue 24: 1.8-5x faster per hull). A
  flat or too-small leaf becomes the thin slab of
  :func:`kinmo.export.kinematics.simulator_safe`; a zero-area leaf has no piece. This is the
  collision geometry PartNet-Mobility's own URDFs give in PyBullet (one hull per leaf OBJ),
  at milliseconds per object. The default of issues 24 to 34.
- ``vhacd``: V-HACD (PyBullet's ``pybullet.vhacd``) of the link's merged mesh, in a child
  process (seconds per link, 60 s limit, then the link's hull).
- ``coacd``: CoACD (Wei et al., SIGGRAPH 2022; the ``coacd`` package, ``pip install coacd``)
  of the link's merged mesh, in a child process (same limit and fallback).

The decompositions of ``vhacd`` and ``coacd`` are cached by the content of the link's mesh
and the method's settings (``$KINMO_VHACD_CACHE``, default ``~/.cache/kinmo/vhacd``), so
re-exports are instant; ``hull`` and ``parts`` are cheaper than a cache lookup and are not
cached.

The choice of default, measured on the shared objects (time, pieces, the per-joint PyBullet
check of issue 35: each joint driven alone over its range, its penetration beyond the rest
pose's at most 2% of the diagonal): ``bench/bench_collision.py`` and
``docs/results/collision.md`` (issue 24, item 2; issue 35).

Length: over 500 lines, about a third of them docstrings and comments: one topic, the registry of
collision methods and the one writer they share.
"""

from __future__ import annotations

import hashlib
import os
import subprocess
import sys
import tempfile
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path
from typing import Callable

import numpy as np

from kinmo.errors import KinmoDataError, KinmoUsageError
from kinmo.export.kinematics import FLAT_RELATIVE, SLAB_THICKNESS, LinkMesh, simulator_safe, write_obj
from kinmo.geometry import convex_hull, sample_surface
from kinmo.io import atomic_path

__all__ = ["COLLISION_METHODS", "DEFAULT_COLLISION", "CollisionMethod", "collision_pieces",
           "leaf_hulls", "check_collision_method"]

#: V-HACD voxel resolution. PyBullet's default is 100000; V-HACD's time grows steeply with it
#: on some PartNet parts (a laptop screen link: 1.4 s at 10000, 260 s at 50000), and 10000
#: (the smallest it accepts) gives collision pieces that follow PartNet parts closely enough.
VHACD_RESOLUTION = 10_000
#: V-HACD's most clipping stages (its default 20): bounds the number of pieces and the time.
VHACD_DEPTH = 10
#: CoACD's concavity threshold (its default).
COACD_THRESHOLD = 0.05
#: Seconds a decomposition may run on one link before the link's convex hull is used instead.
DECOMPOSITION_TIMEOUT = 60.0

Piece = tuple[np.ndarray, np.ndarray]


@dataclass(frozen=True)
class CollisionMethod:
    """One registered way to make a link's convex pieces.

    Attributes
    ----------
    name : str
        Name on the command line (``--collision NAME``).
    description : str
        One line for ``--help`` and ``docs``.
    pieces : callable
        ``pieces(mesh: LinkMesh) -> list of (vertices (V, 3) float64, faces (F, 3) int64)``,
        the link's mesh frame and units.
    cached : bool
        Results are cached by mesh content (slow methods).
    settings : str
        Part of the cache key (the method's parameters).
    """

    name: str
    description: str
    pieces: Callable[[LinkMesh], list[Piece]]
    cached: bool = False
    settings: str = ""


#: Method name -> method, in registration order.
COLLISION_METHODS: dict[str, CollisionMethod] = {}
#: The method of ``kinmo export/predict/pseudo-label`` without ``--collision``.
DEFAULT_COLLISION = "parts"


def _register(method: CollisionMethod) -> None:
    COLLISION_METHODS[method.name] = method


def check_collision_method(name: str) -> CollisionMethod:
    """The registered method ``name``.

    Raises
    ------
    KinmoUsageError
        Unknown name (the message lists the known ones), or ``coacd`` without the package.
    """

    if name not in COLLISION_METHODS:
        raise KinmoUsageError("--collision", f"unknown collision method {name!r}; known: "
                                            f"{', '.join(COLLISION_METHODS)}")
    if name == "coacd":
        import importlib.util

        if importlib.util.find_spec("coacd") is None:
            raise KinmoUsageError("--collision", "coacd needs the coacd package: pip install coacd")
    return COLLISION_METHODS[name]


# -- hull: one convex hull per leaf mesh -------------------------------------------------


def _hull(vertices: np.ndarray) -> Piece | None:
    """The exact convex hull of ``vertices`` (:func:`kinmo.geometry.convex_hull`, faces
    outwards); None without volume, or as flat as :func:`simulator_safe` counts flat
    (:data:`~kinmo.export.kinematics.FLAT_RELATIVE`), which then gets its slab."""
    hull = convex_hull(vertices)
    if hull is None:
        return None
    v, f = hull
    sv = np.linalg.svd(v - v.mean(axis=0), compute_uv=False)
    if not sv[-1] > FLAT_RELATIVE * sv[0]:
        return None
    return v, f


def _leaf_piece(vertices: np.ndarray, faces: np.ndarray) -> Piece | None:
    """The convex piece of one face set (``faces`` index ``vertices``): its hull, or for a
    flat set the thin slab of :func:`simulator_safe`; None without area."""
    used = np.unique(faces)
    v = vertices[used]
    hull = _hull(v)
    if hull is not None:
        return hull
    remap = np.full(len(vertices), -1, dtype=np.int64)
    remap[used] = np.arange(len(used))
    try:
        return simulator_safe(v, remap[faces], "leaf")
    except KinmoDataError:  # zero area: nothing to collide with
        return None


def _leaves(mesh: LinkMesh) -> list[np.ndarray]:
    """The faces of every leaf mesh of a link (the whole link when it has no leaves)."""
    counts = list(mesh.leaf_faces) or [len(mesh.faces)]
    ends = np.cumsum(counts)
    return [mesh.faces[e - n:e] for n, e in zip(counts, ends) if n]


def leaf_hulls(mesh: LinkMesh) -> list[Piece]:
    """The convex hull of every leaf mesh of a link (method ``hull``).

    Parameters
    ----------
    mesh : LinkMesh
        With ``leaf_faces`` (faces per leaf, in order); without, the link is one leaf.

    Returns
    -------
    list of (vertices (V, 3) float64, faces (F, 3) int64)
        One piece per leaf with area: its hull, or for a flat leaf the thin slab of
        :func:`kinmo.export.kinematics.simulator_safe`. Link mesh frame and units.
    """

    return [p for f in _leaves(mesh) if (p := _leaf_piece(mesh.vertices, f)) is not None]


_register(CollisionMethod("hull", "exact convex hull of every leaf mesh (milliseconds)",
                          leaf_hulls))


# -- parts: leaf hulls, concave leaves split ----------------------------------------------

#: ``parts``: a piece is split while a point of its hull lies farther than this share of the
#: link's bounding-box diagonal from the piece's own surface (its concavity). Chosen on the
#: shared objects (``docs/results/collision.md``, issue 35): 0.05 passed 0.5 points more
#: joints, but took 2.3x ``hull``'s export time; 0.1 stays within 2x.
CONCAVITY = 0.1
#: ``parts``: the most plane splits on the way from a leaf to one of its pieces.
SPLIT_DEPTH = 4
#: ``parts``: a concave leaf of more connected components than this is cut by planes instead.
MAX_COMPONENTS = 16
#: ``parts``: points sampled on each hull, and at most on each leaf surface (seeded, seed 0).
HULL_SAMPLES = 64
SURFACE_SAMPLES = 2048


def _part_piece(vertices: np.ndarray, used: np.ndarray) -> Piece | None:
    """The convex piece of one face set of ``parts``: its hull, or for a flat set the hull
    of the set thickened on both sides of its plane (a prism as thick as the slab of
    :func:`simulator_safe`, :data:`~kinmo.export.kinematics.SLAB_THICKNESS` times its largest
    extent, following its outline where the slab is its bounding rectangle); None without
    area. ``used``: the set's vertex ids (sorted, unique)."""
    v = vertices[used]
    hull = _hull(v)
    if hull is not None:
        return hull
    centre = v.mean(axis=0)
    _, sv, axes = np.linalg.svd(v - centre, full_matrices=False)
    if len(sv) < 2 or not sv[1] > FLAT_RELATIVE * sv[0]:  # a point or a segment
        return None
    offset = axes[2] * (SLAB_THICKNESS * float(np.ptp(v, axis=0).max()) / 2)
    return _hull(np.concatenate([v - offset, v + offset]))


def _components(faces: np.ndarray) -> list[np.ndarray]:
    """Indices into ``faces`` (vertex ids, ``(F, 3)`` int) of each connected component (faces
    sharing a vertex id), in order of their first face."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    n, nv = len(faces), int(faces.max()) + 1
    rows = np.repeat(np.arange(n), 3)
    graph = coo_matrix((np.ones(3 * n), (rows, n + faces.ravel())), shape=(n + nv, n + nv))
    _, label = connected_components(graph, directed=False)
    label = label[:n]
    _, first = np.unique(label, return_index=True)
    return [np.flatnonzero(label == label[i]) for i in np.sort(first)]


def _tree(points: np.ndarray):
    """A ``scipy.spatial.cKDTree`` of ``points`` (``(N, 3)`` float64) for a few nearest-point
    queries, built unbalanced (faster to build, same answers)."""
    from scipy.spatial import cKDTree

    return cKDTree(points, balanced_tree=False, compact_nodes=False)


class _Leaf:
    """One leaf mesh, for the concavity of its face subsets (surface samples drawn once, on
    first need)."""

    def __init__(self, vertices: np.ndarray, faces: np.ndarray, tol: float):
        self.v, self.f, self.tol = vertices, faces, tol

    @cached_property
    def centroids(self) -> np.ndarray:
        """Face centroids, ``(F, 3)`` float64."""
        return self.v[self.f].mean(axis=1)

    @cached_property
    def samples(self) -> tuple[np.ndarray, np.ndarray]:
        """Points on the leaf, spaced about half the tolerance apart (at most
        :data:`SURFACE_SAMPLES`), ``(n, 3)`` float64, and their faces, ``(n,)`` int64."""
        tri = self.v[self.f]
        area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
        n = int(min(SURFACE_SAMPLES, max(HULL_SAMPLES, np.ceil(area.sum() / (0.5 * self.tol) ** 2))))
        return sample_surface(self.v, self.f, n, seed=0)

    @cached_property
    def merged(self) -> np.ndarray:
        """``faces`` with vertices of equal position given one id, ``(F, 3)`` int64."""
        used = np.unique(self.f)
        _, ids = np.unique(self.v[used], axis=0, return_inverse=True)
        lookup = np.zeros(len(self.v), dtype=np.int64)
        lookup[used] = ids.ravel()
        return lookup[self.f]

    def concave(self, sub: np.ndarray, used: np.ndarray, hull: Piece) -> bool:
        """Whether a point of those sampled on ``hull`` lies farther than the tolerance from
        the surface of the faces ``sub`` (of vertex ids ``used``): from their vertices and,
        where those are not near enough, from the leaf's surface samples on them."""
        on_hull, _ = sample_surface(*hull, HULL_SAMPLES, seed=0)
        d = _tree(self.v[used]).query(on_hull)[0]
        far = d > self.tol
        if not far.any():
            return False
        points, face = self.samples
        mine = np.zeros(len(self.f), dtype=bool)
        mine[sub] = True
        near = points[mine[face]]
        if not len(near):
            return True
        return bool((_tree(near).query(on_hull[far])[0] > self.tol).any())

    def split(self, sub: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
        """``sub`` cut in two by the plane through the middle of its face centroids along
        their principal axis (of largest spread); None when no plane separates them."""
        c = self.centroids[sub]
        _, _, axes = np.linalg.svd(c - c.mean(axis=0), full_matrices=False)
        t = c @ axes[0]
        left = t < 0.5 * (t.min() + t.max())
        if left.all() or not left.any():
            return None
        return sub[left], sub[~left]


def concave_parts(mesh: LinkMesh) -> list[Piece]:
    """Convex pieces following concave leaves (method ``parts``, the default).

    Every leaf mesh gets its convex hull, as in ``hull``, unless that hull is concave: some
    point of it (of :data:`HULL_SAMPLES` sampled on it) lies farther than :data:`CONCAVITY`
    times the link's bounding-box diagonal from the leaf's surface (its vertices and up to
    :data:`SURFACE_SAMPLES` points sampled on it), i.e. the hull fills a slot, a shell or the
    inside of a frame that another part may move into. A concave leaf is split into its
    connected components (faces sharing a vertex position: a cabinet frame modelled as one
    leaf of separate boards) when it has 2 to :data:`MAX_COMPONENTS`; a concave leaf of one
    component, and any concave piece below it, is cut in two by the plane through the middle
    of its face centroids, across their principal axis of largest spread, at most
    :data:`SPLIT_DEPTH` cuts deep. Each piece is checked the same way; one no larger
    than the tolerance is kept whole. Every face lies in one piece, so the pieces cover the
    leaf's surface. A flat piece is the hull of its points moved by half a slab thickness to
    both sides of its plane (:func:`_part_piece`). Deterministic (seeded samples).

    Parameters
    ----------
    mesh : LinkMesh
        Faces of each leaf in ``leaf_faces``; a mesh without it counts as a single leaf.

    Returns
    -------
    list of (vertices (V, 3) float64, faces (F, 3) int64)
        Closed convex pieces with outward faces, in the link's mesh frame and units, leaf by
        leaf; at least one per leaf with area, exactly :func:`leaf_hulls`'s for a link
        without concave leaves (flat leaves aside).
    """

    if not len(mesh.faces):
        return []
    used = mesh.vertices[np.unique(mesh.faces)]
    tol = CONCAVITY * float(np.linalg.norm(np.ptp(used, axis=0)))
    out: list[Piece] = []
    for faces in _leaves(mesh):
        leaf: _Leaf | None = None
        stack = [(np.arange(len(faces)), -1)]  # depth -1: the whole leaf, not yet split
        while stack:
            sub, depth = stack.pop()
            used = np.unique(faces[sub])
            piece = _part_piece(mesh.vertices, used)
            if piece is None:
                continue
            # a piece no larger than the tolerance cannot be more concave than it
            if depth < SPLIT_DEPTH and len(sub) > 1 and \
                    np.linalg.norm(np.ptp(piece[0], axis=0)) > tol > 0:
                leaf = leaf or _Leaf(mesh.vertices, faces, tol)
                if leaf.concave(sub, used, piece):
                    comps = _components(leaf.merged) if depth < 0 else []
                    if 1 < len(comps) <= MAX_COMPONENTS:
                        stack.extend((c, 0) for c in reversed(comps))
                        continue
                    halves = leaf.split(sub)
                    if halves is not None:
                        stack.extend((h, max(depth, 0) + 1) for h in reversed(halves))
                        continue
            out.append(piece)
    return out


_register(CollisionMethod("parts", "leaf hulls, concave leaves split into convex parts "
                                   "(milliseconds)", concave_parts))


# -- vhacd / coacd: decompositions of the merged link mesh, in a child process -----------

_VHACD_SCRIPT = (
    "import sys, pybullet\n"
    "a = sys.argv[1:]\n"
    "pybullet.vhacd(a[0], a[1], a[2], resolution=int(a[3]), depth=int(a[4]))\n"
)

_COACD_SCRIPT = (
    "import sys, numpy as np, trimesh, coacd\n"
    "coacd.set_log_level('error')\n"
    "a = sys.argv[1:]\n"
    "m = trimesh.load(a[0], force='mesh', process=False)\n"
    "parts = coacd.run_coacd(coacd.Mesh(np.asarray(m.vertices), np.asarray(m.faces)),\n"
    "                        threshold=float(a[2]), seed=0)\n"
    "with open(a[1], 'w') as fh:\n"
    "    base = 1\n"
    "    for k, (v, f) in enumerate(parts):\n"
    "        fh.write(f'o piece_{k}\\n')\n"
    "        fh.writelines(f'v {x!r} {y!r} {z!r}\\n' for x, y, z in np.asarray(v, float).tolist())\n"
    "        fh.writelines(f'f {i + base} {j + base} {l + base}\\n' for i, j, l in np.asarray(f).tolist())\n"
    "        base += len(v)\n"
)


def _child(args: list[str], out: Path, timeout: float) -> bool:
    """Run a decomposition script in a child process (their C++ code prints to stdout and
    can run for minutes); False when it failed, timed out, or wrote no faces."""
    try:
        r = subprocess.run([sys.executable, "-c", *args], stdout=subprocess.DEVNULL,
                           stderr=subprocess.DEVNULL, timeout=timeout)
    except subprocess.TimeoutExpired:
        return False
    return r.returncode == 0 and out.is_file() and "\nf " in out.read_text()


def _split_objects(text: str) -> list[Piece]:
    """The ``o`` objects of an OBJ text as separate meshes (face indices renumbered)."""
    out: list[Piece] = []
    verts: list[list[float]] = []
    faces: list[list[int]] = []

    def flush() -> None:
        if faces:
            f = np.asarray(faces, dtype=np.int64) - 1
            lo, hi = int(f.min()), int(f.max())
            out.append((np.asarray(verts[lo:hi + 1], dtype=np.float64), f - lo))
        faces.clear()

    for line in text.splitlines():
        if line.startswith("o "):
            flush()
        elif line.startswith("v "):
            verts.append([float(t) for t in line.split()[1:4]])
        elif line.startswith("f "):
            faces.append([int(t.split("/")[0]) for t in line.split()[1:4]])
    flush()
    return out


def _whole_hull(mesh: LinkMesh) -> list[Piece]:
    """The fallback of a failed decomposition: the link's convex hull, or (flat) its slab."""
    hull = _hull(mesh.vertices)
    if hull is not None:
        return [hull]
    try:
        return [simulator_safe(mesh.vertices, mesh.faces, "link")]
    except KinmoDataError:
        return []


def _decompose(args: Callable[[Path, Path], list[str]]) -> Callable[[LinkMesh], list[Piece]]:
    """A method running ``python -c <args(in.obj, out.obj)>`` in a child process on the link's
    merged mesh; the link's hull (:func:`_whole_hull`) when it fails."""

    def pieces(mesh: LinkMesh) -> list[Piece]:
        with tempfile.TemporaryDirectory(prefix="kinmo-collision-") as tmp:
            src, out = Path(tmp) / "in.obj", Path(tmp) / "out.obj"
            write_obj(src, mesh.vertices, mesh.faces)
            if _child(args(src, out), out, DECOMPOSITION_TIMEOUT):
                return _split_objects(out.read_text())
        return _whole_hull(mesh)

    return pieces


_register(CollisionMethod(
    "vhacd", "V-HACD of each link (PyBullet; seconds per link, cached)",
    _decompose(lambda src, out: [_VHACD_SCRIPT, str(src), str(out), str(out.with_suffix(".log")),
                                 str(VHACD_RESOLUTION), str(VHACD_DEPTH)]),
    cached=True, settings=f"vhacd/{VHACD_RESOLUTION}/{VHACD_DEPTH}"))
_register(CollisionMethod(
    "coacd", "CoACD of each link (pip install coacd; seconds to minutes per link, cached)",
    _decompose(lambda src, out: [_COACD_SCRIPT, str(src), str(out), repr(COACD_THRESHOLD)]),
    cached=True, settings=f"coacd/{COACD_THRESHOLD}"))


# -- the one entry point ---------------------------------------------------------------


def _cache_dir() -> Path:
    env = os.environ.get("KINMO_VHACD_CACHE")
    if env:
        return Path(env)
    return Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache")) / "kinmo" / "vhacd"


def _obj_text(pieces: list[Piece]) -> str:
    """Several meshes as one OBJ text, an ``o piece_<k>`` object each (the cache's format,
    read back by :func:`_split_objects`)."""
    lines: list[str] = []
    base = 1
    for k, (v, f) in enumerate(pieces):
        lines.append(f"o piece_{k}\n")
        lines.extend(f"v {x!r} {y!r} {z!r}\n" for x, y, z in np.asarray(v, dtype=np.float64).tolist())
        lines.extend(f"f {a + base} {b + base} {c + base}\n" for a, b, c in np.asarray(f).tolist())
        base += len(v)
    return "".join(lines)


def collision_pieces(mesh: LinkMesh, dest: Path, method: str = DEFAULT_COLLISION) -> list[Path]:
    """A link's convex collision pieces by ``method``, one OBJ file each.

    Parameters
    ----------
    mesh : LinkMesh
        Mesh frame, mesh units.
    dest : Path
        Stem of the output files: ``<dest>_<k>.obj`` for piece ``k`` (written atomically),
        same frame as the mesh.
    method : str
        A name of :data:`COLLISION_METHODS`.

    Returns
    -------
    list of Path
        The pieces; empty for a mesh without faces (no collision geometry).

    Raises
    ------
    KinmoUsageError
        Unknown method (see :func:`check_collision_method`).
    """

    m = check_collision_method(method)
    if len(mesh.faces) == 0:
        return []
    if m.cached:
        h = hashlib.sha256()
        h.update(np.ascontiguousarray(mesh.vertices, dtype=np.float64).tobytes())
        h.update(np.ascontiguousarray(mesh.faces, dtype=np.int64).tobytes())
        h.update(m.settings.encode())
        cached = _cache_dir() / f"{h.hexdigest()[:32]}.obj"
        if not cached.is_file():
            cached.parent.mkdir(parents=True, exist_ok=True)
            text = _obj_text(m.pieces(mesh))
            with atomic_path(cached) as tmp:
                tmp.write_text(text)
        pieces = _split_objects(cached.read_text())
    else:
        pieces = m.pieces(mesh)
    files = []
    dest.parent.mkdir(parents=True, exist_ok=True)
    for k, (v, f) in enumerate(pieces):
        p = dest.parent / f"{dest.name}_{k}.obj"
        # atomic, not fsync'ed one by one: an object has tens to hundreds of pieces, and
        # every command writes them inside a staged object folder that appears whole
        with atomic_path(p) as tmp:
            write_obj(tmp, v, f)
        files.append(p)
    return files

