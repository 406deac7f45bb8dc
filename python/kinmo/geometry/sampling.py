"""Area-weighted uniform surface sampling of triangle meshes."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from kinmo import _core


def sample_surface(
    vertices: np.ndarray, faces: np.ndarray, n: int, seed: int = 0
) -> tuple[np.ndarray, np.ndarray]:
    """Sample ``n`` points uniformly by area on a triangle mesh.

    Faces are chosen with probability proportional to their area (zero-area faces are never
    chosen), points uniformly inside the face (barycentric ``sqrt`` trick). Reproducible: the
    same inputs and ``seed`` give the same points on every machine.

    Parameters
    ----------
    vertices : (V, 3) float64
    faces : (F, 3) int
    n : int
        Number of points, >= 1.
    seed : int

    Returns
    -------
    points : (n, 3) float64
    face_index : (n,) int64
        The face each point lies on.

    Raises
    ------
    ValueError
        Bad shapes, non-finite vertices, out-of-range indices, or zero total area.
    """
    return _core.sample_surface(
        np.ascontiguousarray(vertices, dtype=np.float64),
        np.ascontiguousarray(faces, dtype=np.int64),
        int(n),
        int(seed),
    )


def sample_surface_groups(
    meshes: Sequence[tuple[np.ndarray, np.ndarray]],
    groups: Sequence[Sequence[int]],
    n: int,
    seed: int = 0,
) -> np.ndarray:
    """Sample ``n`` points on the union of each group of meshes, in parallel.

    Used for part graphs: a leaf node is a group of its own meshes, an inner node the group
    of all meshes below it. Group ``g`` is sampled with a seed derived from ``(seed, g)``, so
    results do not depend on the number of threads.

    Parameters
    ----------
    meshes : sequence of (vertices (V, 3) float64, faces (F, 3) int)
    groups : sequence of sequences of int
        Mesh indices of each group (non-empty).
    n : int
        Points per group.
    seed : int

    Returns
    -------
    (G, n, 3) float64

    Raises
    ------
    ValueError
        A bad mesh (naming its index), an empty group, an index out of range, or a group of
        zero total area.
    """
    ms = [
        (np.ascontiguousarray(v, dtype=np.float64), np.ascontiguousarray(f, dtype=np.int64))
        for v, f in meshes
    ]
    return _core.sample_surface_groups(ms, [list(map(int, g)) for g in groups], int(n), int(seed))
