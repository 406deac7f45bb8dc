"""Training data of the axis-selection network: moving edges, triples, split (Sec. 3.3).

**Samples.** Every moving sibling edge ``(i, j)`` of a labelled part graph (PartNet-Mobility,
:class:`~kinmo.data.graph.PartGraph` with ``edge_fine`` in P/R/PR types) gives, per epoch, a
triple of point clouds (:func:`kinmo.refine.motions.edge_cloud`: the moving part ``i`` and
either its reference part ``j`` with some context, or the whole rest of the shape, with the
moving mask as 4th channel): the rest state, a **positive** state and a **negative** state.

- Positive: the part moved about / along its true axis by an amount inside the joint's limits
  (``mobility_v2.json``, kept in ``PartGraph.meta["links"]``): a direction of motion is
  chosen among the sides of the rest pose the limits allow (probability proportional to the
  room on each side), and the magnitude is ``u * span`` with ``u ~ U(amount_range)``
  (default 30-90% of the range on that side). Hinges without limits, or whose limits do not
  contain the rest pose, turn either way by ``U(30°, 90°)``; spans are capped at
  ``max_angle_deg``. Cylindrical (``PR``) joints translate within their limit and turn by
  ``U(30°, 90°)`` (or within their rotation limit).
- Negative: the same amount about / along a wrong line. With probability ``flip_prob``, when
  the limits forbid it, the true axis in the opposite direction (a door opening into the
  cabinet); otherwise a random wrong candidate line of the moving part's OBB: with
  probability ``hard_negative_prob`` one of the edge's own fine type (the choices the
  refinement faces), else one of its coarse motion (every OBB edge, centre and interaction
  line of every orientation for revolute motions, every OBB axis for prismatic ones;
  :func:`kinmo.refine.candidates.candidate_axes`), in a random direction, excluding lines
  equivalent to the true axis (:func:`equivalent_lines`).
- **Articulated rest states** (the paper's code): with probability ``articulated_prob`` the
  "before" cloud is itself articulated, the part moved a share ``u0 ~ U(articulated_range)``
  of the positive motion about the true axis; the positive then moves it the rest of the way
  (still about the true axis, inside the limits), the negative by the same amount about the
  wrong line carried along by that articulation (a flip negative turns back past the rest
  pose, into the forbidden side).

Training triples are mirrored left-right with probability ``mirror_prob`` (label-preserving
augmentation). Randomness comes only from the generator passed in: runs are reproducible.

**Split.** The motion GNN's test shapes (its run's ``split.json``, or the same default split,
:func:`kinmo.train.split.make_split`) are never used; of the other shapes a share per
category validates (:func:`split_graphs`).

The configuration (:class:`kinmo.refine.axis_config.AxisTrainConfig`) is duck-typed here (its
``net``, amounts and probabilities), so this module does not import the training loop.
"""

from __future__ import annotations

import dataclasses
import hashlib
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from kinmo.data.cache import load_cache
from kinmo.data.graph import PartGraph
from kinmo.data.model import FINE_TYPES
from kinmo.errors import KinmoDataError
from kinmo.geometry import apply_motions
from kinmo.refine.candidates import candidate_axes, motion_of
from kinmo.refine.motions import PairCloud, edge_cloud, network_inputs
from kinmo.train.gnn import labelled_graphs
from kinmo.train.split import Split, make_split

if TYPE_CHECKING:
    from kinmo.refine.axis_config import AxisTrainConfig

__all__ = [
    "MovingEdge",
    "build_triples",
    "equivalent_lines",
    "load_graphs",
    "moving_edges",
    "split_graphs",
]


@dataclass(frozen=True)
class MovingEdge:
    """A labelled moving sibling edge of a part graph.

    Attributes
    ----------
    graph : int
        Index of the graph in the list given to :func:`moving_edges`.
    edge : int
        Sibling-edge index.
    moving, reference : int
        Node indices ``i``, ``j``.
    fine_type : str
    origin, direction : (3,) float64
        True axis (mesh frame, unit direction).
    limit : tuple of float or None
        Joint limits ``(a, b)`` (degrees for hinges, mesh units for sliders), None if
        unlimited or unknown.
    rotation_limit : float or None
        Rotation range of a cylindrical joint (degrees), None if unlimited or unknown.
    """

    graph: int
    edge: int
    moving: int
    reference: int
    fine_type: str
    origin: np.ndarray
    direction: np.ndarray
    limit: tuple[float, float] | None
    rotation_limit: float | None


def moving_edges(graphs: Sequence[PartGraph]) -> list[MovingEdge]:
    """Every labelled moving sibling edge of ``graphs``.

    Returns
    -------
    list of MovingEdge
        Edges with a P/R/PR fine type and a finite axis, in graph then edge order.
    """
    out: list[MovingEdge] = []
    for g_idx, g in enumerate(graphs):
        if not g.has_labels or g.edge_axis_direction is None or g.edge_axis_origin is None:
            continue
        links = {int(lk["id"]): lk for lk in g.meta.get("links", []) or []}
        for e, f in enumerate(np.asarray(g.edge_fine)):
            name = FINE_TYPES[int(f)]
            if name in ("Fixed", "None"):
                continue
            o, d = g.edge_axis_origin[e], g.edge_axis_direction[e]
            if not (np.all(np.isfinite(o)) and np.all(np.isfinite(d))):
                continue
            lk = links.get(int(g.edge_link[e])) if g.edge_link is not None else None
            limit = None
            rot = None
            if lk is not None:
                if lk.get("limit") is not None:
                    limit = (float(lk["limit"][0]), float(lk["limit"][1]))
                if lk.get("rotation_limit") is not None:
                    rot = float(lk["rotation_limit"])
            i, j = (int(x) for x in g.sibling_edges[e])
            out.append(MovingEdge(g_idx, e, i, j, name, np.asarray(o, float),
                                  np.asarray(d, float) / np.linalg.norm(d), limit, rot))
    return out


def _sides(limit: tuple[float, float] | None, cap: float) -> tuple[float, float] | None:
    """Room on the negative and positive side of the rest pose (0), capped; None: either way."""
    if limit is None:
        return None
    lo, hi = min(limit), max(limit)
    if not lo <= 0.0 <= hi:
        return None
    return min(-lo, cap), min(hi, cap)


def _signed_amount(
    sides: tuple[float, float] | None, rng: np.random.Generator, frac: tuple[float, float],
    default: tuple[float, float],
) -> tuple[float, bool]:
    """A signed amount inside the limits and whether the opposite sign is forbidden."""
    if sides is None or sides[0] + sides[1] <= 0:
        mag = rng.uniform(*default)
        return float(mag * rng.choice([-1.0, 1.0])), False
    neg, pos = sides
    s = 1.0 if rng.uniform() < pos / (neg + pos) else -1.0
    span = pos if s > 0 else neg
    mag = span * rng.uniform(*frac)
    other = neg if s > 0 else pos
    return float(s * mag), other < 1e-3 * span


def equivalent_lines(
    origins: np.ndarray,
    directions: np.ndarray,
    true_origin: np.ndarray,
    true_direction: np.ndarray,
    rotates: bool,
    length_scale: float,
    angle_deg: float = 10.0,
    distance: float = 0.1,
) -> np.ndarray:
    """Which candidate lines match a true axis.

    Parameters
    ----------
    origins, directions : (C, 3) float
    true_origin, true_direction : (3,) float
    rotates : bool
        Revolute or cylindrical: the position must match too.
    length_scale : float
        The moving part's OBB diagonal.
    angle_deg : float
        Largest angle between the lines.
    distance : float
        Largest distance from the true origin to the candidate line, relative to
        ``length_scale`` (checked only when ``rotates``).

    Returns
    -------
    (C,) bool
    """
    u = np.asarray(directions, float).reshape(-1, 3)
    u = u / np.linalg.norm(u, axis=1, keepdims=True)
    t = np.asarray(true_direction, float) / np.linalg.norm(true_direction)
    ok = np.abs(u @ t) >= math.cos(math.radians(angle_deg))
    if rotates:
        d = np.linalg.norm(np.cross(np.asarray(true_origin) - np.asarray(origins).reshape(-1, 3), u),
                           axis=1)
        ok &= d <= distance * length_scale
    return ok


def _obb(g: PartGraph, i: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    return g.obb_center[i], g.obb_axes[i], g.obb_half_extents[i]


def _diag(g: PartGraph, i: int) -> float:
    return max(2.0 * float(np.linalg.norm(g.obb_half_extents[i])), 1e-12)


def _motion(direction: np.ndarray, motion: str, amount_t: float, amount_r: float
            ) -> tuple[np.ndarray, float, float]:
    """(signed direction, angle rad, translation) for a motion with signed amounts."""
    if motion == "R":
        return direction * math.copysign(1.0, amount_r), math.radians(abs(amount_r)), 0.0
    if motion == "P":
        return direction * math.copysign(1.0, amount_t), 0.0, abs(amount_t)
    # PR: translation sign sets the direction; the rotation's sign is relative to it.
    s = math.copysign(1.0, amount_t)
    return direction * s, math.radians(amount_r * s), abs(amount_t)


def _with_moving(pair: PairCloud, moved: np.ndarray) -> PairCloud:
    """``pair`` with its moving rows replaced (an articulated state; the frame recomputed)."""
    pts = np.concatenate([moved, pair.points[pair.n_moving :]], axis=0)
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    scale = float(np.linalg.norm(hi - lo))
    return dataclasses.replace(pair, points=pts, center=0.5 * (lo + hi),
                               scale=scale if scale > 0 else 1.0)


def _true_amounts(me: MovingEdge, config: AxisTrainConfig, obb, diag: float,
                  rng: np.random.Generator) -> tuple[float, float, bool]:
    """Signed translation, signed rotation (degrees) of a positive, and whether the limits
    forbid the opposite direction."""
    motion = motion_of(me.fine_type)
    frac = tuple(config.amount_range)
    amount_t = amount_r = 0.0
    forbid_flip = False
    if motion == "R":
        amount_r, forbid_flip = _signed_amount(
            _sides(me.limit, config.max_angle_deg), rng, frac, (30.0, 90.0))
        return amount_t, amount_r, forbid_flip
    if me.limit is not None and _sides(me.limit, math.inf) is not None:
        amount_t, forbid_flip = _signed_amount(_sides(me.limit, math.inf), rng, frac, (0.0, 0.0))
    else:  # unknown range: a fraction of the part's extent, either way
        ext = float(2.0 * np.abs(obb[1] @ me.direction) @ obb[2])
        amount_t = ext * rng.uniform(*frac) * rng.choice([-1.0, 1.0])
    if abs(amount_t) <= 0:
        amount_t = 1e-3 * diag
    if motion == "PR":
        rs = _sides(None if me.rotation_limit is None else (0.0, me.rotation_limit),
                    config.max_angle_deg)
        amount_r, _ = _signed_amount(rs, rng, frac, (30.0, 90.0))
    return amount_t, amount_r, forbid_flip


def _negative_line(g: PartGraph, me: MovingEdge, config: AxisTrainConfig, obb, diag: float,
                   rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray] | None:
    """A wrong candidate line ``(origin, signed direction)``, None when every line matches."""
    motion = motion_of(me.fine_type)
    kind = me.fine_type if rng.uniform() < config.hard_negative_prob else motion
    for k in dict.fromkeys((kind, motion)):  # fall back to every orientation
        cands = candidate_axes(obb, k, g.points[me.moving], g.points[me.reference],
                               interaction_radius=config.interaction_radius)
        wrong = ~equivalent_lines(cands.origins, cands.directions, me.origin, me.direction,
                                  motion != "P", diag, config.match_angle_deg,
                                  config.match_distance)
        pool = np.flatnonzero(wrong)
        if pool.size:
            c = int(rng.choice(pool))
            return cands.origins[c], cands.directions[c] * rng.choice([-1.0, 1.0])
    return None


def build_triples(
    graphs: Sequence[PartGraph],
    edges: Sequence[MovingEdge],
    config: AxisTrainConfig,
    rng: np.random.Generator,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Rest, positive and negative clouds of the given moving edges (module docstring).

    Parameters
    ----------
    graphs : sequence of PartGraph
    edges : sequence of MovingEdge
        From :func:`moving_edges` on ``graphs``.
    config : AxisTrainConfig
        Uses ``net`` (input format), ``amount_range``, ``max_angle_deg``, ``flip_prob``,
        ``hard_negative_prob``, ``articulated_prob``, ``articulated_range``, ``mirror_prob``,
        the matching thresholds and ``interaction_radius``.
    rng : numpy Generator

    Returns
    -------
    rest, positive, negative : (B, N, 4) float32
        Network clouds with the moving flag (:func:`kinmo.refine.motions.network_inputs`);
        ``B = len(edges)``; the first ``ceil(N / 2)`` points are the moving part's.
    """

    n = config.net.n_points
    out = np.empty((3, len(edges), n, 4), dtype=np.float32)
    art_prob = float(getattr(config, "articulated_prob", 0.0))
    art_range = tuple(getattr(config, "articulated_range", (0.2, 0.8)))
    for b, me in enumerate(edges):
        g = graphs[me.graph]
        motion = motion_of(me.fine_type)
        obb = _obb(g, me.moving)
        diag = _diag(g, me.moving)
        pair = edge_cloud(g, me.moving, me.reference, config.net, rng)
        amount_t, amount_r, forbid_flip = _true_amounts(me, config, obb, diag, rng)
        pd, pa, pt = _motion(me.direction, motion, amount_t, amount_r)
        # Negative line (absolute, rest frame) and amounts.
        if forbid_flip and rng.uniform() < config.flip_prob:
            n_origin, nd, na, nt = me.origin, pd * -1.0, (-pa if motion == "PR" else pa), pt
            flip = True
        else:
            line = _negative_line(g, me, config, obb, diag, rng)
            flip = line is None  # every candidate matches: the reversed motion
            n_origin, nd = (me.origin, pd * -1.0) if line is None else line
            na, nt = pa, pt
        draw, u = rng.uniform(), rng.uniform(*art_range)  # drawn always: same stream
        u0 = u if draw < art_prob else 0.0
        if u0 > 0.0:
            # Articulate the rest state by u0 of the positive motion about the true axis and
            # carry the negative line along; the positive does the remaining (1 - u0), the
            # negative the same about its line (a flip turns back the whole way, past rest).
            m = pair.n_moving
            o0, d0 = me.origin[None], pd[None]
            a0, t0 = np.array([u0 * pa]), np.array([u0 * pt])
            moved0 = apply_motions(pair.points[:m], o0, d0, a0, t0)[0]
            ends = apply_motions(np.stack([n_origin, n_origin + nd]), o0, d0, a0, t0)[0]
            pair = _with_moving(pair, moved0)
            n_origin, nd = ends[0], ends[1] - ends[0]
            pa, pt = (1.0 - u0) * pa, (1.0 - u0) * pt
            if not flip:
                na, nt = pa, pt
        rest, moved = network_inputs(
            pair,
            np.stack([me.origin, n_origin]),
            np.stack([pd, nd]),
            np.array([pa, na]),
            np.array([pt, nt]),
        )
        out[0, b], out[1, b], out[2, b] = rest, moved[0], moved[1]
        if rng.uniform() < config.mirror_prob:  # drawn always: same stream for any prob
            out[:, b, :, 0] *= -1.0  # the mirror image (x -> -x) moves just as feasibly
    return out[0], out[1], out[2]


# --------------------------------------------------------------------------- graphs, split


def load_graphs(data: str | Path) -> list[PartGraph]:
    """Read the labelled part graphs of a cache folder written by ``kinmo prepare``.

    Uses :func:`kinmo.data.cache.load_cache` (the manifest's ``ok`` / ``skipped`` rows, or
    every ``*.npz``) and keeps, like the motion GNN's training, the graphs with ground-truth
    labels and at least one sibling edge, so that both networks split the same id set.

    Parameters
    ----------
    data : str or Path
        The cache folder.

    Returns
    -------
    list of PartGraph
        Sorted by shape id.

    Raises
    ------
    KinmoDataError
        The folder does not exist or holds no labelled graph (message names it).
    """

    graphs = labelled_graphs(load_cache(data))
    if not graphs:
        raise KinmoDataError(data, "no labelled (PartNet-Mobility) part graphs in the cache")
    return sorted(graphs, key=lambda g: g.shape_id)


def _hash_unit(text: str, seed: int) -> float:
    h = hashlib.sha256(f"{seed}:{text}".encode()).digest()
    return int.from_bytes(h[:8], "big") / 2**64


def split_graphs(
    graphs: Sequence[PartGraph],
    config: AxisTrainConfig,
    split: Any = None,
) -> tuple[list[int], list[int], list[str]]:
    """Train / validation graph indices, never touching the motion GNN's test shapes.

    The test shapes are those of ``split`` (a :class:`kinmo.train.split.Split` or its JSON
    file, e.g. the GNN run's ``split.json``), or of
    :func:`kinmo.train.split.make_split` with ``config.test_fraction`` and ``config.seed``
    (the GNN's default split of the same cache). Of the remaining shapes, per category, about
    ``config.val_fraction`` (ranked by a hash of the id and the seed; categories with one
    shape stay in training) validate the axis network.

    Parameters
    ----------
    graphs : sequence of PartGraph
    config : AxisTrainConfig
    split : Split, str, Path or None

    Returns
    -------
    train, val : list of int
        Graph indices.
    test : list of str
        The excluded test ids.
    """

    if split is None:
        sp = make_split([g.shape_id for g in graphs], [g.category for g in graphs],
                        config.test_fraction, config.seed)
    elif isinstance(split, Split):
        sp = split
    else:
        sp = Split.load(split)
    test = set(sp.test)
    by_cat: dict[str, list[int]] = {}
    for k, g in enumerate(graphs):
        if g.shape_id not in test:
            by_cat.setdefault(g.category, []).append(k)
    train, val = [], []
    for cat in sorted(by_cat):
        ks = by_cat[cat]
        ranked = sorted(ks, key=lambda k: _hash_unit(graphs[k].shape_id, config.seed))
        n_val = min(round(config.val_fraction * len(ks)), len(ks) - 1) if len(ks) > 1 else 0
        val += ranked[:n_val]
        train += ranked[n_val:]
    return sorted(train), sorted(val), sorted(test)

