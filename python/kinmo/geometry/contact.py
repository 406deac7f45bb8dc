"""Contact adjacency between the parts of a shape, exact mesh-to-mesh distances."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from kinmo import _core


def _meshes(meshes: Sequence[tuple[np.ndarray, np.ndarray]]) -> list[tuple[np.ndarray, np.ndarray]]:
    return [
        (np.ascontiguousarray(v, dtype=np.float64), np.ascontiguousarray(f, dtype=np.int64))
        for v, f in meshes
    ]


def contact_pairs(
    meshes: Sequence[tuple[np.ndarray, np.ndarray]], tolerance: float
) -> tuple[np.ndarray, np.ndarray]:
    """All pairs of meshes whose surfaces come within ``tolerance`` of each other.

    Exact surface-to-surface distance (triangles, not samples) with an AABB broad phase, so
    the cost grows about ``n log n`` with the number of meshes.

    Parameters
    ----------
    meshes : sequence of (vertices (V, 3) float64, faces (F, 3) int)
    tolerance : float
        Absolute distance, >= 0 (callers use a fraction of the shape's diagonal).

    Returns
    -------
    pairs : (K, 2) int64
        ``i < j``, sorted lexicographically.
    distances : (K,) float64
        Minimum distance of each pair (0 for touching or intersecting meshes).
    """
    return _core.contact_pairs(_meshes(meshes), float(tolerance))


def mesh_distance(
    mesh_a: tuple[np.ndarray, np.ndarray], mesh_b: tuple[np.ndarray, np.ndarray]
) -> float:
    """Exact minimum distance between the surfaces of two triangle meshes (0 if they touch)."""
    (a, b) = _meshes([mesh_a, mesh_b])
    return float(_core.mesh_distance(a[0], a[1], b[0], b[1]))
