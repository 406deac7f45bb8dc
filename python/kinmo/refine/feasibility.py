"""Batched feasibility of candidate axis lines: every moving edge of one or many shapes at once.

The axis-selection network (:class:`~kinmo.refine.axis_net.AxisSelectionNet`, Liu et al. 2023,
Sec. 3.3) judges a candidate line by moving the part about / along it. The paper's code scores
a line by the mean feasibility over the motions ``±30°, ±45°, ±60°, ±80°`` (both directions
of the line, :data:`PAPER_ANGLES`); kinmo also keeps the per-direction means, so a ranker can
use the better direction (which fixes the sign of the refined axis) and the gap between them.

:func:`score_lines` takes any number of :class:`LineRequest` (a moving edge of a part graph and
its candidate lines), builds every rest cloud and every moved cloud (numpy and the Rust
:func:`kinmo.geometry.apply_motions`), and calls the network once for all rest clouds and in
chunks of ``chunk`` moved clouds for all motions together, under ``torch.inference_mode`` -
no per-candidate or per-edge network call. With an :class:`~kinmo.refine.axis_io.AxisModelSet`
the requests are grouped by their shape's category network.

Results do not depend on the batching: request ``r`` draws its points from
``numpy.random.default_rng([seed, r])`` unless it brings its own generator seed.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from kinmo.refine.candidates import Candidates
from kinmo.refine.motions import MotionAmounts, candidate_motions, edge_cloud, network_inputs

__all__ = ["PAPER_ANGLES", "LineFeasibility", "LineRequest", "score_lines"]

#: The paper code's rotation angles (degrees), each tried in both directions of a line.
PAPER_ANGLES: tuple[float, ...] = (30.0, 45.0, 60.0, 80.0)


@dataclass(frozen=True)
class LineRequest:
    """One moving edge of a part graph and the candidate lines to score.

    Attributes
    ----------
    graph : PartGraph
        Needs ``points``, ``obb_*`` and ``category`` (per-category networks).
    moving, reference : int
        Node indices.
    candidates : Candidates
        Lines (mesh frame) and their motion type (:func:`kinmo.refine.candidates.candidate_axes`).
    seed : int or sequence of int, optional
        Seed of this request's point sampling (default: ``[seed, index]`` of :func:`score_lines`).
    """

    graph: object
    moving: int
    reference: int
    candidates: Candidates
    seed: int | tuple[int, ...] | None = None


@dataclass(frozen=True)
class LineFeasibility:
    """Feasibility of the ``C`` candidate lines of one request.

    Attributes
    ----------
    feasibility : (C,) float64
        Mean over the amounts and both directions (the paper code's score).
    positive, negative : (C,) float64
        Mean over the amounts of the ``+direction`` / ``-direction`` motions.
    per_motion : (C, 2, A) float64
        Every motion's value: line, direction (``+``, ``-``), amount (``A`` angles for
        revolute / ``PR`` lines, 1 for prismatic).

    Notes
    -----
    ``best`` and ``sign`` give the better direction (kinmo's pre-existing score, ``max`` over
    the two directions, :func:`kinmo.refine.scoring.line_feasibility`).
    """

    feasibility: np.ndarray
    positive: np.ndarray
    negative: np.ndarray
    per_motion: np.ndarray

    @property
    def best(self) -> np.ndarray:
        """``(C,) float64``: the better direction's mean."""
        return np.maximum(self.positive, self.negative)

    @property
    def sign(self) -> np.ndarray:
        """``(C,) int64``: +1 or -1, the better direction (+1 when tied)."""
        return np.where(self.negative > self.positive, -1, 1).astype(np.int64)

    def subset(self, amounts: Sequence[int]) -> LineFeasibility:
        """The same scores restricted to some amount indices (e.g. a subset of the angles)."""
        idx = list(amounts) if self.per_motion.shape[2] > 1 else [0]
        pm = self.per_motion[:, :, idx]
        return LineFeasibility(pm.mean(axis=(1, 2)), pm[:, 0].mean(axis=1),
                               pm[:, 1].mean(axis=1), pm)


def _model_for(models, graph):
    get = getattr(models, "for_category", None)
    return get(getattr(graph, "category", None)) if get is not None else models


def score_lines(
    models,
    requests: Sequence[LineRequest],
    amounts: MotionAmounts | None = None,
    seed: int = 0,
    chunk: int = 16,
    n_points: int | None = None,
) -> list[LineFeasibility]:
    """Score the candidate lines of many moving edges in batched network calls.

    Parameters
    ----------
    models : AxisSelectionNet or AxisModelSet
        The network, or a global network with per-category ones (chosen by
        ``request.graph.category``).
    requests : sequence of LineRequest
        From one or several shapes.
    amounts : MotionAmounts, optional
        Rotation angles and translation share (default: :data:`PAPER_ANGLES`, 0.5).
    seed : int
        Default sampling seed (request ``r`` uses ``[seed, r]``).
    chunk : int
        Moved clouds per encoder call (16: on one CPU thread larger batches were not faster,
        ``bench/bench_refine.py --only batched``; raise it on a GPU).
    n_points : int, optional
        Points per cloud (default: the network's ``n_points``; fewer is faster).

    Returns
    -------
    list of LineFeasibility
        One per request, in order; requests without candidates get empty arrays.
    """
    import torch

    amounts = amounts or MotionAmounts(PAPER_ANGLES)
    n_amt = len(amounts.angles_deg)
    out: list[LineFeasibility | None] = [None] * len(requests)
    groups: dict[int, tuple[object, list[int]]] = {}
    for r, req in enumerate(requests):
        net = _model_for(models, req.graph)
        groups.setdefault(id(net), (net, []))[1].append(r)
    for net, idxs in groups.values():
        cfg = net.config if n_points is None else net.config.model_copy(update={"n_points": n_points})
        befores, afters, owners, metas = [], [], [], []
        for r in idxs:
            req = requests[r]
            cands = req.candidates
            a = n_amt if cands.motion in ("R", "PR") else 1
            if len(cands) == 0:
                out[r] = LineFeasibility(*(np.zeros(0),) * 3, np.zeros((0, 2, a)))
                continue
            g = req.graph
            rng = np.random.default_rng([seed, r] if req.seed is None else req.seed)
            obb = (g.obb_center[req.moving], g.obb_axes[req.moving],
                   g.obb_half_extents[req.moving])
            mot = candidate_motions(cands, obb, amounts)
            pair = edge_cloud(g, req.moving, req.reference, cfg, rng)
            rest, moved = network_inputs(pair, mot.origins, mot.directions, mot.angles,
                                         mot.translations)
            owners.append(np.full(len(mot), len(befores), dtype=np.int64))
            befores.append(rest)
            afters.append(moved)
            metas.append((r, len(cands), a))
        if not befores:
            continue
        device = next(net.parameters()).device
        s = net.feasibility_batch(
            torch.from_numpy(np.stack(befores)).to(device),
            torch.from_numpy(np.concatenate(afters)).to(device),
            torch.from_numpy(np.concatenate(owners)).to(device), chunk=chunk,
        ).cpu().numpy().astype(np.float64)
        start = 0
        for r, c, a in metas:  # motions are ordered line, sign (+ first), amount
            pm = s[start : start + 2 * c * a].reshape(c, 2, a)
            start += 2 * c * a
            out[r] = LineFeasibility(pm.mean(axis=(1, 2)), pm[:, 0].mean(axis=1),
                                     pm[:, 1].mean(axis=1), pm)
    return [o for o in out if o is not None]
