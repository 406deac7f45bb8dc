"""PointNet++ neighbourhoods of point clouds (Rust, ``kinmo-geometry/src/pointnet.rs``).

Farthest point sampling, ball query and k nearest neighbours (Qi et al. NeurIPS 2017), the
index computations of PointNet++'s set abstraction and feature propagation, for one cloud
``(N, 3)`` or a batch ``(B, N, 3)``, in parallel over the batch. Coordinates are float32 (the
network's precision; other dtypes are converted). Used by :mod:`kinmo.ancsh.plan` to
plan a batch's neighbourhoods before the forward pass.

Numerical rules (those of the PyTorch reference in :mod:`kinmo.ancsh.plan`):
farthest point sampling starts at point 0, keeps float32 distances evaluated as PyTorch does
and picks the first point of largest distance, so it equals the reference exactly; ball
query and nearest neighbours compare float64 squared distances of the float32 coordinates,
ties broken by index.
"""

from __future__ import annotations

import numpy as np

from kinmo import _core

__all__ = ["ball_query", "farthest_point_sample", "k_nearest"]


def _clouds(x: np.ndarray, what: str) -> tuple[np.ndarray, bool]:
    a = np.asarray(x, dtype=np.float32)  # views stay views: the core checks sizes before copying
    if a.ndim == 2:
        return a[None], True
    if a.ndim != 3:
        raise ValueError(f"{what}: expected shape (N, 3) or (B, N, 3), got {a.shape}")
    return a, False


def farthest_point_sample(points: np.ndarray, m: int) -> np.ndarray:
    """Farthest point sampling of ``m`` points per cloud, starting at point 0.

    Parameters
    ----------
    points : (N, 3) or (B, N, 3) float
    m : int
        In ``[1, N]``.

    Returns
    -------
    (m,) or (B, m) int64
        Indices into ``N``, in the order chosen.

    Raises
    ------
    ValueError
        Bad shape, ``m`` out of range, or a NaN/inf coordinate.
    """
    p, single = _clouds(points, "points")
    out = _core.farthest_point_sample(p, int(m))
    return out[0] if single else out


def ball_query(points: np.ndarray, centers: np.ndarray, radius: float, k: int) -> np.ndarray:
    """Up to ``k`` points within ``radius`` of each centre (the first ``k`` in index order).

    Slots beyond the number of neighbours repeat the first neighbour; a centre with no point
    within ``radius`` gets its nearest point in every slot.

    Parameters
    ----------
    points : (N, 3) or (B, N, 3) float
    centers : (M, 3) or (B, M, 3) float
        Same batch layout as ``points``.
    radius : float
        Finite, > 0.
    k : int
        >= 1.

    Returns
    -------
    (M, k) or (B, M, k) int64
        Indices into ``N``.

    Raises
    ------
    ValueError
        Bad shapes, batch sizes that differ, bad ``radius`` or ``k``, NaN/inf coordinates.
    """
    p, single = _clouds(points, "points")
    c, _ = _clouds(centers, "centers")
    out = _core.ball_query(p, c, float(radius), int(k))
    return out[0] if single else out


def k_nearest(points: np.ndarray, queries: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
    """The ``k`` nearest of ``points`` to each query, by distance then index.

    Parameters
    ----------
    points : (M, 3) or (B, M, 3) float
        The reference cloud(s).
    queries : (N, 3) or (B, N, 3) float
        Same batch layout as ``points``.
    k : int
        In ``[1, M]``.

    Returns
    -------
    indices : (N, k) or (B, N, k) int64
        Into ``M``, nearest first.
    distances : (N, k) or (B, N, k) float32
        Euclidean.

    Raises
    ------
    ValueError
        Bad shapes, batch sizes that differ, ``k`` out of range, NaN/inf coordinates.
    """
    p, single = _clouds(points, "points")
    q, _ = _clouds(queries, "queries")
    idx, dist = _core.k_nearest(p, q, int(k))
    return (idx[0], dist[0]) if single else (idx, dist)
