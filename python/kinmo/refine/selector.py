"""A learned selector of candidate axes: soft GNN priors, geometric terms, a small ranker.

kinmo extension of the refinement of Liu et al. 2023, Sec. 3.3. The paper scores the
candidates of the *predicted* fine type by ``0.5 feasibility + 0.3 direction + 0.2 position``;
a wrong orientation in the type (a door predicted ``R_H_S``) can then never be repaired, and
the fixed weights let the agreement terms decide. Here instead:

1. **Candidates of every orientation** (:func:`edge_candidates`): the lines of the predicted
   *coarse* motion (``R``: OBB edges, centre and interaction-region lines of all three axes;
   ``P``/``PR``: all three axes) of the moving part boxed in its own OBB, in its reference
   part's OBB axes and in the shape frame, plus the GNN's own line; near-duplicates merged.
2. **Soft priors from the GNN** (:class:`GNNPriors`, per candidate in
   :func:`candidate_features`): the GNN's axis-candidate distribution (softmax over its 10
   candidate directions, the mass of those parallel to the candidate), the horizontal /
   vertical and centre / side probabilities of the fine types *before* any consistency step,
   and the distance to the GNN's pivot.
3. **Geometric terms**: the swept collision of the moving part's surface samples against the
   meshes of every part not below it (:func:`kinmo.geometry.sweep_collisions`, parry in the
   Rust core: free and colliding fraction of the range per sign), the attachment distance
   (line to the reference part's mesh, :func:`kinmo.geometry.line_mesh_distance`, and to the
   samples of the reference part and of any static part), and a cheaper point proxy of the
   collision (the moving part's box moved by a few amounts in each sign; the fraction of the
   other parts' samples it newly encloses). The meshes are read once per shape from the
   graph's source folder (``graph.meta["source"]``, :func:`shape_meshes`); without it the
   mesh terms take neutral constants (free 1, colliding 0, distance = the point attachment),
   which drop out of the per-edge softmax, and the point terms remain. The *handle side*
   (revolute only): the distance from the line to the centroid of the moving part's own
   children (handles, knobs; ``d_child``, 0 without children) and the same for OBB-edge lines
   only (``d_child_edge``): a hinge lies at the side opposite the handle, which separates the
   parallel edges of a door that sweep and attachment cannot tell apart. The *semantic prior*
   (``sem_prior``, :mod:`kinmo.refine.semantic_prior`): the share of the training objects'
   joints of the same motion, category and part names whose axis is parallel to the line,
   which separates what geometry cannot (a microwave's vertical hinge from an oven's
   horizontal one).
4. **A ranker** (:mod:`kinmo.refine.ranker`, re-exported here: :class:`Ranker`,
   :func:`fit_ranker`, :func:`load_ranker`, :func:`calibrate`): a calibrated linear listwise
   score over these features, fit on out-of-fold GNN predictions of training objects.

Frames and units: mesh frame (y-up), mesh units; distance features divided by the moving
part's OBB diagonal ``L``.

Length: over 500 lines, about 30 % of them docstrings: steps 1 to 3 above are one topic, the
per-candidate features in the column order of :data:`~kinmo.refine.features.FEATURES`, computed
from the candidates, GNN priors and meshes defined here; the ranker is
:mod:`kinmo.refine.ranker`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from kinmo.data.graph import PartGraph
from kinmo.data.labels import VERTICAL_COS, pivots_are_central
from kinmo.data.model import FINE_TYPES
from kinmo.errors import KinmoError
from kinmo.geometry import SweepObstacle, line_mesh_distance
from kinmo.metrics.axis import line_distance
from kinmo.refine.candidates import (
    Candidates,
    candidate_axes,
    canonical_direction,
    frame_box,
    merge_candidates,
)
from kinmo.refine.features import FEATURES, FEATURE_GROUPS, FEATURE_INDEX as _F
from kinmo.refine.ranker import Ranker, calibrate, fit_ranker, load_ranker
from kinmo.refine.semantic_prior import SemanticPrior, motion_of

__all__ = [
    "FEATURES",
    "FEATURE_GROUPS",
    "GNNPriors",
    "ShapeMeshes",
    "Ranker",
    "graph_meshes",
    "candidate_features",
    "calibrate",
    "candidate_labels",
    "edge_candidates",
    "fit_ranker",
    "fixed_leaves",
    "freer_sign",
    "line_sweeps",
    "load_ranker",
    "rotate_about",
    "shape_meshes",
]

_PARALLEL_COS = float(np.cos(np.radians(5.0)))
#: The swept test's defaults (:func:`line_sweeps`), shared by the selector's ``sweep_*``
#: features and the fixed-parts slide veto so that both judge a line by the same test: a
#: quarter turn of revolute lines, half the part's extent along prismatic ones, the first 256
#: samples of the moving part.
SWEEP_ANGLE_DEG = 90.0
SWEEP_FRACTION = 0.5
SWEEP_POINTS = 256


@dataclass
class GNNPriors:
    """The GNN's raw outputs of one shape's sibling edges, before any consistency step.

    Attributes
    ----------
    probs : (E, K) float64
        Type probabilities over ``type_names`` as the type head gives them.
    type_names : tuple of str
        :data:`~kinmo.data.model.FINE_TYPES` or :data:`~kinmo.data.model.COARSE_TYPES`.
    axis_prob : (E, 10) float64 or None
        Softmax of the axis-candidate logits (:class:`kinmo.models.edge_gnn.EdgeHeads`).
    axis_dirs : (E, 10, 3) float64 or None
        The GNN's candidate directions (mesh frame = normalised frame orientation).
    turned : bool
        The outputs are the average of the object's four quarter turns about the vertical
        (an object without known part names, :func:`kinmo.inference.gnn.average_turns`): its
        facing is unknown, so the semantic direction prior is averaged over the same turns
        (:meth:`kinmo.refine.semantic_prior.SemanticPrior.probability`).
    """

    probs: np.ndarray
    type_names: tuple[str, ...]
    axis_prob: np.ndarray | None = None
    axis_dirs: np.ndarray | None = None
    turned: bool = False

    def orientation(self, k: int) -> tuple[float, float]:
        """``(P(H), P(V))`` of edge ``k`` among its moving fine types (0.5, 0.5 for coarse)."""
        if tuple(self.type_names) != FINE_TYPES:
            return 0.5, 0.5
        p = self.probs[k]
        h = sum(p[n] for n, t in enumerate(FINE_TYPES) if "_H" in t)
        v = sum(p[n] for n, t in enumerate(FINE_TYPES) if "_V" in t)
        s = h + v
        return (0.5, 0.5) if s <= 0 else (float(h / s), float(v / s))

    def pivot(self, k: int) -> tuple[float, float]:
        """``(P(C), P(S))`` of edge ``k`` among its revolute fine types (0.5, 0.5 for coarse)."""
        if tuple(self.type_names) != FINE_TYPES:
            return 0.5, 0.5
        p = self.probs[k]
        c = sum(p[n] for n, t in enumerate(FINE_TYPES) if t.startswith("R_") and t.endswith("_C"))
        s = sum(p[n] for n, t in enumerate(FINE_TYPES) if t.startswith("R_") and t.endswith("_S"))
        return (0.5, 0.5) if c + s <= 0 else (float(c / (c + s)), float(s / (c + s)))

    def motion(self, k: int) -> tuple[float, float]:
        """``(P(slide), P(turn))`` of edge ``k``: the mass of its ``P``/``P_*`` types and of its
        ``R``/``R_*`` types, fine or coarse (``PR`` types count for neither)."""
        p = self.probs[k]
        slide = sum(p[n] for n, t in enumerate(self.type_names) if _coarse_motion(t) == "P")
        turn = sum(p[n] for n, t in enumerate(self.type_names) if _coarse_motion(t) == "R")
        return float(slide), float(turn)

    def direction_prior(self, k: int, directions: np.ndarray) -> np.ndarray:
        """``(C,)``: the GNN's axis-candidate mass within 5° of each line (0.1 each without)."""
        d = np.asarray(directions, dtype=np.float64).reshape(-1, 3)
        if self.axis_prob is None or self.axis_dirs is None:
            return np.full(d.shape[0], 0.1)
        g = self.axis_dirs[k] / np.maximum(np.linalg.norm(self.axis_dirs[k], axis=1,
                                                          keepdims=True), 1e-12)
        par = np.abs(d @ g.T) >= _PARALLEL_COS  # (C, 10)
        return (par * self.axis_prob[k][None, :]).sum(axis=1)


def _coarse_motion(type_name: str) -> str:
    return type_name.split("_")[0]


def edge_candidates(
    graph: PartGraph,
    moving: int,
    reference: int,
    motion_type: str,
    gnn_direction: np.ndarray,
    gnn_origin: np.ndarray,
    *,
    interaction_radius: float = 0.1,
    merge_angle_deg: float = 2.0,
    merge_distance: float = 0.02,
    frames: tuple[str, ...] = ("moving", "reference", "shape"),
    with_gnn: bool = True,
) -> tuple[Candidates, tuple[str, ...]]:
    """Candidate lines of every orientation for one moving edge.

    Parameters
    ----------
    graph : PartGraph
    moving, reference : int
        Node indices of the edge ``(moving, reference)``.
    motion_type : str
        Predicted fine or coarse type; only its coarse motion (``R``, ``P``, ``PR``) is used.
    gnn_direction, gnn_origin : (3,) float
        The GNN's axis (mesh frame); its line is the last candidate (kind ``"gnn"``).
    interaction_radius : float
        As :func:`kinmo.refine.candidates.candidate_axes`.
    merge_angle_deg, merge_distance : float
        Lines within this angle and distance (fraction of the moving OBB's diagonal) of an
        earlier line are merged into it.
    frames : tuple of {"moving", "reference", "shape"}
        Boxes of the moving part whose lines are candidates (in this order).
    with_gnn : bool
        Append the GNN's own line.

    Returns
    -------
    (Candidates, tuple of str)
        Candidates for the coarse motion, and the frame of each (``"gnn"`` for the GNN's).

    Raises
    ------
    ValueError
        A type without an axis, malformed geometry.
    """
    motion = _coarse_motion(str(motion_type))
    diag = max(2.0 * float(np.linalg.norm(graph.obb_half_extents[moving])), 1e-12)
    cands: Candidates | None = None
    frame_of: list[str] = []
    for frame in dict.fromkeys(frames):
        if frame == "moving":
            box = (graph.obb_center[moving], graph.obb_axes[moving], graph.obb_half_extents[moving])
        else:
            axes = graph.obb_axes[reference] if frame == "reference" else np.eye(3)
            box = frame_box(graph.points[moving], axes)
        c = candidate_axes(box, motion, graph.points[moving], graph.points[reference],
                           interaction_radius=interaction_radius)
        before = 0 if cands is None else len(cands)
        cands = c if cands is None else merge_candidates(
            cands, c, angle_deg=merge_angle_deg, distance=merge_distance * diag)
        frame_of += [frame] * (len(cands) - before)
    if cands is None:
        raise ValueError("frames: expected at least one of moving, reference, shape")
    if with_gnn:
        g = np.asarray(gnn_direction, dtype=np.float64)
        if not (np.all(np.isfinite(g)) and np.linalg.norm(g) > 0):
            g = np.array([0.0, 1.0, 0.0])
        cands = Candidates(np.vstack([cands.origins, np.asarray(gnn_origin, float)[None]]),
                           np.vstack([cands.directions, canonical_direction(g)[None]]),
                           (*cands.kinds, "gnn"), cands.motion_type)
        frame_of.append("gnn")
    return cands, tuple(frame_of)


def rotate_about(points: np.ndarray, origins: np.ndarray, directions: np.ndarray,
                 angles: np.ndarray) -> np.ndarray:
    """Rotate points about lines (Rodrigues), batched.

    Parameters
    ----------
    points : (P, 3) float64
    origins, directions : (M, 3) float64
        Lines (directions unit).
    angles : (M,) float64
        Radians, right-handed about ``directions``.

    Returns
    -------
    (M, P, 3) float64
    """
    p = points[None, :, :] - origins[:, None, :]
    k = directions[:, None, :]
    c = np.cos(angles)[:, None, None]
    s = np.sin(angles)[:, None, None]
    kxp = np.cross(np.broadcast_to(k, p.shape), p)
    kdp = np.sum(k * p, axis=2, keepdims=True)
    return p * c + kxp * s + k * kdp * (1 - c) + origins[:, None, :]


def _subtree(graph: PartGraph, node: int) -> np.ndarray:
    parent = np.asarray(graph.parent)
    inside = np.zeros(graph.n_nodes, dtype=bool)
    inside[node] = True
    changed = True
    while changed:
        new = inside | ((parent >= 0) & inside[np.maximum(parent, 0)])
        changed = bool((new != inside).any())
        inside = new
    return inside


def fixed_leaves(graph: PartGraph, moving_nodes) -> np.ndarray:
    """``(L,) int64``: the graph's leaves outside the subtree of every node of
    ``moving_nodes`` (graph node indices: the parts predicted to move), sorted."""
    out = np.zeros(graph.n_nodes, dtype=bool)
    for n in set(int(x) for x in moving_nodes):
        out |= _subtree(graph, n)
    return np.flatnonzero(np.asarray(graph.is_leaf, dtype=bool) & ~out).astype(np.int64)


def _static_points(graph: PartGraph, moving: int, cap: int, rng: np.random.Generator) -> np.ndarray:
    leaves = np.asarray(graph.is_leaf, dtype=bool) & ~_subtree(graph, moving)
    pts = np.asarray(graph.points)[leaves].reshape(-1, 3)
    if pts.shape[0] > cap:
        pts = pts[rng.choice(pts.shape[0], cap, replace=False)]
    return pts


@dataclass
class ShapeMeshes:
    """The leaf meshes of a part graph (mesh frame), for the swept-collision terms.

    Attributes
    ----------
    leaves : dict of int to (vertices (V, 3) float64, faces (F, 3) int64)
        By graph node index (leaves only).

    One object serves every edge of one shape, and :meth:`sweep` remembers its results: the
    edges of one moving part (one per sibling it may move against) share most candidate lines
    (its OBB edges and centre lines), and their swept collisions do not depend on the
    reference part. :meth:`obstacle` keeps one prepared obstacle (parry BVH) per set of
    static leaves, for the selector's sweeps and the range sweeps
    (:func:`kinmo.ranges.predict_ranges`) of the same shape alike.
    """

    leaves: dict[int, tuple[np.ndarray, np.ndarray]]
    _sweeps: dict = field(default_factory=dict, repr=False, compare=False)
    _obstacles: dict = field(default_factory=dict, repr=False, compare=False)

    def sweep(self, moving: int, static_leaves: np.ndarray, points: np.ndarray, origins: np.ndarray,
              directions: np.ndarray, kinds: np.ndarray, ranges: np.ndarray,
              n_steps: int) -> tuple[np.ndarray, np.ndarray]:
        """:func:`kinmo.geometry.sweep_collisions` of ``moving``'s ``points`` against the union
        of ``static_leaves``, each line computed once per shape (same results: every line's
        sweep is independent of the others in a call).

        Parameters
        ----------
        moving : int
            Graph node of the moving part (with ``static_leaves`` and ``points``: the cache
            key of the part).
        static_leaves : (L,) int
        points : (N, 3) float64
        origins, directions : (C, 3) float64
        kinds : (C,) int64
        ranges : (C,) float64
        n_steps : int

        Returns
        -------
        free, colliding : (C, 2) float64
            As :func:`kinmo.geometry.sweep_collisions`.
        """
        part = (int(moving), np.asarray(static_leaves, np.int64).tobytes(),
                np.ascontiguousarray(points, np.float64).tobytes())
        keys = [(part, origins[k].tobytes(), directions[k].tobytes(), int(kinds[k]),
                 float(ranges[k]), int(n_steps)) for k in range(len(origins))]
        todo = [k for k, key in enumerate(keys) if key not in self._sweeps]
        if todo:
            t = np.asarray(todo)
            free, coll = self.obstacle(static_leaves).sweep(
                points, np.ascontiguousarray(origins[t]), np.ascontiguousarray(directions[t]),
                kinds[t], ranges[t], n_steps=n_steps)
            for n, k in enumerate(todo):
                self._sweeps[keys[k]] = (free[n], coll[n])
        got = [self._sweeps[key] for key in keys]
        return (np.array([g[0] for g in got]).reshape(-1, 2),
                np.array([g[1] for g in got]).reshape(-1, 2))

    def obstacle(self, nodes) -> SweepObstacle:
        """The union of the leaves ``nodes`` ``(L,) int`` (:meth:`union`, in that order) as a
        swept-collision obstacle, prepared once per shape and node list: its BVH is built on
        the first call and shared by every later one (same results:
        :class:`~kinmo.geometry.SweepObstacle`)."""
        key = np.asarray(nodes, dtype=np.int64).tobytes()
        if key not in self._obstacles:
            self._obstacles[key] = SweepObstacle(*self.union(nodes))
        return self._obstacles[key]

    def union(self, nodes) -> tuple[np.ndarray, np.ndarray]:
        """One mesh of the given leaf nodes (faces re-indexed); empty arrays for none."""
        vs, fs, off = [], [], 0
        for n in nodes:
            m = self.leaves.get(int(n))
            if m is None:
                continue
            vs.append(m[0])
            fs.append(m[1] + off)
            off += m[0].shape[0]
        if not vs:
            return np.zeros((0, 3)), np.zeros((0, 3), np.int64)
        return np.vstack(vs), np.vstack(fs).astype(np.int64)


def shape_meshes(graph: PartGraph) -> ShapeMeshes | None:
    """Load the leaf meshes of ``graph`` from its source folder (``graph.meta["source"]``).

    Every OBJ is read once with the Rust loader (:func:`kinmo.geometry.load_objs`).

    Returns
    -------
    ShapeMeshes or None
        None when the graph has no readable source folder or its parts do not match the
        graph's node ids (the callers then fall back to the point terms).
    """

    src = graph.meta.get("source") if isinstance(graph.meta, dict) else None
    if not src or not Path(src).is_dir():
        return None
    try:
        from kinmo.data.build import load_shape_meshes
        from kinmo.data.readers import read_shape

        shape = read_shape(src)
        nodes = shape.hierarchy.nodes
        objs = list(dict.fromkeys(o for k in np.flatnonzero(graph.is_leaf)
                                  for o in nodes[int(graph.node_ids[k])].objs))
        meshes = load_shape_meshes([shape.mesh_path(o) for o in objs])
        return graph_meshes(graph, shape.hierarchy, dict(zip(objs, meshes)))
    except (KinmoError, OSError, ValueError, KeyError):
        return None


def graph_meshes(graph: PartGraph, hierarchy, named) -> ShapeMeshes:
    """The leaf meshes of ``graph`` from meshes already read (no file access).

    Parameters
    ----------
    graph : PartGraph
    hierarchy : PartHierarchy
        The shape's hierarchy (``graph.node_ids`` are its node ids).
    named : mapping of str to (vertices (V, 3) float64, faces (F, 3) int64)
        Mesh name -> mesh, e.g. :func:`kinmo.data.build.load_named_meshes`.

    Raises
    ------
    KeyError
        A leaf names a mesh missing from ``named``.
    """
    nodes = hierarchy.nodes
    out: dict[int, tuple[np.ndarray, np.ndarray]] = {}
    for k in np.flatnonzero(graph.is_leaf):
        objs = nodes[int(graph.node_ids[k])].objs
        part = ShapeMeshes({n: (np.asarray(named[o][0], np.float64), np.asarray(named[o][1], np.int64))
                            for n, o in enumerate(objs)})
        out[int(k)] = part.union(range(len(objs)))
    return ShapeMeshes(out)


def _point_line(points: np.ndarray, origins: np.ndarray, directions: np.ndarray) -> np.ndarray:
    """``(C,)`` minimum distance from each line to the points (``directions`` unit).

    ``|w x d|`` with the cross product written out and one square root per line: the same
    arithmetic as ``np.linalg.norm(np.cross(w, d), axis=2).min(axis=1)``, bit for bit (the
    square root is monotonic), about 3x faster (issue 24)."""
    if points.shape[0] == 0:
        return np.full(origins.shape[0], np.inf)
    w = points[None, :, :] - origins[:, None, :]
    w0, w1, w2 = w[..., 0], w[..., 1], w[..., 2]
    d = directions[:, None, :]
    d0, d1, d2 = d[..., 0], d[..., 1], d[..., 2]
    c0 = w1 * d2 - w2 * d1
    c1 = w2 * d0 - w0 * d2
    c2 = w0 * d1 - w1 * d0
    return np.sqrt((c0 * c0 + c1 * c1 + c2 * c2).min(axis=1))


def line_sweeps(graph: PartGraph, moving: int, cands: Candidates, meshes: ShapeMeshes,
                static_leaves: np.ndarray, *, sweep_angle_deg: float = SWEEP_ANGLE_DEG,
                sweep_fraction: float = SWEEP_FRACTION, sweep_points: int = SWEEP_POINTS
                ) -> tuple[np.ndarray, np.ndarray]:
    """The swept test of every candidate line of ``moving`` against ``static_leaves``: the
    ``sweep_*`` terms of :func:`candidate_features` (which sweeps against every leaf outside
    ``moving``'s subtree) and of the fixed-parts slide veto
    (:func:`kinmo.refine.edge.fixed_parts_slide_veto`, against the parts predicted not to move).

    Parameters
    ----------
    graph : PartGraph
    moving : int
        Graph node of the moving part; its first ``sweep_points`` samples are swept.
    cands : Candidates
        Its candidate lines (mesh frame); revolute ones turn ``sweep_angle_deg`` degrees,
        prismatic ones (``cands.motion == "P"``) slide ``sweep_fraction`` of the part's extent
        along the line.
    meshes : ShapeMeshes
    static_leaves : (L,) int
        Graph leaves that stay put (the obstacle).

    Returns
    -------
    free, colliding : (C, 2) float64
        As :func:`kinmo.geometry.sweep_collisions`, for the + and - direction of each line.
    """
    c = len(cands)
    o, d = np.ascontiguousarray(cands.origins), np.ascontiguousarray(cands.directions)
    mp = np.asarray(graph.points[moving], dtype=np.float64)[:sweep_points]
    if cands.motion != "P":
        kinds = np.zeros(c, np.int64)
        ranges = np.full(c, np.radians(sweep_angle_deg))
    else:
        kinds = np.ones(c, np.int64)
        ranges = np.maximum(sweep_fraction * np.ptp(mp @ d.T, axis=0), 1e-9)
    return meshes.sweep(moving, static_leaves, mp, o, d, kinds, ranges, n_steps=8)


def freer_sign(free: np.ndarray, colliding: np.ndarray) -> np.ndarray:
    """``(C,) int64`` ±1: the freer direction of each swept line (:func:`line_sweeps`' ``(C, 2)``
    free and colliding fractions, + then -): the larger free fraction, then the smaller
    colliding one; +1 on ties."""
    better = np.where(free[:, 1] != free[:, 0], free[:, 1] > free[:, 0], colliding[:, 1] < colliding[:, 0])
    return np.where(better, -1, 1).astype(np.int64)


def candidate_features(
    graph: PartGraph,
    moving: int,
    reference: int,
    edge: int,
    cands: Candidates,
    frames: tuple[str, ...],
    priors: GNNPriors,
    gnn_direction: np.ndarray,
    gnn_origin: np.ndarray,
    feasibility: np.ndarray | None = None,
    meshes: ShapeMeshes | None = None,
    *,
    sweep_angle_deg: float = SWEEP_ANGLE_DEG,
    sweep_fraction: float = SWEEP_FRACTION,
    sweep_points: int = SWEEP_POINTS,
    angles_deg: tuple[float, ...] = (30.0, 60.0),
    fractions: tuple[float, ...] = (0.25, 0.5),
    static_cap: int = 2048,
    seed: int = 0,
    semantic: SemanticPrior | None = None,
    exclude: str | None = None,
    proxy: bool = True,
) -> tuple[np.ndarray, np.ndarray]:
    """Per-candidate features (:data:`FEATURES`) and the less-colliding sign of each line.

    Parameters
    ----------
    graph : PartGraph
    moving, reference, edge : int
        The edge's node indices and its row in ``graph.sibling_edges`` (for the priors).
    cands : Candidates
        From :func:`edge_candidates`; ``frames`` the frame of each.
    priors : GNNPriors
    gnn_direction, gnn_origin : (3,) float
        The GNN's axis (mesh frame).
    feasibility : (C,) float, optional
        The axis-selection network's feasibility of each line (0.5 each without).
    meshes : ShapeMeshes, optional
        The shape's leaf meshes (:func:`shape_meshes`) for the swept-collision and mesh
        attachment terms; without them those terms are neutral constants.
    sweep_angle_deg, sweep_fraction : float
        Range of the sweep: rotation (degrees) of revolute lines, translation (fraction of the
        moving part's extent along the line) of prismatic ones. 90° (a door opened square):
        on the out-of-fold groups of the 132 training objects, over five fold seeds, the
        per-joint angle of the chosen line is 8.7° with 90° and 120° against 9.3° with 60°
        (docs/results/table1_four_settings.md, fourth round).
    sweep_points : int
        Moving-part samples swept (the first ``sweep_points`` of the graph's).
    angles_deg, fractions : tuple of float
        Amounts of the collision proxy: rotations (degrees) of revolute motions, translations
        (fraction of the moving part's extent along the line) of prismatic ones.
    static_cap : int
        At most this many static surface samples (random subset, ``seed``).
    seed : int
    semantic : SemanticPrior, optional
        Category / part-name prior on the direction (:mod:`kinmo.refine.semantic_prior`);
        without it ``sem_prior`` is 1/3 for every line (drops out of the per-edge softmax).
    exclude : str, optional
        Shape id left out of the semantic prior (out-of-fold fits on training objects).
    proxy : bool
        Compute the point proxy of the collision (``collide_*``, zeros otherwise). Skipped
        only with ``meshes`` (the sweep then gives the sign); a ranker without ``collide_*``
        features does not need it.

    Returns
    -------
    features : (C, len(FEATURES)) float64
    sign : (C,) int64
        ±1, the freer direction of motion: the sweep's (larger free fraction, then smaller
        colliding fraction) with meshes, the point proxy's otherwise (+1 on ties).
    """
    rng = np.random.default_rng([seed, moving, reference])
    c = len(cands)
    x = np.zeros((c, len(FEATURES)))
    o, d = cands.origins, cands.directions
    half = np.asarray(graph.obb_half_extents[moving], dtype=np.float64)
    centre = np.asarray(graph.obb_center[moving], dtype=np.float64)
    axes = np.asarray(graph.obb_axes[moving], dtype=np.float64)
    diag = max(2.0 * float(np.linalg.norm(half)), 1e-9)
    revolute = cands.motion != "P"
    g = np.asarray(gnn_direction, dtype=np.float64)
    g = g / max(float(np.linalg.norm(g)), 1e-12)

    dp = priors.direction_prior(edge, d)
    x[:, _F["dir_prior"]] = dp
    x[:, _F["log_dir_prior"]] = np.log(dp + 1e-3)
    x[:, _F["cos_gnn"]] = np.abs(d @ g)
    ph, pv = priors.orientation(edge)
    vert = np.abs(d[:, 1]) > VERTICAL_COS
    x[:, _F["orient_prior"]] = np.where(vert, pv, ph)
    if revolute:
        pc, ps = priors.pivot(edge)
        central = pivots_are_central(o, d, centre, axes, half)
        x[:, _F["pivot_prior"]] = np.where(central, pc, ps)
        dist = np.linalg.norm(np.cross(np.asarray(gnn_origin, float) - o, d), axis=1) / diag
        x[:, _F["d_gnn"]] = np.minimum(dist, 2.0)
        x[:, _F["pos_prior"]] = np.exp(-dist / 0.25)
        ref = np.asarray(graph.points[reference], dtype=np.float64)
        x[:, _F["attach_ref"]] = np.minimum(_point_line(ref, o, d) / diag, 2.0)
    else:
        x[:, _F["pivot_prior"]] = 0.5
        x[:, _F["pos_prior"]] = 1.0
    static = _static_points(graph, moving, static_cap, rng)
    if revolute:
        x[:, _F["attach_any"]] = np.minimum(_point_line(static, o, d) / diag, 2.0)

    # collision proxy: static samples newly inside the moving part's (slightly shrunk) box
    sign = np.ones(c, dtype=np.int64)
    if static.shape[0] and (proxy or meshes is None):
        shrink = np.maximum(half * 0.9, half - 0.02 * diag)
        local0 = (static - centre) @ axes.T
        rest = np.all(np.abs(local0) < shrink, axis=1)
        x[:, _F["collide_rest"]] = rest.mean()
        amounts = np.radians(angles_deg) if revolute else np.asarray(fractions)
        a_n = len(amounts)
        oo = np.repeat(o, 2 * a_n, axis=0)
        dd = np.repeat(d, 2 * a_n, axis=0)
        sg = np.tile(np.repeat([1.0, -1.0], a_n), c)
        am = np.tile(np.tile(amounts, 2), c)
        if revolute:
            # inverse motion applied to the static samples: rotate by -s*a
            moved = rotate_about(static, oo, dd, -sg * am)
        else:
            ext = np.ptp(np.asarray(graph.points[moving]) @ d.T, axis=0)  # (C,)
            shift = (np.repeat(ext, 2 * a_n) * sg * am)[:, None] * dd
            moved = static[None, :, :] - shift[:, None, :]
        local = (moved - centre) @ axes.T
        inside = np.all(np.abs(local) < shrink, axis=2) & ~rest[None, :]
        frac = inside.mean(axis=1).reshape(c, 2, a_n).mean(axis=2)  # (C, 2)
        x[:, _F["collide_min"]] = frac.min(axis=1)
        x[:, _F["collide_max"]] = frac.max(axis=1)
        sign = np.where(frac[:, 1] < frac[:, 0], -1, 1).astype(np.int64)
    x[:, _F["sweep_free_min"]] = x[:, _F["sweep_free_max"]] = 1.0
    x[:, _F["attach_mesh"]] = x[:, _F["attach_ref"]]
    if meshes is not None:
        static_leaves = np.flatnonzero(np.asarray(graph.is_leaf, bool) & ~_subtree(graph, moving))
        free, coll = line_sweeps(graph, moving, cands, meshes, static_leaves,
                                 sweep_angle_deg=sweep_angle_deg, sweep_fraction=sweep_fraction,
                                 sweep_points=sweep_points)
        x[:, _F["sweep_free_min"]] = free.min(axis=1)
        x[:, _F["sweep_free_max"]] = free.max(axis=1)
        x[:, _F["sweep_coll_min"]] = coll.min(axis=1)
        x[:, _F["sweep_coll_max"]] = coll.max(axis=1)
        sign = freer_sign(free, coll)
        rv, rf = meshes.union(np.flatnonzero(np.asarray(graph.is_leaf, bool) & _subtree(graph, reference)))
        if revolute and rf.shape[0]:
            x[:, _F["attach_mesh"]] = np.minimum(
                line_mesh_distance(np.ascontiguousarray(o), np.ascontiguousarray(d), rv, rf) / diag, 2.0)
    if revolute:  # hinges lie away from the moving part's own children (handles, knobs)
        kids = np.flatnonzero(_subtree(graph, moving))
        kids = kids[kids != moving]
        if kids.size:
            pc = np.vstack([np.asarray(graph.points[k], dtype=np.float64) for k in kids]).mean(0)
            x[:, _F["d_child"]] = np.minimum(_point_line(pc[None], o, d) / diag, 2.0)
    x[:, _F["feasibility"]] = 0.5 if feasibility is None else np.asarray(feasibility, float)
    for kind in ("edge", "center", "interaction", "axis", "gnn"):
        x[:, _F[f"kind_{kind}"]] = [k == kind for k in cands.kinds]
    for frame in ("moving", "reference", "shape"):
        x[:, _F[f"frame_{frame}"]] = [f == frame for f in frames]
    x[:, _F["d_child_edge"]] = x[:, _F["d_child"]] * x[:, _F["kind_edge"]]
    x[:, _F["shape_aligned"]] = np.abs(d).max(axis=1) >= _PARALLEL_COS
    ra = np.asarray(graph.obb_axes[reference], dtype=np.float64)
    x[:, _F["ref_aligned"]] = np.abs(d @ ra.T).max(axis=1) >= _PARALLEL_COS
    sp = (np.full(c, 1.0 / 3.0) if semantic is None else
          semantic.probability(motion_of(cands.motion), graph.category,
                               graph.node_names[moving], graph.node_names[reference], d, exclude,
                               turns=priors.turned))
    x[:, _F["sem_prior"]] = sp
    x[:, _F["log_sem_prior"]] = np.log(sp + 0.01)
    _part_shape_features(x, centre, axes, half, np.asarray(graph.obb_center[reference], np.float64),
                         d, revolute, central if revolute else None, float(graph.scale))
    return x, sign


def _part_shape_features(x: np.ndarray, centre: np.ndarray, axes: np.ndarray, half: np.ndarray,
                         ref_centre: np.ndarray, d: np.ndarray, revolute: bool,
                         central: np.ndarray | None, scale: float) -> None:
    """Fill the ``part_shape`` features of ``x`` in place: how the moving part's own OBB sits
    on each candidate line, cues that hold in any facing and up axis (kinmo extension, issue 34).

    - ``ext_along``: the OBB's half-width along the line over its largest half extent (1: the
      line runs along the part's longest side, as a door's hinge; small: across it).
    - ``thin_*``: ``|d . a_thin|`` times how distinctly thin the part is
      (``1 - h_thin / h_mid``), ``a_thin`` the OBB axis of the smallest extent: knobs, wheels
      and caps turn about it through their centre, buttons slide along it, and doors and lids
      never turn about it. Split by motion and, for revolute lines, by a central or an edge
      pivot (:func:`pivots_are_central`), so that a linear ranker weighs each case alone.
    - ``offset_*``: ``|d . u|``, ``u`` the unit vector from the reference part's OBB centre to
      the moving part's: drawers and buttons move along it, knobs turn about it, doors and
      lids hinge across it. Split as ``thin_*``.

    Parameters
    ----------
    x : (C, len(FEATURES)) float64
    centre : (3,) float64
        The moving part's OBB centre (mesh frame).
    axes : (3, 3) float64
        Its OBB axes (rows).
    half : (3,) float64
        Its OBB half extents.
    ref_centre : (3,) float64
        The reference part's OBB centre.
    d : (C, 3) float64
        Candidate directions (normalised here).
    revolute : bool
    central : (C,) bool or None
        Central pivots of the lines (revolute only).
    scale : float
        The shape's diagonal (an offset below ``1e-9 * scale`` counts as none).
    """
    d = d / np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-12)
    cos_obb = np.abs(d @ axes.T)  # (C, 3)
    x[:, _F["ext_along"]] = (cos_obb @ half) / max(float(half.max()), 1e-12)
    order = np.argsort(half)
    thin = cos_obb[:, order[0]] * (1.0 - half[order[0]] / max(float(half[order[1]]), 1e-12))
    off = centre - ref_centre
    n = float(np.linalg.norm(off))
    offset = np.abs(d @ (off / n)) if n > 1e-9 * max(scale, 1e-12) else np.zeros(len(d))
    if revolute:
        c = np.asarray(central, bool)
        x[:, _F["thin_r_center"]] = thin * c
        x[:, _F["thin_r_edge"]] = thin * ~c
        x[:, _F["offset_r_center"]] = offset * c
        x[:, _F["offset_r_edge"]] = offset * ~c
    else:
        x[:, _F["thin_p"]] = thin
        x[:, _F["offset_p"]] = offset


def candidate_labels(
    cands: Candidates,
    true_origin: np.ndarray,
    true_direction: np.ndarray,
    scale: float,
    revolute: bool,
    *,
    angle_deg: float = 5.0,
    distance: float = 0.05,
) -> np.ndarray:
    """``(C,) bool``: the line is within ``angle_deg`` and (revolute) ``distance * scale``.

    ``scale`` is the shape's bounding-box diagonal (:attr:`PartGraph.scale`), the evaluation's
    normaliser; the distance is the line-to-line distance
    (:func:`kinmo.metrics.axis.line_distance`).
    """

    t = np.asarray(true_direction, dtype=np.float64)
    t = t / np.linalg.norm(t)
    ok = np.abs(cands.directions @ t) >= np.cos(np.radians(angle_deg)) - 1e-12
    if revolute and len(cands):
        dist = np.atleast_1d(line_distance(cands.origins, cands.directions,
                                           np.broadcast_to(true_origin, cands.origins.shape),
                                           np.broadcast_to(t, cands.origins.shape)))
        ok &= dist <= distance * scale
    return ok
