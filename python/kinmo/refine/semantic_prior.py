"""A category-level prior on axis directions from the labelled objects' part names.

kinmo extension of the refinement of Liu et al. 2023, Sec. 3.3. The motion GNN sees geometry
only; a microwave door predicted with a horizontal hinge (an oven's) sweeps freely either way,
so neither the GNN nor the swept collision can repair the 90° flip. The labelled training
objects can: PartNet and PartNet-Mobility shapes are canonically aligned (y-up, a common
front) and name their parts (``door``, ``drawer``, ``switch``, ``button``), so the share of
training joints of the same motion, category and part names whose axis is parallel to a
candidate line is a prior on that line's direction.

The estimate backs off through ever coarser keys (Bayesian smoothing with ``alpha`` pseudo
counts at each level)::

    (motion, category, moving name, reference name)
      -> (motion, category, moving name) -> (motion, moving name) -> (motion) -> 1/3

where ``motion`` is ``"R"`` (revolute and revolute-prismatic) or ``"P"`` (prismatic). A shape
can be left out of its own prior (``exclude``), which the out-of-fold ranker fit needs.

Frames: mesh frame (y-up); directions are unit vectors, sign-free.
"""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from kinmo.data.frames import quarter_turn
from kinmo.data.graph import PartGraph
from kinmo.data.model import FINE_TYPES

__all__ = ["SemanticPrior", "motion_of"]

#: A training axis counts for a candidate line when they are within this angle.
PARALLEL_DEG: float = 15.0
_BASE = 1.0 / 3.0


def motion_of(type_name: str) -> str:
    """``"P"`` for ``P_*`` types, ``"R"`` for revolute and revolute-prismatic ones."""
    return "P" if type_name.startswith("P") and not type_name.startswith("PR") else "R"


def _norm(name: str) -> str:
    return name.strip().lower().replace(" ", "_")


@dataclass
class SemanticPrior:
    """Training joints' axis directions indexed by motion, category and part names.

    Attributes
    ----------
    joints : list of (shape_id, motion, category, moving name, reference name, (3,) direction)
        One entry per labelled moving sibling edge of the training objects (mesh frame).
    alpha : float
        Pseudo counts of the smoothing towards the next coarser key.
    parallel_deg : float
        Tolerance of "parallel" (degrees).
    """

    joints: list[tuple[str, str, str, str, str, np.ndarray]] = field(default_factory=list)
    alpha: float = 2.0
    parallel_deg: float = PARALLEL_DEG

    def __post_init__(self) -> None:
        self._index()

    def _index(self) -> None:
        self._levels: list[dict[tuple, list[int]]] = [defaultdict(list) for _ in range(4)]
        for n, (_, mo, cat, mv, rf, _) in enumerate(self.joints):
            for lv, key in enumerate(self._keys(mo, cat, mv, rf)):
                self._levels[lv][key].append(n)
        self._dirs = (np.array([j[5] for j in self.joints], dtype=np.float64).reshape(-1, 3))
        self._shapes = np.array([j[0] for j in self.joints], dtype=object)

    @staticmethod
    def _keys(motion: str, category: str, moving: str, reference: str) -> list[tuple]:
        c, m, r = _norm(category), _norm(moving), _norm(reference)
        return [(motion,), (motion, m), (motion, c, m), (motion, c, m, r)]

    @classmethod
    def from_graphs(cls, graphs: Iterable[PartGraph], alpha: float = 2.0,
                    parallel_deg: float = PARALLEL_DEG) -> SemanticPrior:
        """Collect the moving sibling edges of labelled graphs (``edge_fine`` set).

        Parameters
        ----------
        graphs : iterable of PartGraph
            The training objects only (never the test split).
        alpha, parallel_deg : float

        Returns
        -------
        SemanticPrior
        """
        joints = []
        for g in graphs:
            if g.edge_fine is None or g.edge_axis_direction is None:
                continue
            for k, (i, j) in enumerate(np.asarray(g.sibling_edges).reshape(-1, 2)):
                t = FINE_TYPES[int(g.edge_fine[k])]
                if t in ("Fixed", "None"):
                    continue
                d = np.asarray(g.edge_axis_direction[k], dtype=np.float64)
                n = float(np.linalg.norm(d))
                if not np.isfinite(n) or n < 1e-9:
                    continue
                joints.append((g.shape_id, motion_of(t), g.category, g.node_names[int(i)],
                               g.node_names[int(j)], d / n))
        return cls(joints, alpha, parallel_deg)

    def probability(self, motion: str, category: str, moving: str, reference: str,
                    directions: np.ndarray, exclude: str | None = None, turns: bool = False) -> np.ndarray:
        """Smoothed share of matching training joints parallel to each direction.

        Parameters
        ----------
        motion : {"R", "P"}
        category, moving, reference : str
            The shape's category and the moving / reference parts' semantic names.
        directions : (C, 3) float64
            Candidate directions (mesh frame; need not be unit).
        exclude : str, optional
            A shape id whose own joints are left out (out-of-fold fits).
        turns : bool
            The object's facing is unknown (an object without known part names, whose GNN
            answer is the average of its four quarter turns, :mod:`kinmo.inference.gnn`):
            the mean of the prior over the four quarter turns of each direction about the
            vertical, since the training objects' shared front is part of what it learned.

        Returns
        -------
        (C,) float64 in (0, 1)
        """
        d = np.asarray(directions, dtype=np.float64).reshape(-1, 3)
        if turns:
            return np.mean([self.probability(motion, category, moving, reference, d @ quarter_turn(q).T,
                                             exclude) for q in range(4)], axis=0)
        d = d / np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-12)
        cos_t = float(np.cos(np.radians(self.parallel_deg)))
        p = np.full(d.shape[0], _BASE)
        for lv, key in enumerate(self._keys(motion, category, moving, reference)):
            idx = np.asarray(self._levels[lv].get(key, ()), dtype=np.int64)
            if exclude is not None and idx.size:
                idx = idx[self._shapes[idx] != exclude]
            if idx.size == 0:
                continue
            hits = (np.abs(d @ self._dirs[idx].T) >= cos_t).sum(axis=1)
            p = (hits + self.alpha * p) / (idx.size + self.alpha)
        return p

    def to_json(self) -> dict[str, Any]:
        """JSON-serialisable form (stored inside ``ranker.json``)."""
        return {"alpha": self.alpha, "parallel_deg": self.parallel_deg,
                "joints": [[s, mo, c, m, r, [round(float(v), 6) for v in d]]
                           for s, mo, c, m, r, d in self.joints]}

    @classmethod
    def from_json(cls, blob: dict[str, Any]) -> SemanticPrior:
        """Inverse of :meth:`to_json`.

        Raises
        ------
        KeyError, ValueError
            On a malformed blob (the caller names the file).
        """
        joints = [(str(s), str(mo), str(c), str(m), str(r), np.asarray(d, dtype=np.float64))
                  for s, mo, c, m, r, d in blob["joints"]]
        for j in joints:
            if j[1] not in ("R", "P") or j[5].shape != (3,):
                raise ValueError(f"bad semantic prior joint {j[:5]}")
        return cls(joints, float(blob.get("alpha", 2.0)),
                   float(blob.get("parallel_deg", PARALLEL_DEG)))

    def __len__(self) -> int:
        return len(self.joints)
