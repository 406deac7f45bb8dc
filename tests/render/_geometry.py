"""Exact point-to-triangle-mesh distances in numpy, for checking rendered point clouds.

Brute force (chunked), exact: the closest point on each triangle is found by the Voronoi
region tests of Ericson, *Real-Time Collision Detection*, Sec. 5.1.5.
"""

from __future__ import annotations

import numpy as np


def point_triangle_distances(points: np.ndarray, tris: np.ndarray) -> np.ndarray:
    """Distance from every point to every triangle.

    Parameters
    ----------
    points : (N, 3) float64
    tris : (T, 3, 3) float64
        Triangle corners.

    Returns
    -------
    (N, T) float64
    """
    p = points[:, None, :]
    a, b, c = tris[None, :, 0], tris[None, :, 1], tris[None, :, 2]
    ab, ac, ap = b - a, c - a, p - a
    d1 = (ab * ap).sum(-1)
    d2 = (ac * ap).sum(-1)
    bp = p - b
    d3 = (ab * bp).sum(-1)
    d4 = (ac * bp).sum(-1)
    cp = p - c
    d5 = (ab * cp).sum(-1)
    d6 = (ac * cp).sum(-1)
    va = d3 * d6 - d5 * d4
    vb = d5 * d2 - d1 * d6
    vc = d1 * d4 - d3 * d2
    with np.errstate(divide="ignore", invalid="ignore"):
        denom = va + vb + vc
        v = vb / denom
        w = vc / denom
        q = a + ab * v[..., None] + ac * w[..., None]  # interior
        # edge regions
        t_ab = d1 / (d1 - d3)
        t_ac = d2 / (d2 - d6)
        t_bc = (d4 - d3) / ((d4 - d3) + (d5 - d6))
    e_ab = (vc <= 0) & (d1 >= 0) & (d3 <= 0)
    e_ac = (vb <= 0) & (d2 >= 0) & (d6 <= 0)
    e_bc = (va <= 0) & ((d4 - d3) >= 0) & ((d5 - d6) >= 0)
    q = np.where(e_bc[..., None], b + (c - b) * t_bc[..., None], q)
    q = np.where(e_ac[..., None], a + ac * t_ac[..., None], q)
    q = np.where(e_ab[..., None], a + ab * t_ab[..., None], q)
    q = np.where(((d6 >= 0) & (d5 <= d6))[..., None], c, q)
    q = np.where(((d3 >= 0) & (d4 <= d3))[..., None], b, q)
    q = np.where(((d1 <= 0) & (d2 <= 0))[..., None], a, q)
    # degenerate triangles: fall back to the nearest corner
    bad = ~np.isfinite(q).all(-1)
    if bad.any():
        corners = np.stack([np.broadcast_to(x, q.shape) for x in (a, b, c)], 0)
        dc = np.linalg.norm(corners - p[None], axis=-1)
        k = dc.argmin(0)
        qc = np.take_along_axis(corners, k[None, ..., None], 0)[0]
        q = np.where(bad[..., None], qc, q)
    return np.linalg.norm(q - p, axis=-1)


def point_mesh_distance(points: np.ndarray, tris: np.ndarray, chunk: int = 400_000) -> np.ndarray:
    """Exact distance from each point to the union of triangles ``tris`` (``(T, 3, 3)``)."""
    points = np.asarray(points, dtype=np.float64)
    out = np.empty(len(points))
    step = max(1, chunk // max(1, len(tris)))
    for i in range(0, len(points), step):
        out[i:i + step] = point_triangle_distances(points[i:i + step], tris).min(1)
    return out
