"""A synthetic box cabinet as a labelled PartGraph, for the motion-GNN tests.

Hierarchy (pre-order indices)::

    0 cabinet
    ├── 1 body            (leaf, link 0: base)
    ├── 2 door            (leaf, link 1: hinge, vertical axis at its left edge -> R_V_S)
    └── 3 drawer          (link 2: slider along +z -> P_H)
        ├── 4 drawer_front (leaf)
        └── 5 handle       (leaf)

Sibling edge labels follow kinmo.data.labels: (door, body) R_V_S, (drawer, body) P_H,
(drawer_front, handle) and (handle, drawer_front) Fixed, everything else None.
Mesh frame y-up; sizes in metres-ish units. ``jitter`` randomises the sizes so that several
distinct training shapes can be made.
"""

from __future__ import annotations

import numpy as np

from kinmo.data.graph import PartGraph
from kinmo.data.model import FINE_INDEX


def _box_points(lo, hi, n, rng):
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    pts = rng.uniform(lo, hi, size=(n, 3))
    axis = rng.integers(0, 3, size=n)
    side = rng.integers(0, 2, size=n)
    pts[np.arange(n), axis] = np.where(side == 1, hi[axis], lo[axis])
    return pts


def _box_distance(a, b):
    (alo, ahi), (blo, bhi) = a, b
    gap = np.maximum(0.0, np.maximum(np.asarray(blo) - ahi, np.asarray(alo) - bhi))
    return float(np.linalg.norm(gap))


def cabinet_graph(n_points: int = 64, seed: int = 0, jitter: float = 0.0,
                  shape_id: str | None = None) -> PartGraph:
    """The cabinet of the module docstring as a labelled PartGraph."""
    rng = np.random.default_rng(seed)
    s = 1.0 + jitter * rng.uniform(-1, 1, size=3)
    w, h, d = 1.0 * s[0], 1.0 * s[1], 0.6 * s[2]
    t = 0.02
    boxes = {
        1: ((-w / 2, 0.0, -d / 2), (w / 2, h, d / 2)),
        2: ((-w / 2, h / 2, d / 2), (0.0, h, d / 2 + t)),
        4: ((0.0, h / 2, d / 2), (w / 2, h, d / 2 + t)),
        5: ((w / 8, 0.7 * h, d / 2 + t), (w / 4, 0.8 * h, d / 2 + 3 * t)),
    }
    boxes[3] = (tuple(np.minimum(boxes[4][0], boxes[5][0])), tuple(np.maximum(boxes[4][1], boxes[5][1])))
    boxes[0] = (tuple(np.min([boxes[k][0] for k in (1, 2, 3)], axis=0)),
                tuple(np.max([boxes[k][1] for k in (1, 2, 3)], axis=0)))
    names = ["cabinet", "body", "door", "drawer", "drawer_front", "handle"]
    parent = np.array([-1, 0, 0, 0, 3, 3])
    is_leaf = np.array([False, True, True, False, True, True])
    depth = np.array([0, 1, 1, 1, 2, 2])
    leaf_pts = {k: _box_points(*boxes[k], n_points, rng) for k in (1, 2, 4, 5)}
    pts = np.zeros((6, n_points, 3))
    for k in (1, 2, 4, 5):
        pts[k] = leaf_pts[k]
    both = np.concatenate([leaf_pts[4], leaf_pts[5]])
    pts[3] = both[rng.choice(len(both), n_points, replace=False)]
    allp = np.concatenate([leaf_pts[k] for k in (1, 2, 4, 5)])
    pts[0] = allp[rng.choice(len(allp), n_points, replace=False)]
    center = np.array([(np.add(*boxes[k]) / 2) for k in range(6)])
    half = np.array([(np.subtract(boxes[k][1], boxes[k][0]) / 2) for k in range(6)])
    axes = np.tile(np.eye(3), (6, 1, 1))
    sib = np.array([(a, b) for group in ((1, 2, 3), (4, 5)) for a in group for b in group if a != b])
    sib = sib[np.lexsort((sib[:, 1], sib[:, 0]))]
    lo0, hi0 = np.array(boxes[0][0]), np.array(boxes[0][1])
    scale = float(np.linalg.norm(hi0 - lo0))
    dist = np.array([_box_distance(boxes[a], boxes[b]) for a, b in sib])
    contact = dist <= 0.01 * scale
    fine = np.full(len(sib), FINE_INDEX["None"])
    origin = np.full((len(sib), 3), np.nan)
    direction = np.full((len(sib), 3), np.nan)
    elink = np.full(len(sib), -1)
    hinge_o = np.array([-w / 2, 0.75 * h, d / 2 + t / 2])
    for k, (a, b) in enumerate(sib):
        if (a, b) == (2, 1):
            fine[k] = FINE_INDEX["R_V_S"]
            c = center[2]
            origin[k] = hinge_o + np.dot(c - hinge_o, [0, 1, 0]) * np.array([0, 1, 0])
            direction[k] = [0, 1, 0]
            elink[k] = 1
        elif (a, b) == (3, 1):
            fine[k] = FINE_INDEX["P_H"]
            origin[k] = center[3]
            direction[k] = [0, 0, 1]
            elink[k] = 2
        elif {a, b} == {4, 5}:
            fine[k] = FINE_INDEX["Fixed"]
    links = [
        {"id": 0, "parent": -1, "name": "base", "joint": "free", "parts": [1], "origin": None,
         "direction": None, "limit": None, "rotates": False, "rotation_limit": None},
        {"id": 1, "parent": 0, "name": "door", "joint": "hinge", "parts": [2],
         "origin": hinge_o.tolist(), "direction": [0.0, 1.0, 0.0], "limit": [0.0, 90.0],
         "rotates": False, "rotation_limit": None},
        {"id": 2, "parent": 0, "name": "drawer", "joint": "slider", "parts": [3],
         "origin": center[3].tolist(), "direction": [0.0, 0.0, 1.0], "limit": [0.0, 0.4],
         "rotates": False, "rotation_limit": None},
    ]
    return PartGraph(
        shape_id=shape_id or f"cabinet{seed}",
        category="StorageFurniture",
        format="partnet-mobility",
        node_ids=np.arange(6, dtype=np.int64),
        node_names=names,
        parent=parent.astype(np.int64),
        is_leaf=is_leaf,
        depth=depth.astype(np.int64),
        points=pts.astype(np.float32),
        obb_center=center,
        obb_axes=axes,
        obb_half_extents=half,
        child_edges=np.array([(p, c) for c, p in enumerate(parent) if p >= 0], dtype=np.int64),
        sibling_edges=sib.astype(np.int64),
        sibling_contact=contact,
        sibling_distance=dist,
        scale=scale,
        edge_fine=fine.astype(np.int64),
        edge_axis_origin=origin,
        edge_axis_direction=direction,
        edge_link=elink.astype(np.int64),
        node_link=np.array([-1, 0, 1, 2, 2, 2], dtype=np.int64),
        meta={"links": links},
    )


def oracle_prediction(graph: PartGraph, types: str = "fine"):
    """Ground truth as a confident EdgePrediction (mesh frame)."""
    from kinmo.data.model import FINE_TO_COARSE
    from kinmo.mobility_tree import EdgePrediction

    fine = np.asarray(graph.edge_fine)
    k = 10 if types == "fine" else 5
    lab = fine if types == "fine" else np.asarray(FINE_TO_COARSE)[fine]
    probs = np.full((len(fine), k), 0.01 / (k - 1))
    probs[np.arange(len(fine)), lab] = 0.99
    o = np.nan_to_num(np.asarray(graph.edge_axis_origin), nan=0.0)
    d = np.asarray(graph.edge_axis_direction)
    d = np.where(np.isfinite(d), d, np.array([0.0, 1.0, 0.0]))
    return EdgePrediction(probs, d, o)
