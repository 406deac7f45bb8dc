"""Contact adjacency between the parts of a shape, exact mesh-to-mesh distances.

Two parts are *in contact* when their surfaces come within a tolerance of each other. kinmo's
part graphs use ``tolerance = DEFAULT_RELATIVE_TOLERANCE × diagonal`` (1 % of the diagonal
of the object's axis-aligned bounding box), on the leaf meshes of the part hierarchy.

Distances are exact Euclidean distances between the triangle *surfaces*, in the units and
frame of the vertices (PartNet objects: y-up, unit-less normalised coordinates), not
distances between sampled points: thin gaps and small contact patches are never missed.
A mesh nested inside a closed mesh without touching it is at a positive distance.

Algorithm (Rust, ``kinmo-geometry/src/contact.rs``): one bounding volume hierarchy per mesh
(median split, 8 triangles per leaf); sort-and-sweep over the mesh bounding boxes (cost
``n log n`` in the number of meshes); for each candidate pair, a branch-and-bound traversal
of the two hierarchies bounded by the tolerance, with an exact triangle-triangle distance
(edge-edge closest points with the separating-slab early exit of PQP, Larsen et al. 1999;
vertex-face projections; edge-face crossings) that stops at the first contact. Pairs are
tested in parallel for large inputs. On the 109 PartNet-Mobility objects it returns exactly
the pairs of FCL's all-pairs ``fcl.distance`` (see ``bench/bench_geometry.py``).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from kinmo import _core

#: Contact tolerance of kinmo's part graphs, as a fraction of the object's bounding-box
#: diagonal.
DEFAULT_RELATIVE_TOLERANCE = 0.01


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
        The parts of one shape, in one frame. Zero-area triangles and duplicate vertices are
        accepted; a mesh without faces is in contact with nothing.
    tolerance : float
        Absolute distance, finite and >= 0, in the units of the vertices (kinmo uses
        ``DEFAULT_RELATIVE_TOLERANCE`` × the shape's bounding-box diagonal). A pair at
        distance exactly ``tolerance`` is included.

    Returns
    -------
    pairs : (K, 2) int64
        ``i < j``, sorted lexicographically.
    distances : (K,) float64
        Minimum distance of each pair (0 for touching or intersecting meshes).

    Raises
    ------
    ValueError
        Bad array shapes, non-finite coordinates, face indices out of range (naming
        ``meshes[i]``), or a negative / non-finite tolerance.

    Examples
    --------
    >>> import numpy as np
    >>> tri = (np.eye(3), np.array([[0, 1, 2]]))
    >>> moved = (np.eye(3) + [0.0, 0.0, 0.5], np.array([[0, 1, 2]]))
    >>> contact_pairs([tri, moved], 0.6)[0].tolist()
    [[0, 1]]
    """
    return _core.contact_pairs(_meshes(meshes), float(tolerance))


def mesh_distance(
    mesh_a: tuple[np.ndarray, np.ndarray], mesh_b: tuple[np.ndarray, np.ndarray]
) -> float:
    """Exact minimum distance between the surfaces of two triangle meshes (0 if they touch).

    Parameters
    ----------
    mesh_a, mesh_b : (vertices (V, 3) float64, faces (F, 3) int)
        In the same frame.

    Returns
    -------
    float
        Euclidean distance in the units of the vertices; 0 for touching or intersecting
        surfaces.

    Raises
    ------
    ValueError
        Bad shapes, non-finite coordinates, face indices out of range (naming ``mesh_a`` or
        ``mesh_b``), or a mesh without faces.
    """
    (a, b) = _meshes([mesh_a, mesh_b])
    return float(_core.mesh_distance(a[0], a[1], b[0], b[1]))
