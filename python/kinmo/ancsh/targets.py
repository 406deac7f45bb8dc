"""Per-point joint targets of ANCSH (Li et al. CVPR 2020, Sec. 4.2), computed in NAOCS.

A point is associated with a joint of its part (as child or parent): for revolute joints when
it lies within ``theta`` of the axis line, its heatmap target is ``1 - d / theta`` and its
unit vector points to its foot on the axis; for prismatic joints every point of the child part
is associated (no heatmap / unit vector: prismatic axes have no position). When several joints
qualify, the nearest revolute axis wins, then the prismatic joint.
"""

from __future__ import annotations

import numpy as np

from kinmo.ancsh.structure import KinematicStructure


def joint_targets(
    naocs: np.ndarray,
    seg: np.ndarray,
    structure: KinematicStructure,
    origins: np.ndarray,
    directions: np.ndarray,
    theta: float = 0.2,
) -> dict[str, np.ndarray]:
    """Joint-association targets of one frame.

    Parameters
    ----------
    naocs : (N, 3) float
        NAOCS coordinates of the points.
    seg : (N,) int
        Part label of each point (0 .. K-1).
    structure : KinematicStructure
    origins, directions : (J, 3) float
        Joint axes in NAOCS (directions need not be unit).
    theta : float
        Association distance in NAOCS units.

    Returns
    -------
    dict with ``heatmap`` (N,) float32 in [0, 1], ``unitvec`` (N, 3) float32,
    ``axis`` (N, 3) float32 (unit direction of the associated joint, 0 if none),
    ``joint`` (N,) int64 (0: none, j + 1 for joint j), ``position_mask`` (N,) bool.
    """
    p = np.asarray(naocs, dtype=np.float64)
    seg = np.asarray(seg)
    n = len(p)
    d_best = np.full(n, np.inf)
    out_joint = np.zeros(n, dtype=np.int64)
    heat = np.zeros(n, dtype=np.float32)
    unit = np.zeros((n, 3), dtype=np.float32)
    axis = np.zeros((n, 3), dtype=np.float32)
    pos = np.zeros(n, dtype=bool)
    for j, jt in enumerate(structure.joint_types):
        child, parent = j + 1, structure.parents[j + 1]
        u = np.asarray(directions[j], dtype=np.float64)
        u = u / np.linalg.norm(u)
        if jt == "revolute":
            rel = p - origins[j]
            foot = origins[j] + np.outer(rel @ u, u)
            vec = foot - p
            d = np.linalg.norm(vec, axis=1)
            cand = ((seg == child) | (seg == parent)) & (d < theta) & (d < d_best)
        else:
            d = np.full(n, theta)  # lower priority than any revolute association
            cand = (seg == child) & (d < d_best)
            vec = np.zeros_like(p)
        idx = np.flatnonzero(cand)
        d_best[idx] = d[idx]
        out_joint[idx] = j + 1
        axis[idx] = u
        if jt == "revolute":
            heat[idx] = 1.0 - d[idx] / theta
            nrm = np.linalg.norm(vec[idx], axis=1, keepdims=True)
            unit[idx] = np.where(nrm > 1e-12, vec[idx] / np.maximum(nrm, 1e-12), 0.0)
            pos[idx] = True
        else:
            heat[idx] = 0.0
            unit[idx] = 0.0
            pos[idx] = False
    return {"heatmap": heat, "unitvec": unit, "axis": axis, "joint": out_joint, "position_mask": pos}
