"""Convex pieces of concave meshes: the export's ``parts`` collision geometry (issue 35).

A mesh gets its exact convex hull unless the hull is *concave*: a point sampled on it lies
farther than a tolerance from the mesh's surface (exact point-to-triangle distances, parry),
i.e. the hull fills a slot, a shell or the inside of a frame. A concave mesh is split into
its connected components (faces sharing a vertex position) when it has 2 to
``max_components``; otherwise, and for every concave piece below, it is cut in two by the
plane through the middle of its face centroids, across their principal axis, at most
``max_depth`` cuts deep. Each piece is checked the same way. A flat piece becomes the hull of
its points moved half a slab thickness to both sides of its plane.

Algorithm in Rust (``kinmo-geometry/src/decompose.rs``): kinmo's exact hull, its seeded area
sampler, parry's point projection and nalgebra's SVD; one call per link, the GIL released.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from kinmo import _core

__all__ = ["concave_pieces"]


def concave_pieces(vertices: np.ndarray, leaves: Sequence[np.ndarray], tolerance: float, *,
                   max_depth: int, max_components: int, hull_samples: int,
                   flat_relative: float, slab_thickness: float
                   ) -> list[list[tuple[np.ndarray, np.ndarray, np.ndarray]]]:
    """The convex pieces of each leaf mesh of a link.

    Parameters
    ----------
    vertices : (V, 3) float64
        Shared by the leaves; any frame and units (PartNet: y-up).
    leaves : sequence of (F, 3) int
        Each leaf's triangles, indices into ``vertices``.
    tolerance : float
        A piece is concave when a point of its hull (of ``hull_samples`` sampled on it,
        seed 0) lies farther than this from its surface, in the units of ``vertices``;
        ``0`` splits nothing. A piece no larger than it is never split.
    max_depth : int
        Most plane cuts on the way from a leaf to one of its pieces.
    max_components : int
        A concave leaf of more connected components than this is cut by planes instead.
    hull_samples : int
        Points sampled on each hull for the concavity test (>= 1).
    flat_relative : float
        A point set is flat when its smallest singular value is at most this share of its
        largest.
    slab_thickness : float
        A flat piece's prism thickness, as a share of its largest extent.

    Returns
    -------
    list (one per leaf) of lists of (vertices (H, 3) float64, faces (T, 3) int64, face ids (K,) int64)
        Closed convex pieces (faces counter-clockwise seen from outside) in depth-first
        order, with the leaf faces each covers (ascending). Together the face ids cover
        every leaf face with area exactly once; a face set without area or volume (a point,
        a segment) has no piece.

    Raises
    ------
    ValueError
        Bad array shapes, non-finite vertices, face indices out of range (naming
        ``leaves[k]``), a negative tolerance or ``hull_samples`` of 0.
    """
    return _core.concave_pieces(
        np.ascontiguousarray(vertices, dtype=np.float64),
        [np.ascontiguousarray(f, dtype=np.int64) for f in leaves],
        float(tolerance), int(max_depth), int(max_components), int(hull_samples),
        float(flat_relative), float(slab_thickness))
