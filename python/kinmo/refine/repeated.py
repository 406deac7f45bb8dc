"""Repeated parts move alike: a vote among the learned selector's choices (kinmo extension).

Keys of a keyboard, buttons of a remote or a coffee machine, a column of drawers: parts of
one shape that are copies of each other, attached to the same reference part and predicted
the same motion type, move about or along the same direction. The learned selector
(:func:`kinmo.refine.edge.select_edge`) decides every moving edge alone, and on a part whose
category it has not been trained on its geometric terms can turn some copies and not others:
out of fold (issue 34, ``docs/results/table1_four_settings.md``), the only keyboard of the
shared data had 43 % of its 115 keys turned off the GNN's (right) vertical direction by the
coarse selector.

The rule, after every edge has been selected:

1. **Groups.** Refined edges with the same reference part and predicted type, whose moving
   parts' OBB half extents (sorted) agree within ``extent_tol`` relative to the larger, are
   copies; groups of at least ``min_group`` edges vote (two doors of a cabinet are left to
   the selector).
2. **Vote.** Directions are compared in each member's own OBB frame (axes ordered by half
   extent, signs dropped), so copies turned about the shape, like a box's four flaps, vote
   alike. Every direction among the members' candidates (within ``angle_deg``) gets the
   sum over members of each member's support for it: the member's highest ranker
   probability for a candidate in that direction, or, for a ranker that chooses by
   direction (:func:`kinmo.refine.ranker.direction_choice`, ``mass``), the sum of its
   probabilities over its candidates in that direction, within the same angle as that
   choice (``mass`` degrees): the quantity the member's own choice compares. The direction with the largest sum wins: the selector's evidence
   pooled over the copies, where each copy alone may be unsure (a key's 19 candidates
   share the probability, 0.15 at most). With the highest probability instead of the mass,
   a wrong direction offered by one line outvoted the right one offered by several lines
   that each member's own choice had picked (session 24: out of fold, a phone's three
   buttons turned off their right direction).
3. **Follow.** A member off the winning direction takes its own most probable candidate
   within ``angle_deg`` of it (its line's position stays its own), with that candidate's
   calibrated confidence; a member without such a candidate keeps its choice.

With the selector's sweep vetoes on (``slide_veto``), a slider's lines that the slide veto
rules out (:func:`kinmo.refine.edge.vetoed_slides`: blocked, while one of its horizontal
lines is free) neither support a direction nor are followed: the vote pools the selector's
evidence, it does not undo what the sweep decided (session 24: a table's six drawers, each
turned by the veto from a blocked sideways line to its free front one, were turned back by
the mass of their two sideways lines).

Frames: mesh frame, like the predictions. Directions are unit (3,) float64 vectors.
Cost: edges are bucketed by (reference part, type) first, so grouping is linear in the
refined edges times the groups of one bucket.
"""

from __future__ import annotations

from typing import Callable, Sequence

import numpy as np

from kinmo.data.graph import PartGraph
from kinmo.refine.edge import EdgeRefinement, switched_line, vetoed_slides

__all__ = ["repeated_groups", "vote_repeated"]


def repeated_groups(graph: PartGraph, edges: np.ndarray, types: Sequence[str],
                    members: Sequence[int], *, extent_tol: float = 0.25,
                    min_group: int = 3) -> list[list[int]]:
    """Groups of copies among the edges ``members`` (step 1 of the module's rule).

    Parameters
    ----------
    graph : PartGraph
    edges : (E, 2) int64
        (moving, reference) node of every edge.
    types : sequence of str
        Predicted type of every edge.
    members : sequence of int
        The edges that may vote (the refined ones).
    extent_tol : float
        Largest relative difference of a sorted OBB half extent between copies.
    min_group : int
        Smallest group returned.

    Returns
    -------
    list of list of int
        Edge indices, each group in ascending order; groups in order of their first edge.
    """
    buckets: dict[tuple[int, str], list[int]] = {}
    for k in sorted(int(m) for m in members):
        buckets.setdefault((int(edges[k, 1]), types[k]), []).append(k)
    groups: list[list[int]] = []
    for ks in buckets.values():
        if len(ks) < min_group:
            continue
        ext = np.sort(np.asarray(graph.obb_half_extents, float)[edges[ks, 0]], axis=1)
        reps: list[int] = []  # row of each group's first member
        mine: list[list[int]] = []
        for n, k in enumerate(ks):
            if reps:
                r = ext[reps]
                tol = extent_tol * np.maximum(np.maximum(r, ext[n]), 1e-12)
                close = np.all(np.abs(r - ext[n]) <= tol, axis=1)
                if close.any():
                    mine[int(np.argmax(close))].append(k)
                    continue
            reps.append(n)
            mine.append([k])
        groups += mine
    groups.sort(key=lambda g: g[0])
    return [g for g in groups if len(g) >= min_group]


def _local(graph: PartGraph, node: int, directions: np.ndarray) -> np.ndarray:
    """Directions ``(C, 3)`` in the part's OBB frame, axes ordered by half extent, signs
    dropped: copies turned or mirrored about the shape (a box's four flaps) compare equal."""
    rows = np.asarray(graph.obb_axes[node], float)  # (3, 3): one axis per row
    rows = rows[np.argsort(graph.obb_half_extents[node], kind="stable")]
    return np.abs(np.asarray(directions, float) @ rows.T)


def vote_repeated(graph: PartGraph, edges: np.ndarray, types: Sequence[str],
                  details: dict[int, EdgeRefinement],
                  confidence: Callable[[float, float], float], *, extent_tol: float = 0.25,
                  min_group: int = 3, angle_deg: float = 10.0,
                  mass: float | None = None, slide_veto: bool = False) -> dict[int, EdgeRefinement]:
    """Apply the module's rule to the learned selector's choices.

    Parameters
    ----------
    graph : PartGraph
    edges : (E, 2) int64
    types : sequence of str
        Predicted type of every edge.
    details : dict of int to EdgeRefinement
        The selector's result per refined edge (``scores.total``: the ranker's probabilities;
        ``dir_prior``: the GNN's direction prior per candidate).
    confidence : callable (p, dir_prior) -> float
        The ranker's calibrated confidence (:meth:`kinmo.refine.ranker.Ranker.confidence`).
    extent_tol, min_group : see :func:`repeated_groups`
    angle_deg : float
        Directions within this angle (up to sign) are the same.
    mass : float, optional
        Degrees: a member supports a direction with its probability mass there (the sum
        over its candidates within ``mass`` degrees of it), as a ranker choosing by
        direction compares them (:data:`kinmo.refine.ranker.DIRECTION_TOL_DEG`); the
        voting directions are then also told apart at ``mass`` degrees. None: a member
        supports a direction with its most probable candidate within ``angle_deg``.
    slide_veto : bool
        Leave out the lines the selector's slide veto rules out (module docs).

    Returns
    -------
    dict of int to EdgeRefinement
        The edges whose choice changed, with their new refinement (``voted`` True).
    """
    cos = float(np.cos(np.radians(angle_deg)))
    same = cos if mass is None else float(np.cos(np.radians(mass)))  # one voting direction
    valid = [k for k, r in details.items() if r.scores.best >= 0 and not r.abstained and not r.deferred]
    changed: dict[int, EdgeRefinement] = {}
    for group in repeated_groups(graph, edges, types, valid, extent_tol=extent_tol,
                                 min_group=min_group):
        local = {k: _local(graph, int(edges[k, 0]), details[k].candidates.directions)
                 for k in group}
        allowed = {k: ~vetoed_slides(details[k].candidates, details[k].free) if slide_veto
                   else np.ones(len(local[k]), dtype=bool) for k in group}
        reps = np.zeros((0, 3))
        for k in group:
            for d in local[k]:
                if not (reps @ d >= same).any():
                    reps = np.vstack([reps, d])
        support = np.zeros(len(reps))
        for k in group:
            near = (local[k] @ reps.T >= same) & allowed[k][:, None]  # (C, U)
            p = np.where(near, details[k].scores.total[:, None], 0.0)
            support += p.max(0) if mass is None else p.sum(0)
        win = reps[int(np.argmax(support))]
        for k in group:
            r = details[k]
            if float(local[k][r.scores.best] @ win) >= cos:  # its chosen line is a candidate
                continue
            ok = (local[k] @ win >= cos) & allowed[k]
            if not ok.any():
                continue
            b = int(np.argmax(np.where(ok, r.scores.total, -np.inf)))
            changed[k] = switched_line(graph, int(edges[k, 0]), r, b, confidence, voted=True)
    return changed
