"""Per-part pose metrics of articulated pose estimation (ANCSH, Li et al. CVPR 2020, Table 1;
Liu et al. CVPR 2023, Table 2): rotation error, translation error, 3D IoU of amodal boxes,
joint state error.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import ConvexHull, HalfspaceIntersection
from scipy.spatial import QhullError


def rotation_error_deg(r_pred: np.ndarray, r_true: np.ndarray) -> float:
    """Geodesic angle between two rotations, degrees in [0, 180].

    ``arccos((trace(R_pred^T R_true) - 1) / 2)``.

    Parameters
    ----------
    r_pred, r_true : (3, 3) float64
    """
    r = np.asarray(r_pred, float).T @ np.asarray(r_true, float)
    c = np.clip((np.trace(r) - 1.0) / 2.0, -1.0, 1.0)
    return float(np.degrees(np.arccos(c)))


def translation_error(t_pred: np.ndarray, t_true: np.ndarray) -> float:
    """Euclidean distance between two translations ``(3,)`` (same units as the inputs)."""
    return float(np.linalg.norm(np.asarray(t_pred, float) - np.asarray(t_true, float)))


def joint_state_error(pred: float, true: float, revolute: bool) -> float:
    """Joint state error: degrees for revolute joints (inputs in radians), distance for
    prismatic joints (inputs in length units)."""
    d = abs(float(pred) - float(true))
    return float(np.degrees(d)) if revolute else d


def _box_halfspaces(center: np.ndarray, axes: np.ndarray, half: np.ndarray) -> np.ndarray:
    rows = []
    for k in range(3):
        a = axes[k]
        c = float(a @ center)
        # a.x <= c + h  ->  a.x - (c + h) <= 0 ; -a.x <= -(c - h)
        rows.append(np.r_[a, -(c + half[k])])
        rows.append(np.r_[-a, c - half[k]])
    return np.asarray(rows)


def box_iou_3d(
    center_a: np.ndarray,
    axes_a: np.ndarray,
    half_a: np.ndarray,
    center_b: np.ndarray,
    axes_b: np.ndarray,
    half_b: np.ndarray,
) -> float:
    """Exact 3D IoU of two oriented boxes (volume of the convex intersection by half-spaces).

    Parameters
    ----------
    center_a, center_b : (3,) float64
    axes_a, axes_b : (3, 3) float64
        Orthonormal rows.
    half_a, half_b : (3,) float64
        Half extents (> 0).

    Returns
    -------
    float in [0, 1].
    """
    ca, cb = np.asarray(center_a, float), np.asarray(center_b, float)
    aa, ab = np.asarray(axes_a, float), np.asarray(axes_b, float)
    ha, hb = np.asarray(half_a, float), np.asarray(half_b, float)
    va, vb = 8 * np.prod(ha), 8 * np.prod(hb)
    if va <= 0 or vb <= 0:
        return 0.0
    hs = np.vstack([_box_halfspaces(ca, aa, ha), _box_halfspaces(cb, ab, hb)])
    # a strictly interior point is needed: search along the segment between the centres and
    # the corners of the smaller box for one inside both boxes
    def inside(p: np.ndarray) -> float:
        return float(np.max(hs[:, :3] @ p + hs[:, 3]))

    cands = [ca, cb, (ca + cb) / 2]
    for t in np.linspace(0, 1, 21):
        cands.append(ca + t * (cb - ca))
    best = min(cands, key=inside)
    if inside(best) >= -1e-12:
        # refine with a linear program: maximise the slack s s.t. A p + b + s <= 0
        from scipy.optimize import linprog

        norms = np.linalg.norm(hs[:, :3], axis=1)
        res = linprog(
            c=[0, 0, 0, -1],
            A_ub=np.c_[hs[:, :3], norms],
            b_ub=-hs[:, 3],
            bounds=[(None, None)] * 3 + [(0, None)],
            method="highs",
        )
        if not res.success or res.x[3] <= 1e-12:
            return 0.0
        best = res.x[:3]
    try:
        inter = HalfspaceIntersection(hs, best)
        vol = ConvexHull(inter.intersections).volume
    except (QhullError, ValueError):
        return 0.0
    return float(vol / (va + vb - vol))
