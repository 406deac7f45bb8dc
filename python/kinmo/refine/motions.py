"""Candidate motions and the inputs of the axis-selection network (Liu et al. 2023, Sec. 3.3).

A *candidate motion* moves the moving part about (revolute), along (prismatic) or about and
along (both, ``PR``) a candidate axis line by a fixed amount. A line has two directions and a
motion is feasible in at most one of them for most joints (a door opens outwards, a drawer
slides out), so every line is tried in both directions (``sign = ±1``): the feasibility of a
line is that of its better direction, which also fixes the sign of the refined axis.

Amounts at inference, where the joint limits are unknown (:class:`MotionAmounts`):

- rotation: ``angles_deg`` (default 60°, a door half-open);
- translation: ``translation_fraction`` of the moving part's OBB extent along the direction
  (default 0.5: a drawer pulled out by half its depth).

The network sees one point cloud per motion state: ``N`` points, half sampled from the moving
part and half static: from the reference part and, optionally, from the rest of the shape
(:func:`shape_context`; with replacement when a part has fewer samples), with a 4th channel
flagging moving points (1) and static points (0). Both states are expressed in one *pair
frame*: translated by the centre of the axis-aligned bounding box of the rest state and
divided by its diagonal, so the network sees the motion's size relative to the parts; the
orientation (y-up) is kept.

Frames and units: inputs in the mesh frame (mesh units); network inputs in the pair frame.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from kinmo.geometry import apply_motions
from kinmo.refine.candidates import Candidates, obb_of

__all__ = [
    "CandidateMotions",
    "MotionAmounts",
    "PairCloud",
    "candidate_motions",
    "edge_cloud",
    "extent_along",
    "network_inputs",
    "pair_cloud",
    "shape_context",
]


@dataclass(frozen=True)
class MotionAmounts:
    """How far candidate motions move the part at inference.

    Attributes
    ----------
    angles_deg : tuple of float
        Rotation angles tried per line and direction (degrees, > 0); feasibility is averaged
        over them.
    translation_fraction : float
        Translation as a fraction of the moving part's OBB extent along the direction (> 0).
    """

    angles_deg: tuple[float, ...] = (60.0,)
    translation_fraction: float = 0.5

    def __post_init__(self) -> None:
        if not self.angles_deg or any(not (a > 0) for a in self.angles_deg):
            raise ValueError(f"angles_deg: expected positive angles, got {self.angles_deg}")
        if not self.translation_fraction > 0:
            raise ValueError(
                f"translation_fraction: expected > 0, got {self.translation_fraction}"
            )


@dataclass(frozen=True)
class CandidateMotions:
    """``M`` rigid motions generated from ``C`` candidate lines.

    Attributes
    ----------
    origins, directions : (M, 3) float64
        Axis of each motion (directions unit, signed).
    angles : (M,) float64
        Rotation about the axis, radians (right-hand rule); 0 for prismatic motions.
    translations : (M,) float64
        Translation along the signed direction, mesh units; 0 for revolute motions.
    line : (M,) int64
        Index of the candidate line each motion comes from.
    sign : (M,) int64
        +1 or -1: the direction is ``sign * candidates.directions[line]``.
    """

    origins: np.ndarray
    directions: np.ndarray
    angles: np.ndarray
    translations: np.ndarray
    line: np.ndarray
    sign: np.ndarray

    def __len__(self) -> int:
        return int(self.origins.shape[0])


def extent_along(moving_obb, directions: np.ndarray) -> np.ndarray:
    """Full extent of an OBB along unit directions, ``2 * sum_k |d . a_k| h_k``.

    Parameters
    ----------
    moving_obb : OBB or (center, axes, half_extents)
    directions : (M, 3) float64
        Unit directions.

    Returns
    -------
    (M,) float64
        Mesh units.
    """
    box = obb_of(moving_obb)
    d = np.asarray(directions, dtype=np.float64).reshape(-1, 3)
    return 2.0 * (np.abs(d @ box.axes.T) @ box.half_extents)


def candidate_motions(
    candidates: Candidates, moving_obb, amounts: MotionAmounts | None = None
) -> CandidateMotions:
    """Both directions of every candidate line, moved by the inference amounts.

    Parameters
    ----------
    candidates : Candidates
        From :func:`kinmo.refine.candidates.candidate_axes`.
    moving_obb : OBB or (center, axes, half_extents)
        The moving part's OBB (gives the translation amounts).
    amounts : MotionAmounts, optional

    Returns
    -------
    CandidateMotions
        ``M = C * 2 * len(angles_deg)`` for revolute and ``PR`` types, ``C * 2`` for
        prismatic, ordered by line, then sign (+1 first), then angle.
    """
    amounts = amounts or MotionAmounts()
    motion = candidates.motion
    n_ang = len(amounts.angles_deg) if motion in ("R", "PR") else 1
    c = len(candidates)
    line = np.repeat(np.arange(c), 2 * n_ang)
    sign = np.tile(np.repeat([1, -1], n_ang), c)
    d = candidates.directions[line] * sign[:, None]
    o = candidates.origins[line]
    if motion in ("R", "PR"):
        ang = np.tile(np.radians(np.asarray(amounts.angles_deg, dtype=np.float64)), 2 * c)
    else:
        ang = np.zeros(len(line))
    if motion in ("P", "PR"):
        tr = amounts.translation_fraction * extent_along(moving_obb, d)
    else:
        tr = np.zeros(len(line))
    return CandidateMotions(o, d, ang, tr, line.astype(np.int64), sign.astype(np.int64))


@dataclass(frozen=True)
class PairCloud:
    """Points of a moving and a reference part, sampled for the network.

    Attributes
    ----------
    points : (N, 3) float64
        Mesh frame; the first ``n_moving`` rows belong to the moving part.
    n_moving : int
    center : (3,) float64
        Centre of the axis-aligned bounding box of ``points`` (the pair frame's origin).
    scale : float
        Diagonal of that box (the pair frame's unit), > 0.
    """

    points: np.ndarray
    n_moving: int
    center: np.ndarray
    scale: float

    @property
    def flags(self) -> np.ndarray:
        """``(N,) float32``: 1 for moving points, 0 for reference points."""
        f = np.zeros(self.points.shape[0], dtype=np.float32)
        f[: self.n_moving] = 1.0
        return f


def _take(points: np.ndarray, n: int, rng: np.random.Generator, name: str) -> np.ndarray:
    p = np.asarray(points, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 3 or p.shape[0] == 0:
        raise ValueError(f"{name}: expected a non-empty (N, 3) array, got shape {p.shape}")
    if not np.all(np.isfinite(p)):
        raise ValueError(f"{name}: non-finite points")
    idx = rng.choice(p.shape[0], size=n, replace=p.shape[0] < n)
    return p[idx]


def shape_context(shape_points: np.ndarray, moving_points: np.ndarray) -> np.ndarray:
    """Samples of the rest of the shape: ``shape_points`` without those on the moving part.

    Parameters
    ----------
    shape_points : (Ns, 3) float
        Area-uniform samples of the whole shape (e.g. ``PartGraph.points[0]``, the root).
    moving_points : (Na, 3) float
        Samples of the moving part.

    Returns
    -------
    (Nc, 3) float64
        The shape points farther from every moving point than three times the median spacing of
        the moving samples (points of parts touching the moving part within that distance go
        too). May be empty.
    """
    from scipy.spatial import cKDTree

    s = np.asarray(shape_points, dtype=np.float64).reshape(-1, 3)
    m = np.asarray(moving_points, dtype=np.float64).reshape(-1, 3)
    if len(s) == 0 or len(m) == 0:
        return s
    tree = cKDTree(m)
    spacing = float(np.median(tree.query(m, k=2)[0][:, 1])) if len(m) > 1 else 0.0
    d, _ = tree.query(s)
    return s[d > 3.0 * spacing]  # P(a surface point is farther) ~ 2^-9 for uniform samples


def _near_box(p: np.ndarray, lo: np.ndarray, hi: np.ndarray, reach: float, least: int = 8
              ) -> np.ndarray:
    """Points within ``reach`` of the box ``[lo, hi]``, or the ``least`` nearest ones."""
    p = p.reshape(-1, 3)
    d = np.linalg.norm(np.maximum(0.0, np.maximum(lo - p, p - hi)), axis=1)
    keep = d <= reach
    if keep.sum() >= least or len(p) <= least:
        return p[keep] if keep.sum() >= least else p
    return p[np.argsort(d, kind="stable")[:least]]


def pair_cloud(
    moving_points: np.ndarray,
    reference_points: np.ndarray,
    n_points: int,
    rng: np.random.Generator | int = 0,
    context_points: np.ndarray | None = None,
    context_fraction: float = 0.25,
    crop: float | None = None,
) -> PairCloud:
    """Sample ``n_points`` network input points from a moving and a reference part.

    Parameters
    ----------
    moving_points, reference_points : (Na, 3), (Nb, 3) float
        Surface samples (e.g. ``PartGraph.points[i]``, mesh frame).
    n_points : int
        ``N`` >= 2; ``N // 2`` moving points (rounded up), the rest static points.
    rng : numpy Generator or int
        Randomness of the subsampling (an int seeds a new generator).
    context_points : (Nc, 3) float, optional
        Samples of the rest of the shape (:func:`shape_context`): the paper's network sees
        the whole object, so that a motion sweeping through a neighbouring part looks
        infeasible. When given (and not empty), ``round(context_fraction * N)`` of the static
        points come from it, the others from the reference part.
    context_fraction : float
        In ``[0, 0.5)``.
    crop : float or None
        Keep only static points within ``crop`` times the moving part's size (the diagonal of
        its samples' bounding box) of that box, so that small parts (a knob on a door) are
        seen at a scale where their motion shows; when fewer than 8 are that close, the 8
        nearest are kept. None: no crop.

    Returns
    -------
    PairCloud
        Moving points first, then reference points, then context points (all static ones
        flagged 0).
    """
    if n_points < 2:
        raise ValueError(f"n_points: expected >= 2, got {n_points}")
    if not 0.0 <= context_fraction < 0.5:
        raise ValueError(f"context_fraction: expected in [0, 0.5), got {context_fraction}")
    rng = np.random.default_rng(rng) if not isinstance(rng, np.random.Generator) else rng
    n_mov = (n_points + 1) // 2
    n_ctx = 0
    if context_points is not None and len(context_points) > 0:
        n_ctx = min(round(context_fraction * n_points), n_points - n_mov - 1)
    a = _take(moving_points, n_mov, rng, "moving_points")
    ref = np.asarray(reference_points, dtype=np.float64)
    ctx = None if n_ctx == 0 else np.asarray(context_points, dtype=np.float64)
    if crop is not None:
        m = np.asarray(moving_points, dtype=np.float64).reshape(-1, 3)
        lo_m, hi_m = m.min(axis=0), m.max(axis=0)
        reach = crop * float(np.linalg.norm(hi_m - lo_m))
        ref = _near_box(ref, lo_m, hi_m, reach)
        if ctx is not None:
            ctx = _near_box(ctx, lo_m, hi_m, reach)
    b = _take(ref, n_points - n_mov - n_ctx, rng, "reference_points")
    parts = [a, b]
    if ctx is not None:
        parts.append(_take(ctx, n_ctx, rng, "context_points"))
    pts = np.concatenate(parts, axis=0)
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    scale = float(np.linalg.norm(hi - lo))
    return PairCloud(pts, n_mov, 0.5 * (lo + hi), scale if scale > 0 else 1.0)


def network_inputs(
    pair: PairCloud,
    origins: np.ndarray,
    directions: np.ndarray,
    angles: np.ndarray | None = None,
    translations: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """The network's rest-state cloud and one moved cloud per motion.

    The moving points are moved with :func:`kinmo.geometry.apply_motions` (Rust, parallel
    over motions); the reference points stay.

    Parameters
    ----------
    pair : PairCloud
    origins, directions : (M, 3) float64
        Motion axes, mesh frame.
    angles : (M,) float64, radians, optional
    translations : (M,) float64, mesh units, optional

    Returns
    -------
    before : (N, 4) float32
        Pair-frame coordinates and the moving flag.
    after : (M, N, 4) float32
        The same after each motion.
    """

    m = pair.n_moving
    flags = pair.flags[:, None]
    base = ((pair.points - pair.center) / pair.scale).astype(np.float32)
    before = np.concatenate([base, flags], axis=1)
    o = np.asarray(origins, dtype=np.float64).reshape(-1, 3)
    moved = apply_motions(pair.points[:m], o, directions, angles, translations)  # (M, m, 3)
    after = np.empty((o.shape[0], pair.points.shape[0], 4), dtype=np.float32)
    after[:, :m, :3] = (moved - pair.center) / pair.scale
    after[:, m:, :3] = base[m:]
    after[:, :, 3] = flags[:, 0]
    return before, after


def edge_cloud(graph, moving: int, reference: int, net, rng: np.random.Generator | int = 0
               ) -> PairCloud:
    """The network's input points for the moving edge ``(moving, reference)`` of a part graph.

    The input format is the network's (:class:`kinmo.refine.axis_net.AxisNetConfig`, saved
    with every checkpoint, so training and refinement agree):

    - ``input="pair"`` (kinmo): half moving points, the rest from the reference part and a
      ``context_fraction`` share from the rest of the shape (:func:`pair_cloud`, optionally
      cropped);
    - ``input="shape"`` (the paper's code: the whole shape with the moving-part mask): half
      moving points, the other half from the whole shape without the moving part
      (:func:`shape_context` of ``graph.points[0]``, the root's samples); the reference part
      is not singled out. Falls back to the reference part's points when nothing else is
      left.

    Parameters
    ----------
    graph : PartGraph
        Needs ``points`` (per node, mesh frame; node 0 the whole shape).
    moving, reference : int
        Node indices.
    net : AxisNetConfig
        Gives ``n_points``, ``input``, ``context_fraction`` and ``crop``.
    rng : numpy Generator or int

    Returns
    -------
    PairCloud
        Moving points first (``ceil(n_points / 2)`` of them), static points flagged 0.
    """
    mov = graph.points[moving]
    if getattr(net, "input", "pair") == "shape":
        rest = shape_context(graph.points[0], mov)
        if len(rest) == 0:
            rest = graph.points[reference]
        return pair_cloud(mov, rest, net.n_points, rng, None, 0.0, net.crop)
    frac = net.context_fraction
    ctx = shape_context(graph.points[0], mov) if frac > 0 else None
    return pair_cloud(mov, graph.points[reference], net.n_points, rng, ctx, frac, net.crop)
