"""Ground-truth motion labels of the sibling edges of a PartNet-Mobility object.

Liu et al. 2023 Sec. 3.1 label every directed sibling edge ``(i, j)`` of the part hierarchy
("part i moves relative to part j") with one of 10 fine motion types
(:data:`~kinmo.data.model.FINE_TYPES`) and, for moving edges, the joint axis. kinmo derives
them from ``mobility_v2.json`` by the rules below, applied in this order.

**Node → link.** A link's ``parts`` may list leaves or inner nodes; every leaf below a listed
node belongs to the link. A node (leaf or inner) belongs to link ``L`` when all its leaves
belong to ``L`` ("link-pure"); a node whose leaves span several links, or that has a leaf in
no link, gets link ``-1`` ("mixed").

**Rigid groups.** ``static``, ``heavy`` and ``junk`` joints are rigid: such a link that has a
parent link belongs to its parent's rigid group. Formally ``group(L) = L`` when ``L`` has no
parent (``parent == -1``) or its joint is ``hinge``, ``slider`` or ``free``; otherwise
``group(L) = group(parent(L))``. (Root-level ``junk`` links, which have no parent, form groups
of their own.)

**Edge label** of a directed sibling edge ``(i, j)``:

1. ``None`` if ``i`` or ``j`` is mixed.
2. ``Fixed`` if ``group(link(i)) == group(link(j))`` (in both directions).
3. Moving: let ``g = group(link(i))``. If ``g``'s joint is a ``hinge`` or ``slider`` and
   ``group(parent(g)) == group(link(j))``, the edge gets ``g``'s joint: its fine type (below),
   its axis, and ``edge_link = g``.
4. ``None`` otherwise: unrelated siblings, siblings attached through intermediate links, and
   the reverse direction of a moving edge (the reference part does not move relative to the
   moving part in the paper's convention).

**Fine type** of the joint of a moving edge, with ``d`` the unit axis direction and ``+y`` up:

- vertical ``V`` when the angle between the axis line and the ``y`` axis is below 45°, i.e.
  ``|d_y| > cos 45°``; horizontal ``H`` otherwise (exactly 45° is horizontal);
- ``slider`` without ``rotates`` → ``P_H`` / ``P_V``; ``slider`` with ``rotates``
  (cylindrical) → ``PR_H`` / ``PR_V``;
- ``hinge`` → ``R_{H|V}_{C|S}``: centre ``C`` when the distance from the axis line to the
  centre of node ``i``'s OBB is strictly smaller than its distance to each of the OBB's 12
  edges (line-to-segment distance), side ``S`` otherwise. The edges crossing the axis count
  too: an axis inside a thin part but further from its centre than from its faces is ``S``.

**Axis** of a moving edge: the joint's unit direction as in the file (its sign kept), and as
origin the point of the axis line nearest to the centre of node ``i``'s OBB (a canonical
point, so that the regression target does not depend on where the annotator put the origin).
``Fixed`` and ``None`` edges get NaN axes and ``edge_link = -1``.

Frames: mesh frame, y-up.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from kinmo.data.model import FINE_INDEX, Joint, JointType, Link, PartHierarchy

__all__ = [
    "EdgeLabels",
    "VERTICAL_COS",
    "fine_type",
    "is_vertical",
    "label_sibling_edges",
    "line_segment_distance",
    "link_subtree",
    "node_links",
    "obb_edges",
    "pivot_is_central",
    "pivots_are_central",
    "rigid_groups",
]

#: ``|d_y|`` above which an axis is vertical (angle to ±y below 45°).
VERTICAL_COS = float(np.cos(np.pi / 4))
_MOVING = (JointType.HINGE, JointType.SLIDER)
_GROUP_ROOTS = (JointType.HINGE, JointType.SLIDER, JointType.FREE)


def node_links(hierarchy: PartHierarchy, links: list[Link]) -> dict[int, int]:
    """Link of every hierarchy node (rule "Node → link" of the module docstring).

    Parameters
    ----------
    hierarchy : PartHierarchy
    links : list of Link

    Returns
    -------
    dict of int to int
        Node id → link id, ``-1`` for mixed nodes.
    """
    leaf_link: dict[int, int] = {}
    for lk in links:
        for part in lk.parts:
            for leaf in hierarchy.leaves(part):
                leaf_link[leaf] = lk.id
    out: dict[int, int] = {}
    # Post-order: children before parents.
    for nid in reversed(hierarchy.order):
        node = hierarchy.nodes[nid]
        if node.is_leaf:
            out[nid] = leaf_link.get(nid, -1)
        else:
            kids = {out[c] for c in node.children}
            out[nid] = kids.pop() if len(kids) == 1 else -1
    return out


def link_subtree(parent_of: Mapping[int, int], root: int) -> set[int]:
    """Ids of link ``root`` and of every link hanging from it, at any depth.

    Parameters
    ----------
    parent_of : mapping of int to int
        Link id -> parent link id (-1 for a root).
    root : int

    Returns
    -------
    set of int
        Includes ``root``; a cycle of parents ends the walk instead of looping.
    """
    kids: dict[int, list[int]] = {}
    for lid, parent in parent_of.items():
        kids.setdefault(parent, []).append(lid)
    out: set[int] = set()
    stack = [root]
    while stack:
        i = stack.pop()
        if i not in out:
            out.add(i)
            stack.extend(kids.get(i, ()))
    return out


def rigid_groups(links: list[Link]) -> dict[int, int]:
    """Rigid group of every link (rule "Rigid groups" of the module docstring).

    Parameters
    ----------
    links : list of Link
        Validated links (no cycles, known parents: :func:`kinmo.data.readers.read_links`).

    Returns
    -------
    dict of int to int
        Link id → id of the link heading its rigid group.
    """
    by_id = {lk.id: lk for lk in links}
    out: dict[int, int] = {}
    for lk in links:
        cur = lk
        while cur.parent != -1 and cur.joint.type not in _GROUP_ROOTS:
            cur = by_id[cur.parent]
        out[lk.id] = cur.id
    return out


def is_vertical(direction: np.ndarray) -> bool:
    """True when the axis direction is within 45° of ±y (``|d_y| > cos 45°``).

    Parameters
    ----------
    direction : (3,) float64
        Any non-zero length (normalised here); mesh frame, y-up.
    """
    d = np.asarray(direction, dtype=np.float64)
    return bool(abs(d[1]) / np.linalg.norm(d) > VERTICAL_COS)


def line_segment_distance(
    origin: np.ndarray, direction: np.ndarray, a: np.ndarray, b: np.ndarray
) -> np.ndarray:
    """Distance from an infinite line to segments.

    Parameters
    ----------
    origin : (3,) float64
        A point of the line.
    direction : (3,) float64
        Line direction, non-zero (normalised here).
    a, b : (..., 3) float64
        Segment end points.

    Returns
    -------
    (...) float64
        Minimum distance between the line and each segment (input units).
    """
    d = np.asarray(direction, dtype=np.float64)
    d = d / np.linalg.norm(d)
    proj = np.eye(3) - np.outer(d, d)  # projection onto the plane orthogonal to the line
    pa = (np.asarray(a, dtype=np.float64) - origin) @ proj
    pb = (np.asarray(b, dtype=np.float64) - origin) @ proj
    ab = pb - pa
    den = np.einsum("...i,...i->...", ab, ab)
    with np.errstate(invalid="ignore", divide="ignore"):
        t = np.where(den > 0, -np.einsum("...i,...i->...", pa, ab) / den, 0.0)
    t = np.clip(t, 0.0, 1.0)
    return np.linalg.norm(pa + t[..., None] * ab, axis=-1)


def obb_edges(center: np.ndarray, axes: np.ndarray, half_extents: np.ndarray) -> np.ndarray:
    """The 12 edges of an OBB (or of a batch of OBBs).

    Parameters
    ----------
    center : (..., 3) float64
    axes : (..., 3, 3) float64
        Orthonormal rows.
    half_extents : (..., 3) float64

    Returns
    -------
    (..., 12, 2, 3) float64
        End points of each edge, 4 per box axis in axis order.
    """
    c = np.asarray(center, dtype=np.float64)
    ax = np.asarray(axes, dtype=np.float64) * np.asarray(half_extents, dtype=np.float64)[..., :, None]
    edges = []
    for k in range(3):  # edges parallel to axis k
        u, v = [m for m in range(3) if m != k]
        for su in (-1.0, 1.0):
            for sv in (-1.0, 1.0):
                mid = c + su * ax[..., u, :] + sv * ax[..., v, :]
                edges.append(np.stack([mid - ax[..., k, :], mid + ax[..., k, :]], axis=-2))
    return np.stack(edges, axis=-3)


def pivot_is_central(
    origin: np.ndarray,
    direction: np.ndarray,
    center: np.ndarray,
    axes: np.ndarray,
    half_extents: np.ndarray,
) -> bool:
    """True when a revolute axis passes nearer the OBB centre than any of its 12 edges.

    Parameters
    ----------
    origin, direction : (3,) float64
        The axis line.
    center, axes, half_extents : OBB of the moving part (see :func:`obb_edges`).

    Returns
    -------
    bool
        ``C`` (centre) when True, ``S`` (side) otherwise; ties are side.
    """
    e = obb_edges(center, axes, half_extents)
    d_edges = line_segment_distance(origin, direction, e[:, 0], e[:, 1])
    d_centre = float(line_segment_distance(origin, direction, center, center))
    return bool(d_centre < d_edges.min())


def pivots_are_central(
    origins: np.ndarray,
    directions: np.ndarray,
    center: np.ndarray,
    axes: np.ndarray,
    half_extents: np.ndarray,
) -> np.ndarray:
    """:func:`pivot_is_central` of many axis lines at once (same rule, same results):
    refinement asks it for every candidate line of an edge, the mobility tree for every edge.

    Parameters
    ----------
    origins, directions : (C, 3) float64
        The axis lines (directions non-zero, normalised here).
    center : (3,) or (C, 3) float64
    axes : (3, 3) or (C, 3, 3) float64
    half_extents : (3,) or (C, 3) float64
        One OBB for all lines, or one per line (see :func:`obb_edges`).

    Returns
    -------
    (C,) bool
        True (``C``, centre) where a line passes nearer its OBB's centre than any edge.
    """
    o = np.asarray(origins, dtype=np.float64).reshape(-1, 3)
    d = np.asarray(directions, dtype=np.float64).reshape(-1, 3)
    d = d / np.linalg.norm(d, axis=1, keepdims=True)
    n = len(o)
    c = np.broadcast_to(np.asarray(center, dtype=np.float64), (n, 3))
    e = obb_edges(c, np.broadcast_to(np.asarray(axes, dtype=np.float64), (n, 3, 3)),
                  np.broadcast_to(np.asarray(half_extents, dtype=np.float64), (n, 3)))
    pts = np.concatenate([e[:, :, 0], e[:, :, 1], c[:, None]], axis=1)  # (C, 25, 3)
    r = pts - o[:, None]  # onto each line's orthogonal plane
    r = r - np.einsum("cmi,ci->cm", r, d)[..., None] * d[:, None]
    pa, pb, pc = r[:, :12], r[:, 12:24], r[:, 24]
    ab = pb - pa
    den = np.einsum("cmi,cmi->cm", ab, ab)
    with np.errstate(invalid="ignore", divide="ignore"):
        t = np.where(den > 0, -np.einsum("cmi,cmi->cm", pa, ab) / den, 0.0)
    t = np.clip(t, 0.0, 1.0)
    d_edges = np.linalg.norm(pa + t[..., None] * ab, axis=-1).min(axis=1)
    return np.linalg.norm(pc, axis=-1) < d_edges


def fine_type(
    joint: Joint, center: np.ndarray, axes: np.ndarray, half_extents: np.ndarray
) -> str:
    """Fine motion type of a moving joint for a moving part with the given OBB.

    Parameters
    ----------
    joint : Joint
        A ``hinge`` or ``slider`` with an axis.
    center, axes, half_extents : OBB of the moving part.

    Returns
    -------
    str
        One of ``P_H P_V R_H_C R_H_S R_V_C R_V_S PR_H PR_V``.

    Raises
    ------
    ValueError
        The joint is not a hinge or slider with an axis.
    """
    if joint.type not in _MOVING or joint.direction is None or joint.origin is None:
        raise ValueError(f"fine_type needs a hinge or slider with an axis, got {joint.type}")
    hv = "V" if is_vertical(joint.direction) else "H"
    if joint.type is JointType.SLIDER:
        return f"PR_{hv}" if joint.rotates else f"P_{hv}"
    cs = "C" if pivot_is_central(joint.origin, joint.direction, center, axes, half_extents) else "S"
    return f"R_{hv}_{cs}"


@dataclass
class EdgeLabels:
    """Labels of ``Es`` directed sibling edges.

    Attributes
    ----------
    fine : (Es,) int64
        Index into :data:`~kinmo.data.model.FINE_TYPES`.
    axis_origin : (Es, 3) float64
        Point of the axis nearest to the moving node's OBB centre; NaN for Fixed / None.
    axis_direction : (Es, 3) float64
        Unit axis direction; NaN for Fixed / None.
    link : (Es,) int64
        Moving link id; -1 for Fixed / None.
    node_link : (V,) int64
        Link id of each node, -1 for mixed nodes.
    """

    fine: np.ndarray
    axis_origin: np.ndarray
    axis_direction: np.ndarray
    link: np.ndarray
    node_link: np.ndarray


def label_sibling_edges(
    hierarchy: PartHierarchy,
    links: list[Link],
    node_ids: np.ndarray,
    sibling_edges: np.ndarray,
    obb_center: np.ndarray,
    obb_axes: np.ndarray,
    obb_half_extents: np.ndarray,
) -> EdgeLabels:
    """Label directed sibling edges by the rules of the module docstring.

    Parameters
    ----------
    hierarchy : PartHierarchy
    links : list of Link
    node_ids : (V,) int64
        PartNet node id of each node index.
    sibling_edges : (Es, 2) int64
        Directed ``(i, j)`` node-index pairs.
    obb_center : (V, 3) float64
    obb_axes : (V, 3, 3) float64
    obb_half_extents : (V, 3) float64
        OBB of each node (used for C/S and the canonical axis origin).

    Returns
    -------
    EdgeLabels
    """
    nl = node_links(hierarchy, links)
    groups = rigid_groups(links)
    by_id = {lk.id: lk for lk in links}
    node_link = np.array([nl[int(n)] for n in node_ids], dtype=np.int64)
    e = np.asarray(sibling_edges, dtype=np.int64).reshape(-1, 2)
    n_e = e.shape[0]
    fine = np.full(n_e, FINE_INDEX["None"], dtype=np.int64)
    origin = np.full((n_e, 3), np.nan)
    direction = np.full((n_e, 3), np.nan)
    link = np.full(n_e, -1, dtype=np.int64)
    for k, (i, j) in enumerate(e):
        li, lj = node_link[i], node_link[j]
        if li < 0 or lj < 0:
            continue
        gi, gj = groups[int(li)], groups[int(lj)]
        if gi == gj:
            fine[k] = FINE_INDEX["Fixed"]
            continue
        g = by_id[gi]
        if g.joint.type not in _MOVING or g.parent == -1 or groups[g.parent] != gj:
            continue
        c = obb_center[i]
        fine[k] = FINE_INDEX[fine_type(g.joint, c, obb_axes[i], obb_half_extents[i])]
        d = np.asarray(g.joint.direction, dtype=np.float64)
        o = np.asarray(g.joint.origin, dtype=np.float64)
        origin[k] = o + np.dot(c - o, d) * d
        direction[k] = d
        link[k] = g.id
    return EdgeLabels(fine, origin, direction, link, node_link)
