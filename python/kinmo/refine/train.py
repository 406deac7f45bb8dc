"""Training of the axis-selection network (Liu et al. 2023, Sec. 3.3).

**Samples.** Every moving sibling edge ``(i, j)`` of a labelled part graph (PartNet-Mobility,
:class:`~kinmo.data.graph.PartGraph` with ``edge_fine`` in P/R/PR types) gives, per epoch, a
triple of point clouds of the moving part ``i`` and its reference part ``j``
(:func:`kinmo.refine.motions.pair_cloud`): the rest state, a **positive** state and a
**negative** state.

- Positive: the part moved about / along its true axis by an amount inside the joint's limits
  (``mobility_v2.json``, kept in ``PartGraph.meta["links"]``): a direction of motion is
  chosen among the sides of the rest pose the limits allow (probability proportional to the
  room on each side), and the magnitude is ``u * span`` with ``u ~ U(amount_range)``
  (default 30–90% of the range on that side). Hinges without limits, or whose limits do not
  contain the rest pose, turn either way by ``U(30°, 90°)``; spans are capped at
  ``max_angle_deg``. Cylindrical (``PR``) joints translate within their limit and turn by
  ``U(30°, 90°)`` (or within their rotation limit).
- Negative: the same amount about / along a wrong line. With probability ``flip_prob``, when
  the limits forbid it, the true axis in the opposite direction (a door opening into the
  cabinet); otherwise a random candidate line of the moving part's OBB of the same motion
  (:func:`kinmo.refine.candidates.candidate_axes` with the coarse type: every OBB edge,
  centre and interaction line for revolute motions, every OBB axis for prismatic ones) in a
  random direction, excluding lines equivalent to the true axis (angle below
  ``match_angle_deg`` and, for rotations, line distance below ``match_distance`` times the
  moving part's OBB diagonal).

**Split.** The motion GNN's test shapes (its run's ``split.json``, or the same default split,
:func:`kinmo.train.split.make_split`) are never used; of the other shapes a share per
category validates (:func:`split_graphs`).

Training triples are mirrored left-right with probability ``mirror_prob`` (label-preserving
augmentation). Shapes are balanced: each epoch draws up to ``samples_per_shape`` moving edges per shape, so
a keyboard's hundred keys do not drown the doors. Randomness comes from
``numpy.random.default_rng([seed, epoch])``: runs are reproducible.

**Loss and metrics.** Binary cross-entropy on the logits of (rest, positive) → 1 and
(rest, negative) → 0; accuracy at 0.5. The validation metric that matters is the
**selection accuracy**: on every validation edge, the candidates of its true fine type are
scored by feasibility alone (inference amounts, :class:`~kinmo.refine.motions.MotionAmounts`)
and the best must be equivalent to the true axis; shapes weigh equally
(:func:`selection_accuracy`; ``select_chance`` is a random choice's, ``select_coverage`` the
share of edges where some candidate is right).

**Outputs** of :func:`train_axis_model` in the run folder: ``config.json`` (the full
:class:`AxisTrainConfig` and the shape split), ``metrics.csv`` (one row per epoch),
``model.pt`` (best validation selection accuracy, ties broken by validation loss; the last
epoch without validation shapes) and ``last.pt``; checkpoints hold the state dict and the
network configuration
(:func:`load_axis_model`). All files are written atomically.
"""

from __future__ import annotations

import csv
import hashlib
import io
import json
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from kinmo.data.graph import PartGraph
from kinmo.data.model import FINE_TYPES
from kinmo.errors import KinmoDataError
from kinmo.io import atomic_path, read_checkpoint, write_json, write_text
from kinmo.refine.axis_net import AxisNetConfig, AxisSelectionNet
from kinmo.refine.candidates import candidate_axes, motion_of
from kinmo.refine.motions import (
    MotionAmounts,
    candidate_motions,
    network_inputs,
    pair_cloud,
    shape_context,
)
from kinmo.refine.scoring import line_feasibility

__all__ = [
    "PRESETS",
    "AxisTrainConfig",
    "MovingEdge",
    "TrainResult",
    "build_triples",
    "equivalent_lines",
    "load_axis_model",
    "load_graphs",
    "moving_edges",
    "preset_config",
    "save_axis_model",
    "selection_accuracy",
    "split_graphs",
    "train_axis_model",
]

METRIC_COLUMNS: tuple[str, ...] = (
    "epoch", "train_loss", "train_acc", "val_loss", "val_acc", "val_select_acc",
    "val_select_chance", "val_select_coverage", "lr", "seconds",
)


class AxisTrainConfig(BaseModel):
    """Everything that defines an axis-network training run (saved as ``config.json``).

    Attributes
    ----------
    preset : {"quick", "paper", "custom"}
        Origin of the values (:data:`PRESETS`).
    seed : int
    net : AxisNetConfig
    epochs, batch_size : int
        ``batch_size`` triples (rest, positive, negative) per step.
    lr, weight_decay : float
        Adam (paper code: 3e-4, 1e-4), step decay ``lr_gamma`` every ``lr_step`` epochs.
    lr_step : int
    lr_gamma : float
    samples_per_shape : int
        Moving edges drawn per shape and epoch.
    amount_range : (float, float)
        Fractions of the joint range of positive / negative amounts.
    max_angle_deg : float
        Cap of a hinge's span on one side (degrees).
    flip_prob : float
        Probability of a reversed-direction negative when the limits forbid that direction.
    mirror_prob : float
        Probability of mirroring a training triple left-right (``x -> -x`` in the pair frame,
        which keeps +y up and the front facing the same way): a left-hinged door becomes a
        right-hinged one, with the same feasibility.
    hard_negative_prob : float
        Probability that a (non-reversed) negative comes from the candidates of the edge's own
        fine type (the choices the refinement faces) rather than from all candidates of its
        motion.
    match_angle_deg, match_distance : float
        Equivalence of a candidate line to the true axis (degrees; fraction of the moving
        part's OBB diagonal).
    test_fraction : float
        Share of each category held out as the motion GNN's test set when no split is given
        (as :func:`kinmo.train.split.make_split`; must match the GNN run's).
    val_fraction : float
        Share of each category's remaining shapes that validate the axis network.
    val_repeats : int
        Validation triples per validation edge (fixed seed).
    interaction_radius : float
        Passed to :func:`~kinmo.refine.candidates.candidate_axes`.
    amounts : MotionAmounts fields
        ``angles_deg`` and ``translation_fraction`` of inference motions (selection metric).
    threads : int
        torch CPU threads (0: leave torch's default).
    device : str
        ``"cpu"``, ``"cuda"`` or ``"auto"``.
    """

    model_config = ConfigDict(extra="forbid")

    preset: Literal["quick", "paper", "custom"] = "custom"
    seed: int = 0
    net: AxisNetConfig = Field(default_factory=AxisNetConfig)
    epochs: int = Field(30, ge=1)
    batch_size: int = Field(8, ge=1)
    lr: float = Field(3e-4, gt=0)
    weight_decay: float = Field(1e-4, ge=0)
    lr_step: int = Field(20, ge=1)
    lr_gamma: float = Field(0.7, gt=0, le=1)
    samples_per_shape: int = Field(4, ge=1)
    amount_range: tuple[float, float] = (0.3, 0.9)
    max_angle_deg: float = Field(180.0, gt=0)
    flip_prob: float = Field(0.25, ge=0, le=1)
    hard_negative_prob: float = Field(0.5, ge=0, le=1)
    mirror_prob: float = Field(0.5, ge=0, le=1)
    match_angle_deg: float = Field(10.0, gt=0)
    match_distance: float = Field(0.1, gt=0)
    test_fraction: float = Field(0.25, ge=0, lt=1)
    val_fraction: float = Field(0.2, ge=0, lt=1)
    val_repeats: int = Field(2, ge=1)
    interaction_radius: float = Field(0.1, gt=0)
    angles_deg: tuple[float, ...] = (60.0,)
    translation_fraction: float = Field(0.5, gt=0)
    threads: int = Field(0, ge=0)
    device: str = "auto"

    @property
    def amounts(self) -> MotionAmounts:
        """The inference motion amounts."""
        return MotionAmounts(tuple(self.angles_deg), self.translation_fraction)


#: Named configurations. ``quick``: a small network that trains on a CPU in minutes.
#: ``paper``: the paper code's network and optimiser (DGCNN 64-64-128, 4096 points, k = 20,
#: 128-d embedding, Adam 3e-4 / 1e-4, step decay 0.7 every 20 epochs), meant for a GPU.
PRESETS: dict[str, dict[str, Any]] = {
    "quick": {
        "net": {"n_points": 512, "k": 16, "widths": [32, 32, 64], "emb_dim": 64,
                "head": [64, 32], "dropout": 0.3, "norm": "batch"},
        "epochs": 12, "batch_size": 16, "lr": 1e-3, "lr_step": 8, "samples_per_shape": 4,
        "threads": 1,  # as the other quick presets: the same weights on any machine
    },
    "paper": {
        "net": {"n_points": 4096, "k": 20, "widths": [64, 64, 128], "emb_dim": 128,
                "head": [256, 128], "dropout": 0.5, "norm": "batch"},
        "epochs": 200, "batch_size": 8, "lr": 3e-4, "lr_step": 20, "samples_per_shape": 8,
    },
}


def preset_config(preset: str = "quick", **overrides: Any) -> AxisTrainConfig:
    """An :class:`AxisTrainConfig` from a preset of :data:`PRESETS` with ``overrides``.

    Raises
    ------
    ValueError
        Unknown preset or invalid values.
    """
    if preset not in PRESETS:
        raise ValueError(f"preset: expected one of {', '.join(PRESETS)}, got {preset!r}")
    values: dict[str, Any] = json.loads(json.dumps(PRESETS[preset]))
    net = dict(values.pop("net"))
    net.update(overrides.pop("net", {}) or {})
    values.update(overrides)
    return AxisTrainConfig(preset=preset, net=AxisNetConfig(**net), **values)


# --------------------------------------------------------------------------- data


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


def _pair(g: PartGraph, me: MovingEdge, net: AxisNetConfig, rng: np.random.Generator):
    frac = net.context_fraction
    ctx = shape_context(g.points[0], g.points[me.moving]) if frac > 0 else None
    return pair_cloud(g.points[me.moving], g.points[me.reference], net.n_points, rng, ctx, frac,
                      net.crop)


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
    rng : numpy Generator

    Returns
    -------
    rest, positive, negative : (B, N, 4) float32
        Pair-frame clouds with the moving flag (:func:`kinmo.refine.motions.network_inputs`);
        ``B = len(edges)``.
    """
    n = config.net.n_points
    out = np.empty((3, len(edges), n, 4), dtype=np.float32)
    frac = tuple(config.amount_range)
    for b, me in enumerate(edges):
        g = graphs[me.graph]
        motion = motion_of(me.fine_type)
        obb = _obb(g, me.moving)
        diag = _diag(g, me.moving)
        pair = _pair(g, me, config.net, rng)
        # Amounts (signed) relative to the true direction.
        amount_t = amount_r = 0.0
        forbid_flip = False
        if motion == "R":
            amount_r, forbid_flip = _signed_amount(
                _sides(me.limit, config.max_angle_deg), rng, frac, (30.0, 90.0))
        else:
            if me.limit is not None and _sides(me.limit, math.inf) is not None:
                amount_t, forbid_flip = _signed_amount(_sides(me.limit, math.inf), rng, frac,
                                                       (0.0, 0.0))
            else:  # unknown range: a fraction of the part's extent, either way
                ext = float(2.0 * np.abs(obb[1] @ me.direction) @ obb[2])
                amount_t = ext * rng.uniform(*frac) * rng.choice([-1.0, 1.0])
            if abs(amount_t) <= 0:
                amount_t = 1e-3 * diag
            if motion == "PR":
                rs = _sides(None if me.rotation_limit is None else (0.0, me.rotation_limit),
                            config.max_angle_deg)
                amount_r, _ = _signed_amount(rs, rng, frac, (30.0, 90.0))
        pd, pa, pt = _motion(me.direction, motion, amount_t, amount_r)
        # Negative line.
        if forbid_flip and rng.uniform() < config.flip_prob:
            nd, na, nt = pd * -1.0, -pa if motion == "PR" else pa, pt
            n_origin = me.origin
        else:
            kind = me.fine_type if rng.uniform() < config.hard_negative_prob else motion
            cands = candidate_axes(obb, kind, g.points[me.moving], g.points[me.reference],
                                   interaction_radius=config.interaction_radius)
            wrong = ~equivalent_lines(cands.origins, cands.directions, me.origin, me.direction,
                                      motion != "P", diag, config.match_angle_deg,
                                      config.match_distance)
            if not wrong.any() and kind != motion:  # no wrong line of the fine type
                cands = candidate_axes(obb, motion, g.points[me.moving], g.points[me.reference],
                                       interaction_radius=config.interaction_radius)
                wrong = ~equivalent_lines(cands.origins, cands.directions, me.origin,
                                          me.direction, motion != "P", diag,
                                          config.match_angle_deg, config.match_distance)
            pool = np.flatnonzero(wrong)
            if pool.size == 0:  # every candidate matches: fall back to the reversed motion
                nd, na, nt, n_origin = pd * -1.0, pa, pt, me.origin
            else:
                c = int(rng.choice(pool))
                nd = cands.directions[c] * rng.choice([-1.0, 1.0])
                na, nt, n_origin = pa, pt, cands.origins[c]
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

    Uses :func:`kinmo.train.gnn.load_cache` (the manifest's ``ok`` / ``skipped`` rows, or
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
    from kinmo.train.gnn import load_cache

    graphs = [g for g in load_cache(data) if g.has_labels and len(g.sibling_edges) > 0]
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
    from kinmo.train.split import Split, make_split

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


# --------------------------------------------------------------------------- metrics


def selection_accuracy(
    model: AxisSelectionNet,
    graphs: Sequence[PartGraph],
    edges: Sequence[MovingEdge],
    config: AxisTrainConfig,
    seed: int = 0,
) -> tuple[float, float, float]:
    """Share of edges whose most feasible candidate (true fine type) is the true axis.

    Every shape weighs the same (per-shape means, then their mean), so that one object with
    many identical joints (a keyboard, a table of drawers) does not decide the metric.

    Parameters
    ----------
    model : AxisSelectionNet
    graphs : sequence of PartGraph
    edges : sequence of MovingEdge
    config : AxisTrainConfig
        Gives the inference amounts, interaction radius and matching thresholds.
    seed : int
        Point subsampling seed.

    Returns
    -------
    accuracy : float
        NaN without edges.
    chance : float
        Expected accuracy of a uniformly random choice among the candidates (the baseline).
    coverage : float
        Share of edges where some candidate matches the true axis (the accuracy's bound).
    """
    import torch

    rng = np.random.default_rng(seed)
    per_shape: dict[int, list[tuple[float, float, float]]] = {}
    device = next(model.parameters()).device
    for me in edges:
        g = graphs[me.graph]
        obb = _obb(g, me.moving)
        diag = _diag(g, me.moving)
        cands = candidate_axes(obb, me.fine_type, g.points[me.moving], g.points[me.reference],
                               interaction_radius=config.interaction_radius)
        match = equivalent_lines(cands.origins, cands.directions, me.origin, me.direction,
                                 cands.motion != "P", diag, config.match_angle_deg,
                                 config.match_distance)
        mot = candidate_motions(cands, obb, config.amounts)
        pair = _pair(g, me, config.net, rng)
        rest, moved = network_inputs(pair, mot.origins, mot.directions, mot.angles,
                                     mot.translations)
        s = model.feasibility(torch.from_numpy(rest).to(device),
                              torch.from_numpy(moved).to(device)).cpu().numpy()
        feas, _ = line_feasibility(s, mot.line, mot.sign, len(cands))
        per_shape.setdefault(me.graph, []).append(
            (float(match[int(np.argmax(feas))]), float(match.mean()), float(match.any())))
    if not per_shape:
        return float("nan"), float("nan"), float("nan")
    m = np.mean([np.mean(v, axis=0) for v in per_shape.values()], axis=0)
    return float(m[0]), float(m[1]), float(m[2])


# --------------------------------------------------------------------------- training


@dataclass
class TrainResult:
    """Outcome of :func:`train_axis_model`.

    Attributes
    ----------
    run_dir : Path
    metrics : list of dict
        One row per epoch (:data:`METRIC_COLUMNS`).
    best_epoch : int
    n_train_edges, n_val_edges : int
    """

    run_dir: Path
    metrics: list[dict[str, float]]
    best_epoch: int
    n_train_edges: int
    n_val_edges: int


def _device(name: str):
    import torch

    if name == "auto":
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    return torch.device(name)


def save_axis_model(path: str | Path, model: AxisSelectionNet, **extra: Any) -> Path:
    """Write an axis-selection checkpoint atomically (read by :func:`load_axis_model`).

    Parameters
    ----------
    path : str or Path
        The ``.pt`` file.
    model : AxisSelectionNet
    **extra
        JSON-like items stored with it (epoch, metrics, training configuration).

    Returns
    -------
    Path
    """
    import torch

    path = Path(path)
    state = {k: v.detach().cpu() for k, v in model.state_dict().items()}
    blob = {"format": "kinmo-axis-selection", "version": 1, "state_dict": state,
            "net": model.config.model_dump(), **extra}
    with atomic_path(path) as tmp:
        torch.save(blob, tmp)
    return path


def load_axis_model(path: str | Path, device: str = "cpu") -> AxisSelectionNet:
    """Load a trained axis-selection network.

    Parameters
    ----------
    path : str or Path
        A run folder of ``kinmo train axis`` (its ``model.pt``) or a checkpoint file.
    device : str

    Returns
    -------
    AxisSelectionNet
        In eval mode.

    Raises
    ------
    KinmoDataError
        Missing or unreadable checkpoint (message names the file).
    """
    p = Path(path)
    if p.is_dir():
        p = p / "model.pt"
    if not p.is_file():
        raise KinmoDataError(p, "no axis-selection checkpoint (train one with `kinmo train axis`)")
    blob = read_checkpoint(p, "kinmo-axis-selection", "axis-selection")
    try:
        if "net" not in blob:
            raise ValueError("not a kinmo axis-selection checkpoint")
        model = AxisSelectionNet(AxisNetConfig(**blob["net"]))
        model.load_state_dict(blob["state_dict"])
    except Exception as e:  # torch raises many types for corrupt or foreign files
        raise KinmoDataError(p, f"cannot read axis-selection checkpoint: {e}") from None
    return model.to(device).eval()


def _metrics_csv(rows: list[dict[str, float]]) -> str:
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=list(METRIC_COLUMNS), lineterminator="\n")
    w.writeheader()
    for r in rows:
        w.writerow({k: (f"{v:.6g}" if isinstance(v, float) else v) for k, v in r.items()})
    return buf.getvalue()


def _run_batches(model, opt, graphs, edges, config, rng, device, train: bool,
                 on_batch: Callable[[], None] | None = None) -> tuple[float, float]:
    import torch
    import torch.nn.functional as F

    model.train(train)
    losses, accs, count = 0.0, 0.0, 0
    bs = config.batch_size
    for start in range(0, len(edges), bs):
        chunk = list(edges[start : start + bs])
        if train and len(chunk) < 2 and config.net.norm == "batch" and start > 0:
            continue  # a batch of one breaks batch norm; it is drawn again next epoch
        rest, pos, neg = (torch.from_numpy(a).to(device)
                          for a in build_triples(graphs, chunk, config, rng))
        b = rest.shape[0]
        with torch.set_grad_enabled(train):
            f = model.encode(torch.cat([rest, pos, neg]))
            fr, fp, fn = f[:b], f[b : 2 * b], f[2 * b :]
            logits = model.head(torch.cat([fr, fr]), torch.cat([fp, fn]))
            target = torch.cat([torch.ones(b), torch.zeros(b)]).to(device)
            loss = F.binary_cross_entropy_with_logits(logits, target)
        if train:
            opt.zero_grad()
            loss.backward()
            opt.step()
        losses += float(loss.detach()) * 2 * b
        accs += float(((logits > 0).float() == target).float().sum())
        count += 2 * b
        if on_batch is not None:
            on_batch()
    return losses / max(count, 1), accs / max(count, 1)


def _epoch_edges(edges: Sequence[MovingEdge], per_shape: int, rng: np.random.Generator
                 ) -> list[MovingEdge]:
    by_graph: dict[int, list[MovingEdge]] = {}
    for me in edges:
        by_graph.setdefault(me.graph, []).append(me)
    out: list[MovingEdge] = []
    for g in sorted(by_graph):
        lst = by_graph[g]
        pick = rng.choice(len(lst), size=min(per_shape, len(lst)), replace=False)
        out += [lst[int(k)] for k in sorted(pick)]
    order = rng.permutation(len(out))
    return [out[int(k)] for k in order]


def train_axis_model(
    data: str | Path | Sequence[PartGraph],
    out: str | Path,
    config: AxisTrainConfig | None = None,
    split: Any = None,
    progress: bool = True,
) -> TrainResult:
    """Train the axis-selection network on labelled part graphs (module docstring).

    Parameters
    ----------
    data : str, Path or sequence of PartGraph
        A cache folder of ``kinmo prepare`` on PartNet-Mobility objects, or graphs.
    out : str or Path
        Run folder (created; existing files are overwritten).
    config : AxisTrainConfig, optional
        Default: the ``quick`` preset.
    split : Split, str or Path, optional
        The motion GNN's split (or its ``split.json``); its test shapes are never used
        (:func:`split_graphs`).
    progress : bool
        Show a rich progress bar.

    Returns
    -------
    TrainResult

    Raises
    ------
    KinmoDataError
        No labelled graphs with moving joints.
    """
    import torch

    config = config or preset_config("quick")
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    if isinstance(data, (str, Path)):
        graphs = load_graphs(data)
    else:
        graphs = sorted((g for g in data if g.has_labels and len(g.sibling_edges) > 0),
                        key=lambda g: g.shape_id)
    tr_idx, va_idx, test_ids = split_graphs(graphs, config, split)
    all_edges = moving_edges(graphs)
    tr_set, va_set = set(tr_idx), set(va_idx)
    tr_edges = [e for e in all_edges if e.graph in tr_set]
    va_edges = [e for e in all_edges if e.graph in va_set]
    if not tr_edges:
        raise KinmoDataError(str(data), "no moving joints in the training graphs")
    if config.threads:
        torch.set_num_threads(config.threads)
    torch.manual_seed(config.seed)
    device = _device(config.device)
    model = AxisSelectionNet(config.net).to(device)
    opt = torch.optim.Adam(model.parameters(), lr=config.lr, weight_decay=config.weight_decay)
    sched = torch.optim.lr_scheduler.StepLR(opt, step_size=config.lr_step, gamma=config.lr_gamma)
    write_json(out / "config.json", {
        "kind": "axis-selection",
        "config": config.model_dump(mode="json"),
        "data": str(data) if isinstance(data, (str, Path)) else None,
        "split": {"train": [graphs[k].shape_id for k in tr_idx],
                  "val": [graphs[k].shape_id for k in va_idx], "test": test_ids},
        "n_train_edges": len(tr_edges),
        "n_val_edges": len(va_edges),
    })

    rows: list[dict[str, float]] = []
    best_key: tuple[float, float] | None = None
    best_epoch = 0
    per_graph: dict[int, int] = {}
    for e in tr_edges:
        per_graph[e.graph] = per_graph.get(e.graph, 0) + 1
    steps = math.ceil(sum(min(config.samples_per_shape, n) for n in per_graph.values())
                      / config.batch_size)
    bar = _Progress(progress, config.epochs * steps)
    with bar:
        for epoch in range(1, config.epochs + 1):
            t0 = time.perf_counter()
            rng = np.random.default_rng([config.seed, epoch])
            ep_edges = _epoch_edges(tr_edges, config.samples_per_shape, rng)
            bar.describe(f"axis net epoch {epoch}/{config.epochs}")
            tl, ta = _run_batches(model, opt, graphs, ep_edges, config, rng, device, True,
                                  bar.advance)
            sched.step()
            vl = va = vs = vch = vc = float("nan")
            if va_edges:
                vrng = np.random.default_rng([config.seed, 10**6])
                v_edges = [e for e in va_edges for _ in range(config.val_repeats)]
                with torch.no_grad():
                    vl, va = _run_batches(model, None, graphs, v_edges, config, vrng, device,
                                          False)
                vs, vch, vc = selection_accuracy(model, graphs, va_edges, config,
                                                 seed=config.seed)
            row = {"epoch": epoch, "train_loss": tl, "train_acc": ta, "val_loss": vl,
                   "val_acc": va, "val_select_acc": vs, "val_select_chance": vch, "val_select_coverage": vc,
                   "lr": float(opt.param_groups[0]["lr"]), "seconds": time.perf_counter() - t0}
            rows.append(row)
            bar.log(f"epoch {epoch}: loss {tl:.3f} acc {ta:.3f} | val loss {vl:.3f} "
                    f"acc {va:.3f} select {vs:.3f} (chance {vch:.3f}, coverage {vc:.3f})")
            key = (float(epoch), 0.0) if not va_edges else (vs, -vl)
            extra = {"epoch": epoch, "metrics": row, "train_config": config.model_dump(mode="json")}
            save_axis_model(out / "last.pt", model, **extra)
            if best_key is None or key > best_key:
                best_key, best_epoch = key, epoch
                save_axis_model(out / "model.pt", model, **extra)
            write_text(out / "metrics.csv", _metrics_csv(rows))
    return TrainResult(out, rows, best_epoch, len(tr_edges), len(va_edges))


class _Progress:
    """A rich progress bar (or nothing), advanced per training step."""

    def __init__(self, enabled: bool, total: int) -> None:
        self.enabled = enabled
        self.total = total
        self._p = None
        self._task = None

    def __enter__(self) -> _Progress:
        if self.enabled:
            from rich.progress import (
                BarColumn,
                MofNCompleteColumn,
                Progress,
                TextColumn,
                TimeElapsedColumn,
                TimeRemainingColumn,
            )

            self._p = Progress(TextColumn("{task.description}"), BarColumn(),
                               MofNCompleteColumn(), TimeElapsedColumn(), TimeRemainingColumn())
            self._p.__enter__()
            self._task = self._p.add_task("axis net", total=self.total)
        return self

    def describe(self, text: str) -> None:
        if self._p is not None:
            self._p.update(self._task, description=text)

    def advance(self) -> None:
        if self._p is not None:
            self._p.advance(self._task)

    def log(self, text: str) -> None:
        if self._p is not None:
            self._p.console.print(text)

    def __exit__(self, *exc: Any) -> None:
        if self._p is not None:
            self._p.__exit__(*exc)


