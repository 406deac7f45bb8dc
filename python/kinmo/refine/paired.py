"""Paired doors open from the middle: a rule on the learned selector's hinge lines (kinmo extension).

A cabinet with two doors side by side, a wardrobe, a box with two flaps that meet: the two
parts are mirror images, and each turns about its *outer* edge, so that both open from the
seam between them. The learned selector (:func:`kinmo.refine.edge.select_edge`) decides every
moving edge alone, and the two edge lines of a door parallel to its hinge are often close in
its ranking: the swept test turns a door freely about either, and the door's own shape is
symmetric. It then sometimes puts one door's hinge at the seam (issue 35, session 35: test
StorageFurniture 45332's right door, whose predicted range opened the wrong way, IoU 0;
out of fold on fold seeds 1 and 2, a door of StorageFurniture 45001, 45332 and 45463 and of
Table 31249).

Over the true joints of all 235 shared PartNet-Mobility objects, steps 1 and 2 below find
31 pairs (of edges, on 9 cabinets), and every one is hinged at its outer edges (session 35;
``tests/refine/test_paired.py`` checks it on those cabinets). Refrigerator 11709's three
doors, hinged alike, form no pair (step 2).

The rule, after every edge has been selected (and after :mod:`kinmo.refine.repeated`):

1. **Pairs.** Two refined revolute edges (fine types other than a centre pivot ``R_*_C``)
   with the same reference part and different moving parts ``a`` and ``b`` are a pair when:
   their chosen directions ``d`` agree within ``angle_deg`` (up to sign); the parts' sorted
   OBB half extents agree within ``extent_tol`` of the larger; their centres lie at about the
   same height along ``d`` (within ``height_tol`` of the smaller half extent along ``d``);
   they lie in one plane (their thinnest OBB axes agree within ``plane_deg``, and their
   centres lie within ``plane_tol`` of ``w_a + w_b`` of each other along it: a box's top flap
   and the side wall below it are no pair; the doors of StorageFurniture 49182 are modelled
   6° ajar, each its own way); and they sit side by side across ``d``: with ``u`` the unit vector from ``a``'s centre to
   ``b``'s across ``d``, and ``w`` each part's half width along ``u`` (from its points), the
   centres lie between ``side_min`` and ``side_max`` times ``w_a + w_b`` apart.
2. **One neighbour.** A part paired with more than one other part (a row of three or more
   doors) is left alone.
3. **Hinge lines.** A chosen line at least ``edge_min`` of its part's half width along ``u``
   off its centre is a hinge line. Two centre lines give nothing to go by, and the pair is
   left alone. A centre line beside a hinge on its part's outer edge (after step 4) moves
   like a seam line: the side-pivoted door of a pair turns about its outer edge too.
4. **Outer.** A member whose line lies on the seam's side of its centre (``a`` towards ``b``,
   or ``b`` towards ``a``) takes its most probable candidate within ``angle_deg`` of its
   chosen direction whose line lies at least ``edge_min`` of its half width on the other
   side; without such a candidate it keeps its choice. Only the line moves: the direction
   stays the one the selector chose, and so does the calibrated confidence. The candidate's
   own confidence would understate what the pair knows: with it, PartNet cabinet 46166,
   whose seam hinge the rule corrected, fell below the pseudo-label threshold.

Frames: mesh frame, like the predictions. Directions are unit (3,) float64 vectors; points
and centres in mesh units. Cost: pairs are looked for among edges bucketed by reference
part, quadratic in a bucket's revolute edges (a few doors).
"""

from __future__ import annotations

from dataclasses import replace
from typing import NamedTuple, Sequence

import numpy as np

from kinmo.data.graph import PartGraph
from kinmo.refine.edge import EdgeRefinement, chosen_line

__all__ = ["DoorPair", "door_pairs", "open_from_the_middle"]


class DoorPair(NamedTuple):
    """Two refined edges whose moving parts are side-by-side mirror parts (:func:`door_pairs`)."""

    k: int
    """Edge of part ``a`` (the smaller edge index)."""
    l: int
    """Edge of part ``b``, with the same reference part."""
    u: np.ndarray
    """(3,) float64: unit vector from ``a``'s OBB centre to ``b``'s, across ``k``'s direction."""
    width_k: float
    """Half width of ``a``'s points along ``u`` (mesh units)."""
    width_l: float
    """Half width of ``b``'s points along ``u`` (mesh units)."""


def _hinged(kind: str) -> bool:
    """A revolute type that may turn about a side line (coarse ``R`` or fine ``R_*_S``)."""
    return kind.split("_")[0] == "R" and not kind.endswith("_C")


def _across(v: np.ndarray, d: np.ndarray) -> np.ndarray:
    """The part of ``(..., 3)`` vectors ``v`` perpendicular to the unit direction ``d``."""
    return v - (v @ d)[..., None] * d


def door_pairs(graph: PartGraph, edges: np.ndarray, types: Sequence[str],
               details: dict[int, EdgeRefinement], *, angle_deg: float = 10.0,
               extent_tol: float = 0.2, height_tol: float = 0.5, plane_deg: float = 30.0,
               plane_tol: float = 0.25, side_min: float = 0.8, side_max: float = 1.3) -> list[DoorPair]:
    """Pairs of side-by-side mirror parts (steps 1 and 2 of the module's rule).

    Parameters
    ----------
    graph : PartGraph
        Needs ``points`` ((V, P, 3) float64), ``obb_center``, ``obb_axes`` ((V, 3, 3), one
        axis per row) and ``obb_half_extents``.
    edges : (E, 2) int64
        (moving, reference) node of every edge.
    types : sequence of str
        Predicted type of every edge.
    details : dict of int to EdgeRefinement
        The selector's result per refined edge.
    angle_deg, extent_tol, height_tol, plane_deg, plane_tol, side_min, side_max : float
        See the module docs.

    Returns
    -------
    list of DoorPair
        In order of ``k``, then ``l``; ``k < l``.

    Cost: quadratic in the hinged edges of one reference part, but a pair's points are read
    only when the OBBs leave it possible (each part's centred points once).
    """
    cos = float(np.cos(np.radians(angle_deg)))
    flat = float(np.cos(np.radians(plane_deg)))
    valid = [k for k, r in sorted(details.items())
             if r.scores.best >= 0 and not r.abstained and _hinged(types[k])]
    buckets: dict[int, list[int]] = {}
    for k in valid:
        buckets.setdefault(int(edges[k, 1]), []).append(k)
    centre = np.asarray(graph.obb_center, float)
    half = np.asarray(graph.obb_half_extents, float)
    ext = np.sort(half, axis=1)
    thin = np.asarray(graph.obb_axes, float)[np.arange(len(half)), np.argmin(half, axis=1)]
    reach = np.linalg.norm(half, axis=1)  # bounds any half width of the part's points
    local: dict[int, np.ndarray] = {}

    def centred(node: int) -> np.ndarray:
        if node not in local:
            local[node] = np.asarray(graph.points[node], float) - centre[node]
        return local[node]

    found: list[DoorPair] = []
    for ks in buckets.values():
        for n, k in enumerate(ks):
            a = int(edges[k, 0])
            d = np.asarray(details[k].direction, float)
            for l in ks[n + 1:]:
                b = int(edges[l, 0])
                if a == b or abs(float(d @ details[l].direction)) < cos:
                    continue
                if np.any(np.abs(ext[a] - ext[b]) > extent_tol * np.maximum(ext[a], ext[b])):
                    continue
                off = centre[b] - centre[a]
                u = _across(off, d)
                gap = float(np.linalg.norm(u))
                # cheap bounds first (the half widths below are at most ``reach``)
                if gap <= 1e-12 or gap > side_max * (reach[a] + reach[b]) or \
                        abs(float(off @ d)) > height_tol * min(reach[a], reach[b]):
                    continue
                pa, pb = centred(a), centred(b)
                h = min(float(np.abs(pa @ d).max()), float(np.abs(pb @ d).max()))
                if abs(float(off @ d)) > height_tol * h:
                    continue
                u = u / gap
                wa, wb = float(np.abs(pa @ u).max()), float(np.abs(pb @ u).max())
                if not side_min * (wa + wb) <= gap <= side_max * (wa + wb):
                    continue
                if abs(float(thin[a] @ thin[b])) < flat or \
                        abs(float(off @ thin[a])) > plane_tol * (wa + wb):
                    continue  # not in one plane
                found.append(DoorPair(k, l, u, wa, wb))
    partners: dict[int, set[int]] = {}
    for p in found:
        a, b = int(edges[p.k, 0]), int(edges[p.l, 0])
        partners.setdefault(a, set()).add(b)
        partners.setdefault(b, set()).add(a)
    return [p for p in found
            if len(partners[int(edges[p.k, 0])]) == 1 and len(partners[int(edges[p.l, 0])]) == 1]


def _outward(graph: PartGraph, r: EdgeRefinement, node: int, d: np.ndarray, w: float,
             out: np.ndarray, edge_min: float, cos: float) -> EdgeRefinement | None:
    """``r`` moved to its most probable line parallel to ``d`` on the ``out`` side of the
    part's centre (at least ``edge_min * w`` off it), or None without such a candidate."""
    centre = np.asarray(graph.obb_center[node], float)
    offset = _across(np.asarray(r.candidates.origins, float) - centre, d) @ out
    ok = (np.abs(r.candidates.directions @ d) >= cos) & (offset >= edge_min * w)
    if not ok.any():
        return None
    b = int(np.argmax(np.where(ok, r.scores.total, -np.inf)))
    o, dn = chosen_line(graph, node, r.candidates, b, int(r.scores.sign[b]))
    return replace(r, scores=replace(r.scores, best=b), origin=o, direction=dn)


def open_from_the_middle(graph: PartGraph, edges: np.ndarray, types: Sequence[str],
                         details: dict[int, EdgeRefinement], *,
                         angle_deg: float = 10.0, edge_min: float = 0.5,
                         **pair_options: float) -> dict[int, EdgeRefinement]:
    """Apply the module's rule to the learned selector's choices.

    Parameters
    ----------
    graph : PartGraph
        As in :func:`door_pairs`.
    edges : (E, 2) int64
        (moving, reference) node of every edge.
    types : sequence of str
        Predicted type of every edge.
    details : dict of int to EdgeRefinement
        The selector's result per refined edge (after :func:`kinmo.refine.repeated.vote_repeated`).
    angle_deg : float
        Directions within this angle (up to sign) are the same.
    edge_min : float
        Share of a part's half width by which a hinge line lies off its centre (step 3).
    **pair_options
        ``extent_tol``, ``height_tol``, ``plane_deg``, ``plane_tol``, ``side_min``, ``side_max`` of
        :func:`door_pairs`.

    Returns
    -------
    dict of int to EdgeRefinement
        The edges whose line moved to the outer edge, with their new refinement (the same
        calibrated confidence).
    """
    cos = float(np.cos(np.radians(angle_deg)))
    centre = np.asarray(graph.obb_center, float)
    changed: dict[int, EdgeRefinement] = {}
    for k, l, u, width_k, width_l in door_pairs(graph, edges, types, details,
                                                angle_deg=angle_deg, **pair_options):
        members = []
        # ``out``: the outer side, away from the partner; ``w``: the half width along it
        for e, out, w in ((k, -u, width_k), (l, u, width_l)):
            r = details[e]
            node = int(edges[e, 0])
            d = np.asarray(r.direction, float)
            line = float(_across(np.asarray(r.origin, float) - centre[node], d) @ out)
            members.append((e, r, node, d, w, line, out))
        central = [abs(line) < edge_min * w for _, _, _, _, w, line, _ in members]
        if all(central):
            continue  # two centre lines: no hinges to go by (step 3)
        outer = {}
        for (e, r, node, d, w, line, out), mid in zip(members, central):
            outer[e] = not mid and line > 0
            if outer[e] or mid:
                continue  # on the outer side already, or a centre line (after the seam's move)
            moved = _outward(graph, r, node, d, w, out, edge_min, cos)
            if moved is not None:
                changed[e], outer[e] = moved, True
        for (e, r, node, d, w, line, out), mid in zip(members, central):
            partner = l if e == k else k
            if mid and outer[partner]:  # a centre line beside an outer hinge (step 3)
                moved = _outward(graph, r, node, d, w, out, edge_min, cos)
                if moved is not None:
                    changed[e] = moved
    return changed
