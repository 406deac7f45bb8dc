"""Training loss of the motion GNN (Liu et al. 2023, Sec. 3.2, Eq. 1-4).

``L = L_type + w_dir L_dir + w_pos L_pos`` (Eq. 1) over the directed sibling edges of a batch:

- ``L_type`` (Eq. 2): softmax cross-entropy of the motion type, with per-class weights
  against the imbalance of the data (most edges are ``None`` or ``Fixed``):
  :func:`class_weights` gives inverse square-root frequency weights; optionally the focal
  loss ``(1 - p_t)^gamma`` factor (Lin et al. 2017).
- ``L_dir`` (Eq. 3): ``1 - |cos(d_pred, d_true)|``, sign-invariant (an axis and its reverse
  describe the same line), on edges whose true type has an axis (P, R, PR). With the
  candidate direction head (:mod:`kinmo.models.edge_gnn`) ``d_pred`` is the regressed
  direction and ``L_dir`` adds the cross-entropy of the candidate choice,
  ``-log sum_{c correct} p_c``: the correct candidates are those within
  :data:`CANDIDATE_TOL_DEG` of the smallest angle to the true axis when that angle is below
  :data:`CANDIDATE_MAX_DEG`, else the regressed ("free") candidate.
- ``L_pos`` (Eq. 4): distance of the predicted axis point to the true axis line,
  ``|(p - o) x d|`` (normalised-frame units), on edges whose true type rotates (R, PR); a
  prismatic axis has no meaningful position.

Each term is a weighted mean over its edges (0 when a batch has none). With
``balance="edges"`` every edge weighs the same; with ``balance="shapes"`` every *shape* of the
batch weighs the same in each term (an edge of a shape with ``n`` edges in the term weighs
``1/n``), so that a keyboard with 13,000 sibling edges and 115 sliding keys does not drown
a two-part bucket.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch
import torch.nn.functional as F
from torch import nn

from kinmo.features import GraphBatch, moving_fine_mask, rotating_fine_mask
from kinmo.models.motion_gnn import MotionGNNOutput

__all__ = [
    "CANDIDATE_MAX_DEG",
    "CANDIDATE_TOL_DEG",
    "LossTerms",
    "MotionLoss",
    "candidate_targets",
    "class_weights",
    "direction_loss",
    "position_loss",
]

#: A fixed candidate direction is a valid answer when within this many degrees of the best one.
CANDIDATE_TOL_DEG = 1.0
#: Beyond this angle to every fixed candidate, only the regressed direction is correct.
CANDIDATE_MAX_DEG = 5.0


def direction_loss(pred: torch.Tensor, true: torch.Tensor) -> torch.Tensor:
    """Per-edge sign-invariant direction error ``1 - |cos|`` (Eq. 3).

    Parameters
    ----------
    pred, true : (N, 3) float
        Any non-zero lengths (normalised here).

    Returns
    -------
    (N,) float
        In ``[0, 1]``: 0 for parallel or antiparallel, 1 for perpendicular directions.
    """
    cos = F.cosine_similarity(pred, true, dim=1, eps=1e-8)
    return 1.0 - cos.abs()


def position_loss(point: torch.Tensor, origin: torch.Tensor, direction: torch.Tensor) -> torch.Tensor:
    """Per-edge distance of predicted axis points to the true axis lines (Eq. 4).

    Parameters
    ----------
    point : (N, 3) float
        Predicted axis points.
    origin : (N, 3) float
        A point of each true axis.
    direction : (N, 3) float
        True axis directions (normalised here).

    Returns
    -------
    (N,) float
        ``|(point - origin) x d|``, input units.
    """
    d = F.normalize(direction, dim=1, eps=1e-8)
    return torch.linalg.cross(point - origin, d, dim=1).norm(dim=1)


def candidate_targets(candidates: torch.Tensor, true: torch.Tensor) -> torch.Tensor:
    """Which candidate directions count as correct, ``(N, C) bool``.

    Parameters
    ----------
    candidates : (N, C, 3) float
        Unit candidate directions, the last one the regressed ("free") direction.
    true : (N, 3) float
        True unit directions.

    Returns
    -------
    (N, C) bool
        Fixed candidates within :data:`CANDIDATE_TOL_DEG` of the best fixed candidate when that
        one is within :data:`CANDIDATE_MAX_DEG` of ``true``; otherwise only the free one.
    """
    cos = torch.einsum("ncd,nd->nc", candidates[:, :-1].detach(), true).abs().clamp(max=1.0)
    ang = torch.rad2deg(torch.acos(cos))
    best = ang.min(dim=1, keepdim=True).values
    ok = (ang <= best + CANDIDATE_TOL_DEG) & (best <= CANDIDATE_MAX_DEG)
    free = ~ok.any(dim=1, keepdim=True)
    return torch.cat([ok, free], dim=1)


def class_weights(counts: np.ndarray | torch.Tensor) -> torch.Tensor:
    """Inverse square-root frequency class weights.

    Parameters
    ----------
    counts : (K,) int
        Number of training edges of each class.

    Returns
    -------
    (K,) float32
        ``w_k ∝ 1 / sqrt(n_k)``, scaled so that the average weight over the training edges is
        1; classes absent from training get the largest weight of the present ones.

    Raises
    ------
    ValueError
        No edges at all.
    """
    n = torch.as_tensor(np.asarray(counts), dtype=torch.float64)
    if n.sum() <= 0:
        raise ValueError("class_weights: no training edges")
    present = n > 0
    w = torch.zeros_like(n)
    w[present] = 1.0 / n[present].sqrt()
    w = w / (w * n).sum() * n.sum()
    w[~present] = w[present].max()
    return w.to(torch.float32)


@dataclass
class LossTerms:
    """The loss of a batch and its terms (scalar tensors)."""

    total: torch.Tensor
    type: torch.Tensor
    direction: torch.Tensor
    position: torch.Tensor


class MotionLoss(nn.Module):
    """Eq. 1 over a batch (module docstring).

    Parameters
    ----------
    types : {"fine", "coarse"}
        Label set of the model's logits.
    weights : (K,) float, optional
        Class weights of the cross-entropy (:func:`class_weights`).
    focal_gamma : float
        Focal-loss exponent; 0 gives plain (weighted) cross-entropy.
    w_dir, w_pos : float
        Weights of the direction and position terms.
    balance : {"edges", "shapes"}
        Weighting of the edges within each term (module docstring).

    Shapes:
        - ``out``: :class:`MotionGNNOutput` with ``logits (E, K)``, ``direction (E, 3)``,
          ``origin (E, 3)``; ``batch``: labelled :class:`GraphBatch` with ``E`` edges.
        - output: :class:`LossTerms` of scalars.
    """

    def __init__(self, types: str, weights: torch.Tensor | None = None, focal_gamma: float = 0.0,
                 w_dir: float = 1.0, w_pos: float = 1.0, balance: str = "edges") -> None:
        super().__init__()
        if types not in ("fine", "coarse"):
            raise ValueError(f"types must be 'fine' or 'coarse', got {types!r}")
        if balance not in ("edges", "shapes"):
            raise ValueError(f"balance must be 'edges' or 'shapes', got {balance!r}")
        self.balance = balance
        self.types = types
        self.register_buffer("weights", weights if weights is not None else None)
        self.register_buffer("moving", moving_fine_mask())
        self.register_buffer("rotating", rotating_fine_mask())
        self.focal_gamma = float(focal_gamma)
        self.w_dir = float(w_dir)
        self.w_pos = float(w_pos)

    def forward(self, out: MotionGNNOutput, batch: GraphBatch) -> LossTerms:
        if batch.edge_fine is None or batch.axis_origin is None or batch.axis_direction is None:
            raise ValueError("MotionLoss needs a labelled batch")
        target = batch.edge_labels(self.types)
        zero = out.logits.sum() * 0.0
        if target.numel() == 0:
            return LossTerms(zero, zero, zero, zero)
        logp = F.log_softmax(out.logits, dim=1)
        nll = -logp.gather(1, target[:, None]).squeeze(1)
        if self.focal_gamma > 0:
            pt = torch.exp(-nll)
            nll = (1.0 - pt) ** self.focal_gamma * nll
        w = self.weights[target] if self.weights is not None else torch.ones_like(nll)
        w = w * self._shape_weights(batch, torch.ones_like(target, dtype=torch.bool))
        l_type = (w * nll).sum() / w.sum().clamp(min=1e-12)
        has = self.moving[batch.edge_fine] & batch.has_axis
        rot = self.rotating[batch.edge_fine] & batch.has_axis
        l_dir, l_pos = zero, zero
        if has.any():
            wd = self._shape_weights(batch, has)[has]
            free = out.direction_free if out.direction_free is not None else out.direction
            ld = direction_loss(free[has], batch.axis_direction[has])
            if out.axis_logits is not None and out.axis_candidates is not None:
                ok = candidate_targets(out.axis_candidates[has], batch.axis_direction[has])
                lg = out.axis_logits[has]
                ce = torch.logsumexp(lg, dim=1) - torch.logsumexp(
                    lg.masked_fill(~ok, float("-inf")), dim=1)
                ld = ld + ce
            l_dir = (wd * ld).sum() / wd.sum()
        if rot.any():
            wp = self._shape_weights(batch, rot)[rot]
            lp = position_loss(out.origin[rot], batch.axis_origin[rot], batch.axis_direction[rot])
            l_pos = (wp * lp).sum() / wp.sum()
        total = l_type + self.w_dir * l_dir + self.w_pos * l_pos
        return LossTerms(total, l_type, l_dir, l_pos)

    def _shape_weights(self, batch: GraphBatch, mask: torch.Tensor) -> torch.Tensor:
        """Per-edge weight ``(E,)``: 1, or ``1 / (edges of the same shape in mask)``."""
        ones = torch.ones(mask.shape[0], dtype=torch.float32, device=mask.device)
        if self.balance == "edges":
            return ones
        g = batch.edge_graph
        n = torch.zeros(len(batch.graphs), dtype=torch.float32, device=mask.device)
        n = n.index_add(0, g[mask], ones[mask])
        return 1.0 / n[g].clamp(min=1.0)
