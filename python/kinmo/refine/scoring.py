"""Scores of candidate axes and the selection of the best one (Liu et al. 2023, Sec. 3.3).

Every candidate line ``c`` of a moving part gets

.. math::

    s_c = \\frac{w_f\\, s_f + w_d\\, s_d + w_p\\, s_p}{w_f + w_d + w_p}

- ``s_f``, **feasibility**: the axis-selection network's probability that moving the part
  about / along the line is plausible (:class:`kinmo.refine.axis_net.AxisSelectionNet`); the
  better of the line's two directions, averaged over the tried amounts
  (:func:`line_feasibility`);
- ``s_d``, **direction agreement**: ``|cos|`` of the angle between the line and the GNN's
  predicted axis direction (a line has no sign);
- ``s_p``, **position agreement** (revolute and ``PR`` only; 1 for prismatic motions, whose
  axis has no position): with ``d`` the distance from the GNN's predicted axis point to the
  line and ``L`` the moving part's OBB diagonal, ``exp(-d / (sigma L))`` (``"exp"``) or
  ``1 - min(d / (sigma L), 1)`` (``"linear"``).

The paper's weights are ``w_f, w_d, w_p = 0.5, 0.3, 0.2`` (they sum to 1, so the division
changes nothing; it keeps any configured weights' score in ``[0, 1]``). The paper's released
code selects by feasibility alone: ``feasibility_only=True`` gives ``s_c = s_f``. The best
candidate (ties: the first) wins and its score is the joint's confidence, compared against the
pseudo-label threshold (:mod:`kinmo.pseudo_label`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, model_validator

__all__ = [
    "CandidateScores",
    "ScoringConfig",
    "combine_scores",
    "direction_agreement",
    "line_feasibility",
    "position_agreement",
    "score_candidates",
]


class ScoringConfig(BaseModel):
    """Weights and options of the candidate score.

    Attributes
    ----------
    w_feasibility, w_direction, w_position : float
        Non-negative weights, not all zero (paper: 0.5, 0.3, 0.2).
    feasibility_only : bool
        Score by the network alone (the paper's released code).
    position : {"exp", "linear"}
        Shape of the position agreement.
    sigma : float
        Length scale of the position agreement, relative to the moving part's OBB diagonal.
    """

    model_config = ConfigDict(extra="forbid")

    w_feasibility: float = Field(0.5, ge=0.0)
    w_direction: float = Field(0.3, ge=0.0)
    w_position: float = Field(0.2, ge=0.0)
    feasibility_only: bool = False
    position: Literal["exp", "linear"] = "exp"
    sigma: float = Field(0.25, gt=0.0)

    @model_validator(mode="after")
    def _some_weight(self) -> ScoringConfig:
        if self.w_feasibility + self.w_direction + self.w_position <= 0:
            raise ValueError("scoring weights: at least one weight must be positive")
        return self


def _unit(d: np.ndarray, name: str) -> np.ndarray:
    d = np.asarray(d, dtype=np.float64)
    n = np.linalg.norm(d, axis=-1, keepdims=True)
    if d.shape[-1:] != (3,) or not np.all(np.isfinite(d)) or np.any(n <= 0):
        raise ValueError(f"{name}: expected finite non-zero (..., 3) directions, got shape {d.shape}")
    return d / n


def direction_agreement(directions: np.ndarray, gnn_direction: np.ndarray) -> np.ndarray:
    """``|cos|`` between candidate lines and the GNN's axis direction.

    Parameters
    ----------
    directions : (C, 3) float
    gnn_direction : (3,) float
        Any non-zero length.

    Returns
    -------
    (C,) float64 in ``[0, 1]``.
    """
    return np.clip(np.abs(_unit(directions, "directions") @ _unit(gnn_direction, "gnn_direction")),
                   0.0, 1.0)


def position_agreement(
    origins: np.ndarray,
    directions: np.ndarray,
    gnn_point: np.ndarray,
    length_scale: float,
    sigma: float = 0.25,
    mode: str = "exp",
) -> np.ndarray:
    """Agreement of candidate lines with the GNN's predicted axis point.

    Parameters
    ----------
    origins, directions : (C, 3) float
        Candidate lines.
    gnn_point : (3,) float
        The GNN's point on the axis (mesh frame).
    length_scale : float
        ``L``, the moving part's OBB diagonal (> 0).
    sigma : float
        Relative length scale.
    mode : {"exp", "linear"}

    Returns
    -------
    (C,) float64 in ``[0, 1]``: ``exp(-d / (sigma L))`` or ``1 - min(d / (sigma L), 1)``.
    """
    o = np.asarray(origins, dtype=np.float64).reshape(-1, 3)
    u = _unit(np.asarray(directions).reshape(-1, 3), "directions")
    p = np.asarray(gnn_point, dtype=np.float64)
    if p.shape != (3,) or not np.all(np.isfinite(p)):
        raise ValueError(f"gnn_point: expected 3 finite numbers, got {gnn_point!r}")
    if not length_scale > 0:
        raise ValueError(f"length_scale: expected > 0, got {length_scale}")
    d = np.linalg.norm(np.cross(p - o, u), axis=1) / (sigma * length_scale)
    if mode == "exp":
        return np.exp(-d)
    if mode == "linear":
        return 1.0 - np.minimum(d, 1.0)
    raise ValueError(f"mode: expected 'exp' or 'linear', got {mode!r}")


def combine_scores(
    s_f: np.ndarray, s_d: np.ndarray, s_p: np.ndarray, config: ScoringConfig | None = None
) -> np.ndarray:
    """The combined score ``(w_f s_f + w_d s_d + w_p s_p) / (w_f + w_d + w_p)``, or ``s_f``.

    Parameters
    ----------
    s_f, s_d, s_p : (C,) float
        Feasibility, direction and position agreement.
    config : ScoringConfig, optional

    Returns
    -------
    (C,) float64
    """
    cfg = config or ScoringConfig()
    s_f = np.asarray(s_f, dtype=np.float64)
    if cfg.feasibility_only:
        return s_f.copy()
    w = cfg.w_feasibility + cfg.w_direction + cfg.w_position
    return (cfg.w_feasibility * s_f + cfg.w_direction * np.asarray(s_d, dtype=np.float64)
            + cfg.w_position * np.asarray(s_p, dtype=np.float64)) / w


def line_feasibility(
    motion_scores: np.ndarray, line: np.ndarray, sign: np.ndarray, n_lines: int
) -> tuple[np.ndarray, np.ndarray]:
    """Feasibility of each candidate line from the scores of its motions.

    The motions of one line and direction (several amounts) are averaged; the line takes
    the better direction.

    Parameters
    ----------
    motion_scores : (M,) float
        Network feasibility of each motion.
    line, sign : (M,) int
        Line index and direction sign (±1) of each motion
        (:class:`kinmo.refine.motions.CandidateMotions`).
    n_lines : int
        ``C``.

    Returns
    -------
    feasibility : (C,) float64
        0 for lines without motions.
    sign : (C,) int64
        The better direction (+1 when tied or without motions).
    """
    s = np.asarray(motion_scores, dtype=np.float64)
    line = np.asarray(line, dtype=np.int64)
    sign = np.asarray(sign, dtype=np.int64)
    means = np.zeros((n_lines, 2))
    for col, sg in enumerate((1, -1)):
        m = sign == sg
        tot = np.bincount(line[m], weights=s[m], minlength=n_lines)
        cnt = np.bincount(line[m], minlength=n_lines)
        means[:, col] = np.where(cnt > 0, tot / np.maximum(cnt, 1), 0.0)
    best = np.where(means[:, 1] > means[:, 0], -1, 1).astype(np.int64)
    return means.max(axis=1), best


@dataclass(frozen=True)
class CandidateScores:
    """Scores of ``C`` candidate lines and the selection.

    Attributes
    ----------
    feasibility, direction, position, total : (C,) float64
        ``s_f``, ``s_d``, ``s_p`` and the combined score.
    sign : (C,) int64
        Direction sign of each line judged feasible (±1).
    best : int
        Index of the winning candidate (-1 when there are none).
    """

    feasibility: np.ndarray
    direction: np.ndarray
    position: np.ndarray
    total: np.ndarray
    sign: np.ndarray
    best: int

    @property
    def confidence(self) -> float:
        """The winner's combined score (NaN without candidates)."""
        return float(self.total[self.best]) if self.best >= 0 else float("nan")


def score_candidates(
    origins: np.ndarray,
    directions: np.ndarray,
    feasibility: np.ndarray,
    gnn_direction: np.ndarray,
    gnn_point: np.ndarray | None,
    length_scale: float,
    revolute: bool,
    config: ScoringConfig | None = None,
    sign: np.ndarray | None = None,
) -> CandidateScores:
    """Score candidate lines and select the best (see the module docstring).

    Parameters
    ----------
    origins, directions : (C, 3) float
        Candidate lines (mesh frame).
    feasibility : (C,) float
        ``s_f`` per line (:func:`line_feasibility`).
    gnn_direction : (3,) float
        The GNN's axis direction.
    gnn_point : (3,) float or None
        The GNN's axis point; required when ``revolute``.
    length_scale : float
        The moving part's OBB diagonal (mesh units).
    revolute : bool
        The motion rotates (R or PR): position agreement counts; otherwise ``s_p = 1``.
    config : ScoringConfig, optional
    sign : (C,) int, optional
        Feasible direction of each line (default +1).

    Returns
    -------
    CandidateScores
    """
    cfg = config or ScoringConfig()
    o = np.asarray(origins, dtype=np.float64).reshape(-1, 3)
    c = o.shape[0]
    s_f = np.asarray(feasibility, dtype=np.float64).reshape(-1)
    if s_f.shape[0] != c:
        raise ValueError(f"feasibility: expected {c} values, got {s_f.shape[0]}")
    if c == 0:
        z = np.zeros(0)
        return CandidateScores(z, z, z, z, np.zeros(0, dtype=np.int64), -1)
    s_d = direction_agreement(directions, gnn_direction)
    if revolute:
        if gnn_point is None:
            raise ValueError("gnn_point: required for revolute motions")
        s_p = position_agreement(o, directions, gnn_point, length_scale, cfg.sigma, cfg.position)
    else:
        s_p = np.ones(c)
    total = combine_scores(s_f, s_d, s_p, cfg)
    sg = np.ones(c, dtype=np.int64) if sign is None else np.asarray(sign, dtype=np.int64)
    return CandidateScores(s_f, s_d, s_p, total, sg, int(np.argmax(total)))
