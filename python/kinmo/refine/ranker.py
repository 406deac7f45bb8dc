"""The learned selector's ranker: a linear listwise score over candidate features, calibrated.

kinmo extension of the refinement of Liu et al. 2023, Sec. 3.3 (step 4 of
:mod:`kinmo.refine.selector`): a linear score ``w . x`` over the standardised features of
:func:`kinmo.refine.selector.candidate_features`, turned into a softmax over the candidates of
one edge (listwise), fit on out-of-fold GNN predictions of training objects
(:func:`fit_ranker`), and a Platt calibration of the winner's probability
(:meth:`Ranker.confidence`, :func:`calibrate`): ``P(selected line within 5° and 0.05 of the
shape's diagonal of the truth)``, the meaning of the pseudo-label threshold, from the winner's
probability and the GNN's axis-candidate mass on the winner's direction (``dir_prior``). The ranker file
(``ranker.json``) also stores the semantic prior (:mod:`kinmo.refine.semantic_prior`).

One file holds a ranker per type set (issue 34): the top-level ranker serves the fine types
(the motion GNN of a model bundle) and ``coarse`` the coarse types (Table 1's ``OBB_coarse``);
:meth:`Ranker.for_types` picks the one for a prediction. The coarse ranker is fit on the groups
of both type sets (:func:`kinmo.refine.fit_selector.fit_type_rankers`). Rankers fit since
issue 34's direction choice pick the likeliest line of the likeliest direction
(:func:`direction_choice`).
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from functools import lru_cache
from pathlib import Path

import numpy as np

from kinmo.data.model import COARSE_TYPES
from kinmo.errors import KinmoDataError
from kinmo.io import write_json
from kinmo.metrics.axis import axis_angle_deg
from kinmo.refine.features import FEATURES, FEATURE_INDEX
from kinmo.refine.semantic_prior import SemanticPrior

__all__ = ["CHOICES", "DIRECTION_TOL_DEG", "Ranker", "calibrate", "direction_choice", "fit_ranker",
           "load_ranker"]

#: How a ranker picks a candidate from its probabilities (:meth:`Ranker.choose`): ``"line"``,
#: the likeliest line; ``"direction"``, the likeliest line of the likeliest direction
#: (:func:`direction_choice`).
CHOICES: tuple[str, ...] = ("line", "direction")

#: Candidate directions within this angle (degrees, up to sign) are one direction for
#: :func:`direction_choice`: the tolerance of a right candidate (``candidate_labels``).
DIRECTION_TOL_DEG = 5.0


def direction_choice(p: np.ndarray, directions: np.ndarray,
                     max_deg: float = DIRECTION_TOL_DEG) -> int:
    """The likeliest line of the direction with the largest probability mass.

    One direction is often offered by several lines (an OBB edge, the centre, an
    interaction-region line) that share its probability, while a wrong direction offered by
    one line keeps all of its own; the arg-max over lines then picks the wrong direction. The
    mass of candidate ``c``'s direction is the sum of ``p`` over the candidates within
    ``max_deg`` of it (up to sign); the direction of largest mass wins (the first candidate's
    on ties), then its likeliest line. kinmo extension of the refinement of Liu et al. 2023,
    Sec. 3.3 (issue 34: out of fold on the 235 labelled objects of the shared data it lowered
    the per-category mean axis error of both Table 1 settings, docs/results/table1_four_settings.md).

    Parameters
    ----------
    p : (C,) float64
        The candidates' probabilities (:meth:`Ranker.probabilities`).
    directions : (C, 3) float64
        The candidates' directions (any frame, any length > 0).
    max_deg : float

    Returns
    -------
    int
        A candidate index.

    Raises
    ------
    ValueError
        ``p`` and ``directions`` differ in length, or are empty.
    """
    p = np.asarray(p, dtype=np.float64).reshape(-1)
    d = np.asarray(directions, dtype=np.float64).reshape(-1, 3)
    if len(p) != len(d) or not len(p):
        raise ValueError(f"direction_choice: {len(p)} probabilities, {len(d)} directions")
    same = np.atleast_2d(axis_angle_deg(d[:, None, :], d[None, :, :])) <= max_deg
    mass = same @ p
    members = np.flatnonzero(same[int(np.argmax(mass))])
    return int(members[int(np.argmax(p[members]))])


@dataclass
class Ranker:
    """Linear listwise ranker of candidate lines with a Platt-calibrated confidence.

    ``p = softmax_c(w . (x_c - mean) / std)`` over the candidates of one edge; the selected
    line is :meth:`choose`'s (the arg-max, or the likeliest line of the likeliest direction);
    its confidence is
    ``sigmoid(a * logit(p_max) + c * log(dir_prior + 1e-3) + b)``, ``dir_prior`` the GNN's
    axis-candidate mass on the selected line's direction (issue 34: on the out-of-fold groups
    of the shared data it tells right directions from wrong ones with an AUC of 0.88, the
    winner's probability alone 0.55, because near-duplicate lines share the probability).

    Attributes
    ----------
    features : tuple of str
        Names of the used features (a subset of :data:`FEATURES`, in that order).
    weights, mean, std : (F,) float64
    platt : (float, float)
        ``(a, b)``; ``(1, 0)`` (and ``prior_weight`` 0) leaves ``p_max`` unchanged.
    meta : dict
        How it was fit (data, folds, seed, validation numbers).
    prior_weight : float
        ``c``; 0 in ranker files written before issue 34.
    semantic : SemanticPrior or None
        The training objects' direction prior behind the ``sem_prior`` features (stored in
        the same file).
    coarse : Ranker or None
        The ranker of coarse-type predictions (:meth:`for_types`), fit on the coarse GNN's
        groups alone; None: this ranker serves both type sets (files written before issue
        34's per-type fit). It shares this ranker's ``semantic``.
    position : Ranker or None
        The second stage of hinge lines (:mod:`kinmo.refine.position`): among the candidates
        parallel to a revolute edge's winner, it re-chooses the line's position. None: the
        winner stands (files written before it, or a fit where it did not help).
    choice : str
        How :meth:`choose` picks the winner (:data:`CHOICES`); ``"line"`` in files written
        before the direction choice.
    """

    features: tuple[str, ...]
    weights: np.ndarray
    mean: np.ndarray
    std: np.ndarray
    platt: tuple[float, float] = (1.0, 0.0)
    meta: dict = field(default_factory=dict)
    semantic: SemanticPrior | None = None
    prior_weight: float = 0.0
    coarse: Ranker | None = None
    position: Ranker | None = None
    choice: str = "line"

    def choose(self, p: np.ndarray, directions: np.ndarray | None = None) -> int:
        """The winner among one edge's candidates: the arg-max of ``p`` (:attr:`choice`
        ``"line"``, or without ``directions``), else :func:`direction_choice`.

        Parameters
        ----------
        p : (C,) float64
            :meth:`probabilities` of the candidates.
        directions : (C, 3) float64, optional
            The candidates' directions.
        """
        if self.choice == "direction" and directions is not None and len(directions):
            return direction_choice(p, directions)
        return int(np.argmax(p))

    def for_types(self, type_names: Sequence[str]) -> Ranker:
        """The ranker for predictions over ``type_names``: :attr:`coarse` (with this ranker's
        semantic prior) for :data:`~kinmo.data.model.COARSE_TYPES` when there is one, else this."""
        if self.coarse is not None and tuple(type_names) == COARSE_TYPES:
            if self.coarse.semantic is None:
                self.coarse.semantic = self.semantic
            return self.coarse
        return self

    def _x(self, x: np.ndarray) -> np.ndarray:
        idx = [FEATURE_INDEX[n] for n in self.features]
        return (np.asarray(x, dtype=np.float64)[:, idx] - self.mean) / self.std

    def scores(self, x: np.ndarray) -> np.ndarray:
        """``(C,) float64`` linear scores ``w . (x - mean) / std`` (features ``(C, len(FEATURES))``)."""
        return self._x(x) @ self.weights

    def probabilities(self, x: np.ndarray) -> np.ndarray:
        """``(C,)`` softmax over the candidates of one edge (features ``(C, len(FEATURES))``)."""
        s = self.scores(x)
        s = s - s.max()
        e = np.exp(s)
        return e / e.sum()

    def confidence(self, p_max: float, dir_prior: float = 1.0) -> float:
        """Calibrated probability that the selected line is right (Platt scaling).

        Parameters
        ----------
        p_max : float
            The winner's probability (:meth:`probabilities`).
        dir_prior : float
            The GNN's axis-candidate mass on the winner's direction (the ``dir_prior``
            feature, in ``[0, 1]``); unused when :attr:`prior_weight` is 0.
        """
        p = min(max(float(p_max), 1e-6), 1 - 1e-6)
        a, b = self.platt
        q = min(max(float(dir_prior), 0.0), 1.0)
        t = a * np.log(p / (1 - p)) + self.prior_weight * np.log(q + 1e-3) + b
        return float(1.0 / (1.0 + np.exp(-t)))

    def to_json(self) -> dict:
        """JSON-ready dict (:func:`load_ranker` reads it back)."""
        out = {"features": list(self.features), "weights": self.weights.tolist(),
               "mean": self.mean.tolist(), "std": self.std.tolist(),
               "platt": list(self.platt), "prior_weight": self.prior_weight, "meta": self.meta}
        if self.choice != "line":
            out["choice"] = self.choice
        if self.semantic is not None:
            out["semantic_prior"] = self.semantic.to_json()
        if self.coarse is not None:
            out["coarse"] = replace(self.coarse, semantic=None, coarse=None).to_json()
        if self.position is not None:
            out["position"] = replace(self.position, semantic=None, coarse=None,
                                      position=None).to_json()
        return out

    def save(self, path: str | Path) -> Path:
        """Write ``path`` (JSON, atomic)."""

        write_json(Path(path), self.to_json())
        return Path(path)


def load_ranker(path: str | Path) -> Ranker:
    """Read a ranker written by :meth:`Ranker.save`.

    Raises
    ------
    KinmoDataError
        Unreadable file, unknown feature names or inconsistent lengths.
    """
    return _load_ranker_cached(str(Path(path).resolve()))


@lru_cache(maxsize=8)
def _load_ranker_cached(path: str) -> Ranker:
    try:
        d = json.loads(Path(path).read_text())
    except (OSError, ValueError) as e:
        raise KinmoDataError(path, f"not a ranker file ({type(e).__name__}: {e})") from None
    ranker = _ranker_from_json(d, path)
    if "coarse" in d:
        if not isinstance(d["coarse"], dict) or "coarse" in d["coarse"]:
            raise KinmoDataError(path, "ranker: 'coarse' must be one ranker")
        ranker.coarse = _ranker_from_json(d["coarse"], path)
        ranker.coarse.semantic = ranker.semantic
    return ranker


def _position_from_json(d: dict, path: str) -> Ranker | None:
    """The ``position`` stage of one ranker's JSON (None without one)."""
    if "position" not in d:
        return None
    p = d["position"]
    if not isinstance(p, dict) or any(k in p for k in ("coarse", "position", "semantic_prior")):
        raise KinmoDataError(path, "ranker: 'position' must be one plain ranker")
    return _ranker_from_json(p, path)


def _ranker_from_json(d: dict, path: str) -> Ranker:
    try:
        feats = tuple(d["features"])
        w, m, s = (np.asarray(d[k], dtype=np.float64) for k in ("weights", "mean", "std"))
        platt = (float(d["platt"][0]), float(d["platt"][1]))
        sem = SemanticPrior.from_json(d["semantic_prior"]) if "semantic_prior" in d else None
        prior_weight = float(d.get("prior_weight", 0.0))
        if not np.isfinite(prior_weight):
            raise ValueError(f"prior_weight {prior_weight}")
        choice = d.get("choice", "line")
        if choice not in CHOICES:
            raise ValueError(f"choice {str(choice)[:40]!r} (expected one of {', '.join(CHOICES)})")
    except (ValueError, KeyError, TypeError, IndexError) as e:
        raise KinmoDataError(path, f"not a ranker file ({type(e).__name__}: {e})") from None
    unknown = [f for f in feats if f not in FEATURE_INDEX]
    if unknown or not (len(feats) == w.size == m.size == s.size):
        raise KinmoDataError(path, f"ranker: unknown features {unknown} or inconsistent lengths")
    return Ranker(feats, w, m, s, platt, d.get("meta", {}), sem, prior_weight,
                  position=_position_from_json(d, path), choice=choice)


def fit_ranker(
    groups: list[tuple[np.ndarray, np.ndarray]],
    *,
    features: tuple[str, ...] = FEATURES,
    l2: float = 1e-2,
    seed: int = 0,
    iters: int = 300,
    weights: Sequence[float] | None = None,
    offsets: Sequence[np.ndarray] | None = None,
) -> Ranker:
    """Fit a :class:`Ranker` by the listwise softmax loss on labelled candidate groups.

    Parameters
    ----------
    groups : list of (x (C, len(FEATURES)) float64, y (C,) bool)
        One group per moving edge; groups without a positive candidate are skipped
        (they carry no ranking information).
    features : tuple of str
        The features used (ablations drop some).
    l2 : float
        Weight decay on the standardised weights.
    seed : int
        Torch seed (the fit is deterministic for a seed: full-batch L-BFGS from zeros).
    iters : int
        L-BFGS iterations.
    weights : sequence of float, optional
        One non-negative weight per group (the loss is the weighted mean over groups; a
        group of weight 0 is left out, also of the standardisation); uniform without.
        :func:`~kinmo.refine.fit_selector.fit_selector` gives each moving part weight one,
        shared by its sibling edges.
    offsets : sequence of (C,) float64, optional
        One fixed score per candidate of each group, added to ``w . x`` (the position stage
        of :mod:`kinmo.refine.position` learns on top of the first stage's log-probability);
        zeros without.

    Returns
    -------
    Ranker
        ``platt`` is ``(1, 0)``; calibrate with :func:`calibrate`.

    Raises
    ------
    ValueError
        No group with a positive candidate, or ``weights`` of another length than
        ``groups``, negative, non-finite or all zero on the used groups.
    """
    import torch

    idx = [FEATURE_INDEX[n] for n in features]
    if weights is None:
        weights = np.ones(len(groups))
    wg = np.asarray(weights, dtype=np.float64).reshape(-1)
    if wg.size != len(groups) or not np.all(np.isfinite(wg)) or np.any(wg < 0):
        raise ValueError(f"fit_ranker: weights must be {len(groups)} finite values >= 0")
    if offsets is not None and (len(offsets) != len(groups) or any(
            np.shape(o) != (len(y),) or not np.all(np.isfinite(o))
            for o, (_, y) in zip(offsets, groups))):
        raise ValueError("fit_ranker: offsets must be one finite (C,) array per group")
    keep = [n for n, (_, y) in enumerate(groups) if len(y) and np.any(y)]
    if not keep:
        raise ValueError("fit_ranker: no group with a positive candidate")
    keep = [n for n in keep if wg[n] > 0]  # weight 0: left out (standardisation too)
    if not keep:
        raise ValueError("fit_ranker: every group with a positive candidate has weight 0")
    use = [(groups[n][0][:, idx], groups[n][1]) for n in keep]
    wg = wg[keep]
    allx = np.vstack([x for x, _ in use])
    mean = allx.mean(axis=0)
    std = allx.std(axis=0)
    std = np.where(std > 1e-9, std, 1.0)
    torch.manual_seed(seed)
    xs = torch.from_numpy((allx - mean) / std)
    ys = torch.from_numpy(np.concatenate([y for _, y in use]).astype(bool))
    off = torch.from_numpy(np.concatenate([np.asarray(offsets[n], np.float64) for n in keep])
                           if offsets is not None else np.zeros(len(ys)))
    sizes = [len(y) for _, y in use]
    gid = torch.repeat_interleave(torch.arange(len(sizes)), torch.tensor(sizes))
    w = torch.zeros(len(idx), dtype=torch.float64, requires_grad=True)
    opt = torch.optim.LBFGS([w], lr=1.0, max_iter=iters, line_search_fn="strong_wolfe")
    n_g = len(sizes)
    gw = torch.from_numpy(wg / wg.sum())

    def loss_fn() -> torch.Tensor:
        opt.zero_grad()
        s = xs @ w + off
        mx = torch.zeros(n_g, dtype=s.dtype).scatter_reduce(0, gid, s, "amax", include_self=False)
        e = torch.exp(s - mx[gid])
        tot = torch.zeros(n_g, dtype=s.dtype).index_add(0, gid, e)
        pos = torch.zeros(n_g, dtype=s.dtype).index_add(0, gid, e * ys)
        logp = torch.log(pos.clamp_min(1e-300)) - torch.log(tot)
        loss = -(logp * gw).sum() + l2 * (w * w).sum()
        loss.backward()
        return loss

    opt.step(loss_fn)
    return Ranker(tuple(features), w.detach().numpy().copy(), mean, std)


def calibrate(p_max: np.ndarray, correct: np.ndarray, dir_prior: np.ndarray | None = None
              ) -> tuple[float, float] | tuple[float, float, float]:
    """Platt scaling: ``P(correct) = sigmoid(a logit(p_max) [+ c log(dir_prior + 1e-3)] + b)``.

    Parameters
    ----------
    p_max : (N,) float
        The ranker's winning probability on held-out edges.
    correct : (N,) bool
        Whether the winner was right.
    dir_prior : (N,) float, optional
        The GNN's axis-candidate mass on each winner's direction; with it ``c`` is fit too.

    Returns
    -------
    (a, b), or (a, b, c) with ``dir_prior``
        ``(1, 0[, 0])`` when the data cannot be fit (fewer than 2 edges or one class only).
    """
    from scipy.optimize import minimize

    p = np.clip(np.asarray(p_max, dtype=np.float64), 1e-6, 1 - 1e-6)
    y = np.asarray(correct, dtype=np.float64)
    q = None if dir_prior is None else np.log(np.clip(np.asarray(dir_prior, np.float64), 0, 1) + 1e-3)
    if p.size < 2 or y.min() == y.max():
        return (1.0, 0.0) if q is None else (1.0, 0.0, 0.0)
    z = np.log(p / (1 - p))

    def nll(ab: np.ndarray) -> float:
        t = ab[0] * z + ab[1] + (ab[2] * q if q is not None else 0.0)
        return float(np.sum(np.logaddexp(0, t) - y * t) + 1e-3 * (ab @ ab))

    x0 = np.array([1.0, 0.0] if q is None else [1.0, 0.0, 0.0])
    res = minimize(nll, x0, method="Nelder-Mead",
                   options={"xatol": 1e-6, "fatol": 1e-9, "maxiter": 4000})
    return tuple(float(v) for v in res.x)  # type: ignore[return-value]
