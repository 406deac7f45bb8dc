"""Joint-axis metrics: angle between axis directions and distances between axis lines.

Used by the pre-segmented evaluation (Liu et al. CVPR 2023, Table 1: "angle error" and
"distance"), following the definitions of ANCSH (Li et al. CVPR 2020, Sec. 5):

- the **axis angle error** between two axis directions is the angle between the two lines,
  ``min(theta, 180 - theta)`` degrees, so an axis and its reverse count as the same;
- the **line-to-line distance** between two revolute axes is the minimum Euclidean distance
  between the two infinite lines (the length of their common perpendicular; for parallel
  lines the distance of one line's point to the other line).

Inputs may be batched: every function broadcasts over leading dimensions of ``(..., 3)``
arrays. Units are those of the inputs; kinmo's evaluation divides distances by the shape's
scale (the diagonal of its axis-aligned bounding box, :attr:`kinmo.data.graph.PartGraph.scale`).
"""

from __future__ import annotations

import numpy as np

#: Below this value of ``|d1 x d2|`` (unit directions) two lines are treated as parallel.
PARALLEL_EPS = 1e-9


def _unit(d: np.ndarray, name: str) -> np.ndarray:
    d = np.asarray(d, dtype=np.float64)
    if d.shape[-1:] != (3,):
        raise ValueError(f"{name}: expected shape (..., 3), got {d.shape}")
    n = np.linalg.norm(d, axis=-1, keepdims=True)
    if np.any(~np.isfinite(n)) or np.any(n <= 0.0):
        raise ValueError(f"{name}: axis directions must be finite and non-zero")
    return d / n


def _points(p: np.ndarray, name: str) -> np.ndarray:
    p = np.asarray(p, dtype=np.float64)
    if p.shape[-1:] != (3,):
        raise ValueError(f"{name}: expected shape (..., 3), got {p.shape}")
    if not np.all(np.isfinite(p)):
        raise ValueError(f"{name}: points must be finite")
    return p


def axis_angle_deg(d_pred: np.ndarray, d_true: np.ndarray) -> np.ndarray | float:
    """Angle between two axis lines in degrees, ``min(theta, 180 - theta)`` in ``[0, 90]``.

    Parameters
    ----------
    d_pred, d_true : (..., 3) float
        Axis directions (any non-zero length; normalised here). Broadcast together.

    Returns
    -------
    float or (...,) float64
        A Python float for single ``(3,)`` inputs.

    Raises
    ------
    ValueError
        Wrong shapes, zero-length or non-finite directions.

    Notes
    -----
    Computed as ``atan2(|a x b|, |a . b|)``, accurate for nearly parallel lines where
    ``arccos`` loses precision.
    """
    a = _unit(d_pred, "d_pred")
    b = _unit(d_true, "d_true")
    a, b = np.broadcast_arrays(a, b)
    cross = np.linalg.norm(np.cross(a, b), axis=-1)
    dot = np.abs(np.sum(a * b, axis=-1))
    out = np.degrees(np.arctan2(cross, dot))
    return float(out) if out.ndim == 0 else out


def point_line_distance(
    point: np.ndarray, origin: np.ndarray, direction: np.ndarray
) -> np.ndarray | float:
    """Distance from points to infinite lines, ``|(p - o) x d|`` with unit ``d``.

    This is the position term of the paper's loss (Liu et al. 2023, Eq. 4) and SWMP's
    "position error" of a predicted pivot point.

    Parameters
    ----------
    point : (..., 3) float
    origin : (..., 3) float
        A point on each line.
    direction : (..., 3) float
        Line directions (normalised here).

    Returns
    -------
    float or (...,) float64
        In the units of the inputs.
    """
    p = _points(point, "point")
    o = _points(origin, "origin")
    d = _unit(direction, "direction")
    out = np.linalg.norm(np.cross(p - o, d), axis=-1)
    return float(out) if out.ndim == 0 else out


def line_distance(
    o1: np.ndarray, d1: np.ndarray, o2: np.ndarray, d2: np.ndarray
) -> np.ndarray | float:
    """Minimum distance between two infinite 3D lines (ANCSH's axis "distance").

    For non-parallel lines: ``|(o2 - o1) . n| / |n|`` with ``n = d1 x d2``. For parallel lines
    (``|d1 x d2| < PARALLEL_EPS`` after normalisation): the distance of ``o2`` to line 1.

    Parameters
    ----------
    o1, o2 : (..., 3) float
        A point on each line.
    d1, d2 : (..., 3) float
        Directions (normalised here).

    Returns
    -------
    float or (...,) float64
        In the units of the inputs.

    Raises
    ------
    ValueError
        Wrong shapes, zero-length or non-finite input.
    """
    o1 = _points(o1, "o1")
    o2 = _points(o2, "o2")
    u1 = _unit(d1, "d1")
    u2 = _unit(d2, "d2")
    o1, u1, o2, u2 = np.broadcast_arrays(o1, u1, o2, u2)
    w = o2 - o1
    n = np.cross(u1, u2)
    nn = np.linalg.norm(n, axis=-1)
    parallel = nn < PARALLEL_EPS
    skew = np.abs(np.sum(w * n, axis=-1)) / np.where(parallel, 1.0, nn)
    par = np.linalg.norm(np.cross(w, u1), axis=-1)
    out = np.where(parallel, par, skew)
    return float(out) if out.ndim == 0 else out
