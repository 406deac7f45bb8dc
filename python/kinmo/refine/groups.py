"""Labelled candidate groups of moving edges and their per-joint error measures, shared by
the learned selector's first stage (:mod:`kinmo.refine.fit_selector`) and its position stage
(:mod:`kinmo.refine.position`).

One group is one truly moving edge that an out-of-fold GNN predicts moving: its candidate
lines, their features and labels (:func:`kinmo.refine.fit_selector.collect_groups`). One joint
of the mobility tree is one moving part, whatever the number of its sibling edges, so every
mean here weighs a group by one over its part's group count (:func:`joint_weights`); Table 1's
headline is the mean over categories (:func:`joint_means`).
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from kinmo.io import atomic_path
from kinmo.refine.features import FEATURES

__all__ = ["EdgeGroups", "category_weights", "joint_means", "joint_weights", "selection_error",
           "type_sets"]


@dataclass
class EdgeGroups:
    """Labelled candidate groups of moving edges.

    Attributes
    ----------
    x : list of (C, len(FEATURES)) float64
    y : list of (C,) bool
    angle, dist : list of (C,) float64
        Each candidate's angle (degrees) and line distance (/ shape diagonal) to the truth.
    shape_id, category : list of str
    edge : list of int
    gnn_angle, gnn_dist : list of float
        The GNN's own error on the edge.
    revolute : list of bool
    joint : list of str
        The moving part of each edge, ``"shape_id/node/type set"``. One joint of the mobility
        tree is one moving part, whatever the number of its sibling edges (a drawer touching
        20 panels gives 20 groups), so the per-joint statistics of :func:`kinmo.refine.fit_selector.fit_selector`
        weight each group by one over its part's group count. May be empty (older groups):
        no per-joint statistics then.
    directions : list of (C, 3) float64
        Each candidate's direction (mesh frame), for the position stage
        (:mod:`kinmo.refine.position`). May be empty (older groups): no position stage then.
    """

    x: list[np.ndarray]
    y: list[np.ndarray]
    angle: list[np.ndarray]
    dist: list[np.ndarray]
    shape_id: list[str]
    category: list[str]
    edge: list[int]
    gnn_angle: list[float]
    gnn_dist: list[float]
    revolute: list[bool]
    joint: list[str] = field(default_factory=list)
    directions: list[np.ndarray] = field(default_factory=list)

    @classmethod
    def concat(cls, parts: Sequence[EdgeGroups]) -> EdgeGroups:
        """The groups of ``parts`` one after the other (e.g. the fine and the coarse type set)."""
        return cls(*[[v for part in parts for v in getattr(part, f)]
                     for f in cls.__dataclass_fields__])

    def of_shapes(self, keep: set[str]) -> EdgeGroups:
        """The groups of the shapes in ``keep``, in order."""
        idx = [n for n, s in enumerate(self.shape_id) if s in keep]
        return EdgeGroups(*[[getattr(self, f)[n] for n in idx] if len(getattr(self, f)) else []
                            for f in EdgeGroups.__dataclass_fields__])

    def save(self, path: Path) -> None:
        """Write all groups into one ``.npz`` (ragged arrays concatenated with offsets)."""

        sizes = np.array([len(y) for y in self.y], dtype=np.int64)
        with atomic_path(path) as tmp, open(tmp, "wb") as fh:
            np.savez_compressed(
                fh, x=np.vstack(self.x) if self.x else np.zeros((0, len(FEATURES))),
                y=np.concatenate(self.y) if self.y else np.zeros(0, bool),
                angle=np.concatenate(self.angle) if self.angle else np.zeros(0),
                dist=np.concatenate(self.dist) if self.dist else np.zeros(0),
                sizes=sizes, shape_id=np.array(self.shape_id), category=np.array(self.category),
                edge=np.array(self.edge), gnn_angle=np.array(self.gnn_angle),
                gnn_dist=np.array(self.gnn_dist), revolute=np.array(self.revolute),
                joint=np.array(self.joint),
                directions=np.vstack(self.directions) if self.directions else np.zeros((0, 3)),
                features=np.array(FEATURES))


def joint_weights(groups: EdgeGroups) -> np.ndarray:
    """``(G,) float64``: one over the number of groups of each group's moving part.

    Ones when ``groups.joint`` is empty (groups collected without parts).
    """
    if len(groups.joint) != len(groups.y):
        return np.ones(len(groups.y))
    n_of = Counter(groups.joint)
    return np.array([1.0 / n_of[k] for k in groups.joint], dtype=np.float64)


def category_weights(groups: EdgeGroups, power: float) -> np.ndarray:
    """``(G,) float64``: :func:`joint_weights` times ``n_c ** -power`` (``n_c``: the summed joint
    weight of the group's category), the fit weights of
    :func:`kinmo.refine.fit_selector.fit_selector`."""
    w = joint_weights(groups)
    if power == 0.0 or not groups.category:
        return w
    cat = np.asarray(groups.category)
    total = {c: float(w[cat == c].sum()) for c in set(groups.category)}
    return w * np.array([total[c] for c in groups.category]) ** -float(power)


def type_sets(groups: EdgeGroups) -> list[np.ndarray]:
    """``(G,) bool`` masks of the groups of each type set present (``fine``, then ``coarse``, by
    ``groups.joint``); one all-true mask when the groups carry no parts."""
    if len(groups.joint) != len(groups.y):
        return [np.ones(len(groups.y), bool)]
    sets = [np.array([j.endswith("/" + t) for j in groups.joint]) for t in ("fine", "coarse")]
    sets = [m for m in sets if m.any()]
    return sets or [np.ones(len(groups.y), bool)]


def joint_means(values: np.ndarray, weights: np.ndarray, categories: np.ndarray
                ) -> tuple[float, float]:
    """The weighted mean of one value per group, pooled and as the mean over categories.

    Parameters
    ----------
    values, weights : (G,) float64
        One value per group (an angle in degrees, a line distance / diagonal) and its weight
        (:func:`joint_weights`).
    categories : (G,) str
        Each group's object category.

    Returns
    -------
    (float, float)
        ``sum(w v) / sum(w)`` over all groups, and the mean over the categories (sorted) of
        the same within each category.
    """
    wv = values * weights
    per_cat = [float(wv[categories == c].sum() / weights[categories == c].sum())
               for c in sorted(set(categories))]
    return float(wv.sum() / weights.sum()), float(np.mean(per_cat))


def selection_error(groups: EdgeGroups, angle: np.ndarray) -> dict[str, float]:
    """Per-joint mean angle (degrees) of one value per group: pooled (``all``) and the mean
    over categories (``mean``), each averaged over the type sets (fine, coarse).

    Parameters
    ----------
    groups : EdgeGroups
    angle : (G,) float64
        The angle error of each group's chosen line (or the GNN's own).
    """
    w = joint_weights(groups)
    cat = np.asarray(groups.category)
    pooled, per_cat = [], []
    for m in type_sets(groups):
        p, c = joint_means(np.asarray(angle)[m], w[m], cat[m])
        pooled.append(p)
        per_cat.append(c)
    return {"all": float(np.mean(pooled)), "mean": float(np.mean(per_cat))}
