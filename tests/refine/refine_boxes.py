"""Labelled box cabinets as PartGraphs, for the refinement tests (no meshes, no Rust needed).

Hierarchy (pre-order indices), y-up, the front facing +z::

    0 cabinet
    ├── 1 body     solid box, the reference part
    ├── 2 door     upper-left front slab, hinge = its left back vertical edge (R_V_S),
    │              opens outwards (limit -90..0 about +y)
    ├── 3 drawer   lower-right front box, slides out along +z (P_H, limit 0..0.3 * depth)
    └── 4 knob     small box on the door, turns about its own z axis through its centre (R_H_C)

Labels: (door, body) R_V_S, (drawer, body) P_H, (knob, door) R_H_C; all other sibling edges
None. ``jitter`` scales the boxes so that several distinct shapes can be made.
"""

from __future__ import annotations

import numpy as np

from kinmo.data.graph import PartGraph
from kinmo.data.model import FINE_INDEX


def box_points(lo, hi, n: int, rng: np.random.Generator) -> np.ndarray:
    """``n`` points uniformly (by area) on the surface of an axis-aligned box."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    size = hi - lo
    areas = np.array([size[1] * size[2], size[0] * size[2], size[0] * size[1]])
    axis = rng.choice(3, size=n, p=areas / areas.sum())
    side = rng.integers(0, 2, size=n)
    pts = rng.uniform(lo, hi, size=(n, 3))
    pts[np.arange(n), axis] = np.where(side == 1, hi[axis], lo[axis])
    return pts


def box_cabinet(n_points: int = 512, seed: int = 0, jitter: float = 0.0,
                shape_id: str = "boxcab") -> PartGraph:
    """The cabinet of the module docstring as a labelled PartGraph."""
    rng = np.random.default_rng(seed)
    s = 1.0 + jitter * rng.uniform(-1, 1, size=3)
    w, h, d = 1.0 * s[0], 1.0 * s[1], 0.6 * s[2]
    t = 0.02
    z0 = d / 2
    boxes = {
        1: ((-w / 2, 0.0, -d / 2), (w / 2, h, z0)),
        2: ((-w / 2, h / 2, z0), (0.0, h, z0 + t)),
        3: ((0.0, 0.1 * h, -d / 2 + 0.02), (w / 2, h / 2 - 0.02, z0 + t)),
        4: ((-0.15 * w, 0.7 * h, z0 + t), (-0.05 * w, 0.8 * h, z0 + 3 * t)),
    }
    names = ["cabinet", "body", "door", "drawer", "knob"]
    pts = {k: box_points(lo, hi, n_points, rng) for k, (lo, hi) in boxes.items()}
    all_pts = np.concatenate(list(pts.values()))
    root_pts = all_pts[rng.choice(len(all_pts), n_points, replace=False)]
    points = np.stack([root_pts] + [pts[k] for k in (1, 2, 3, 4)]).astype(np.float32)
    lo_all = np.min([b[0] for b in boxes.values()], axis=0)
    hi_all = np.max([b[1] for b in boxes.values()], axis=0)
    center = [(lo_all + hi_all) / 2] + [(np.add(*boxes[k]) / 2) for k in (1, 2, 3, 4)]
    half = [(hi_all - lo_all) / 2] + [(np.subtract(boxes[k][1], boxes[k][0]) / 2)
                                      for k in (1, 2, 3, 4)]
    edges = np.array([(i, j) for i in range(1, 5) for j in range(1, 5) if i != j], np.int64)
    n_e = len(edges)
    fine = np.full(n_e, FINE_INDEX["None"], np.int64)
    origin = np.full((n_e, 3), np.nan)
    direction = np.full((n_e, 3), np.nan)
    link = np.full(n_e, -1, np.int64)
    ci = np.asarray(center)
    labels = {
        (2, 1): ("R_V_S", np.array([-w / 2, 0.0, z0]), np.array([0.0, 1.0, 0.0]), 1),
        (3, 1): ("P_H", ci[3], np.array([0.0, 0.0, 1.0]), 2),
        (4, 2): ("R_H_C", ci[4], np.array([0.0, 0.0, 1.0]), 3),
    }
    for k, (i, j) in enumerate(edges):
        lab = labels.get((int(i), int(j)))
        if lab is None:
            continue
        name, o, dd, lk = lab
        fine[k] = FINE_INDEX[name]
        origin[k] = o + np.dot(ci[i] - o, dd) * dd  # nearest to the moving OBB centre
        direction[k] = dd
        link[k] = lk
    links = [
        {"id": 0, "parent": -1, "name": "body", "joint": "free", "parts": [1], "origin": None,
         "direction": None, "limit": None, "rotates": False, "rotation_limit": None},
        {"id": 1, "parent": 0, "name": "door", "joint": "hinge", "parts": [2],
         "origin": [-w / 2, 0.0, z0], "direction": [0.0, 1.0, 0.0],
         "limit": [-90.0, 0.0], "rotates": False, "rotation_limit": None},
        {"id": 2, "parent": 0, "name": "drawer", "joint": "slider", "parts": [3],
         "origin": list(ci[3]), "direction": [0.0, 0.0, 1.0], "limit": [0.0, 0.3 * d],
         "rotates": False, "rotation_limit": None},
        {"id": 3, "parent": 1, "name": "knob", "joint": "hinge", "parts": [4],
         "origin": list(ci[4]), "direction": [0.0, 0.0, 1.0], "limit": None,
         "rotates": False, "rotation_limit": None},
    ]
    return PartGraph(
        shape_id=shape_id, category="StorageFurniture", format="partnet-mobility",
        node_ids=np.arange(5, dtype=np.int64), node_names=names,
        parent=np.array([-1, 0, 0, 0, 0], np.int64),
        is_leaf=np.array([False, True, True, True, True]),
        depth=np.array([0, 1, 1, 1, 1], np.int64),
        points=points,
        obb_center=np.asarray(center, float), obb_axes=np.tile(np.eye(3), (5, 1, 1)),
        obb_half_extents=np.asarray(half, float),
        child_edges=np.array([[0, k] for k in range(1, 5)], np.int64),
        sibling_edges=edges,
        sibling_contact=np.ones(n_e, bool), sibling_distance=np.zeros(n_e),
        scale=float(np.linalg.norm(hi_all - lo_all)),
        edge_fine=fine, edge_axis_origin=origin, edge_axis_direction=direction,
        edge_link=link, node_link=np.array([-1, 0, 1, 2, 3], np.int64),
        meta={"links": links},
    )


def edge_index(graph: PartGraph, i: int, j: int) -> int:
    """Index of the sibling edge ``(i, j)``."""
    e = graph.sibling_edges
    return int(np.flatnonzero((e[:, 0] == i) & (e[:, 1] == j))[0])
