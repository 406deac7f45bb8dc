"""Exact convex hulls of point sets (Rust, ``kinmo-geometry/src/hull.rs``).

The hull is the one the OBB fit uses (:mod:`kinmo.geometry.obb`, step 1): incremental
Quickhull (Barber, Dobkin & Huhdanpaa, ACM TOMS 22, 1996) deciding every visibility with
Shewchuk's exact predicates, so coplanar, collinear or duplicated points never corrupt it.
kinmo uses it for the convex collision pieces of URDF and MJCF exports
(:mod:`kinmo.export.collision`, method ``hull``). Frame and units are the input's.
"""

from __future__ import annotations

import numpy as np

from kinmo import _core

__all__ = ["convex_hull"]


def convex_hull(points: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """The convex hull of ``points`` as a closed triangle mesh of its corner points.

    Parameters
    ----------
    points : (N, 3) float64

    Returns
    -------
    (vertices (H, 3) float64, faces (F, 3) int64) or None
        The hull's corner points (in input order; points on a face or an edge, and
        repeats, are left out) and its triangles, counter-clockwise seen from outside (every
        normal ``(b - a) x (c - a)`` points outwards). None when the hull has no volume:
        fewer than 4 points, or all of them on one plane (exact test).

    Raises
    ------
    ValueError
        Not ``(N, 3)``, or a NaN/inf coordinate (the message names the index).
    """
    p = np.ascontiguousarray(points, dtype=np.float64)
    if p.ndim == 2 and p.shape[0] == 0 and p.shape[1] == 3:
        return None
    got = _core.convex_hull(p)
    if got is None:
        return None
    idx, faces = got
    remap = np.full(len(p), -1, dtype=np.int64)
    remap[idx] = np.arange(len(idx))
    return p[idx], remap[faces]
