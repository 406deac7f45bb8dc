"""Area-weighted uniform surface sampling of triangle meshes."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from kinmo import _core


def sample_surface(
    vertices: np.ndarray, faces: np.ndarray, n: int, seed: int = 0
) -> tuple[np.ndarray, np.ndarray]:
    """Sample ``n`` points uniformly by area on a triangle mesh.

    Faces are chosen with probability proportional to their area (Walker/Vose alias table;
    zero-area faces are never chosen), points uniformly inside the face with the square-root
    barycentric formula of Osada et al., *Shape distributions* (ACM TOG 2002):
    ``(1 - sqrt(r1)) a + sqrt(r1) (1 - r2) b + sqrt(r1) r2 c``. Random numbers come from
    xoshiro256++ seeded with SplitMix64 (integer arithmetic only), so the same inputs and
    ``seed`` give bit-identical points on every machine. Runs in Rust with the GIL released.

    Parameters
    ----------
    vertices : (V, 3) float64
        Mesh frame, any units.
    faces : (F, 3) int
        Zero-based vertex indices.
    n : int
        Number of points, >= 1.
    seed : int
        In ``[0, 2**64)``.

    Returns
    -------
    points : (n, 3) float64
    face_index : (n,) int64
        The face each point lies on.

    Raises
    ------
    ValueError
        Bad shapes, non-finite vertices, out-of-range indices, zero total area, ``n < 1`` or
        a seed out of range (the message names the argument).
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
    of all meshes below it. Group ``g`` is sampled like :func:`sample_surface` on the
    concatenation of its meshes (in the listed order) with a seed derived from ``(seed, g)``
    (SplitMix64), so results do not depend on the number of threads nor on the other groups.
    Parallel over groups (Rust threads, GIL released), one output buffer.

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
