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
  (seeded samples) lies farther than :data:`CONCAVITY` times the link's diagonal from the
  leaf's surface (exact distances); it is then split into its connected components, or in
  two by planes (:func:`concave_parts`, the loop in Rust: :func:`kinmo.geometry.concave_pieces`).
  Milliseconds per object; deterministic.
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
"""

from __future__ import annotations

import hashlib
import os
import subprocess
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from kinmo.errors import KinmoDataError, KinmoUsageError
from kinmo.export.kinematics import FLAT_RELATIVE, SLAB_THICKNESS, LinkMesh, simulator_safe, write_obj
from kinmo.geometry import concave_pieces, convex_hull
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
#: shared objects (``docs/results/collision.md``, issue 35): 0.1 until session 36, when the
#: split moved to Rust with exact distances and 0.05 came within 2x ``hull``'s export time
#: (1.88x, the median of three runs), passing 4 more of 876 joints than 0.1.
CONCAVITY = 0.05
#: ``parts``: the most plane splits on the way from a leaf to one of its pieces.
SPLIT_DEPTH = 4
#: ``parts``: a concave leaf of more connected components than this is cut by planes instead.
MAX_COMPONENTS = 16
#: ``parts``: points sampled on each hull for the concavity test (seeded, seed 0).
HULL_SAMPLES = 64


def concave_parts(mesh: LinkMesh) -> list[Piece]:
    """Convex pieces following concave leaves (method ``parts``, the default).

    Every leaf mesh gets its convex hull, as in ``hull``, unless that hull is concave: some
    point of it (of :data:`HULL_SAMPLES` sampled on it) lies farther than :data:`CONCAVITY`
    times the link's bounding-box diagonal from the leaf's surface (exact distances to its
    triangles), i.e. the hull fills a slot, a shell or the inside of a frame that another
    part may move into. A concave leaf is split into its
    connected components (faces sharing a vertex position: a cabinet frame modelled as one
    leaf of separate boards) when it has 2 to :data:`MAX_COMPONENTS`; a concave leaf of one
    component, and any concave piece below it, is cut in two by the plane through the middle
    of its face centroids, across their principal axis of largest spread, at most
    :data:`SPLIT_DEPTH` cuts deep. Each piece is checked the same way; one no larger
    than the tolerance is kept whole. Every face lies in one piece, so the pieces cover the
    leaf's surface. A flat piece is the hull of its points moved by half a slab thickness
    (:data:`~kinmo.export.kinematics.SLAB_THICKNESS` times its largest extent) to both sides
    of its plane, a prism that follows its outline where :func:`simulator_safe`'s slab is
    its bounding rectangle. Deterministic (seeded samples). The loop over a leaf's pieces
    runs in Rust (:func:`kinmo.geometry.concave_pieces`).

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
    got = concave_pieces(mesh.vertices, _leaves(mesh), tol, max_depth=SPLIT_DEPTH,
                         max_components=MAX_COMPONENTS, hull_samples=HULL_SAMPLES,
                         flat_relative=FLAT_RELATIVE, slab_thickness=SLAB_THICKNESS)
    return [(v, f) for leaf in got for v, f, _ in leaf]


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

