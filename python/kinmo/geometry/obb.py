"""Oriented bounding boxes (OBB) of point sets: tight, up- and symmetry-aligned, canonical.

The fitting runs in Rust (``kinmo-geometry/src/obb.rs``, :func:`kinmo._core.fit_obb`); this
module documents the rule and wraps the arrays in :class:`OBB`.

Algorithm
---------
1. The exact convex hull of the points (Shewchuk's exact predicates, so coplanar, collinear
   and duplicated points never break it).
2. Candidate orientations, each measured by its volume on the hull vertices:

   - the *face-flush* family: every distinct hull-face normal with the minimum-area
     rectangle of the hull projected along it (rotating calipers). This is the family
     ``trimesh.bounds.oriented_bounds`` searches (O'Rourke, *Finding minimal enclosing boxes*,
     1985), but over every face normal instead of normals rounded to 0.1 rad, pruned by an
     exact lower bound (height x projected hull area);
   - the PCA frame, and each PCA axis with its minimum-area rectangle;
   - with ``up`` set: ``up`` with the minimum-area rectangle (and with the 2D PCA) of the
     projection along ``up``, and the axis-aligned box;
   - a local refinement (compass search over small rotations, then a flush polish) from the
     three best candidates, which finds the edge-flush boxes the face-flush family misses.
3. Selection among *near-minimal* boxes (Fish et al., *Meta-representation of shape
   families*, SIGGRAPH 2014, use symmetry-aligned part boxes): with ``V*`` the smallest
   volume found, the candidates of distinct orientation with volume
   ``<= (1 + volume_tolerance) V*`` compete. A candidate with an axis within 5 degrees of
   ``up`` also enters *snapped* (that axis exactly ``+-up``) when still near-minimal; if any
   competitor has an axis exactly along ``up`` (``|axis . up| >= 1 - 1e-12``), only those
   stay. Of the (at most 8) smallest remaining, the winner minimises
   ``E_sym + (V / V* - 1)``, where ``E_sym`` is the mean, over the box's three mid-planes,
   of the mean nearest-neighbour distance from the reflected points (a subsample of about
   256, independent of the point order and of quarter turns about the world axes) to the
   points, divided by the box diagonal; scores within ``1e-9`` of the lowest are ties, won
   by the frame most aligned with the world axes. With ``symmetry=False`` the smallest
   remaining volume wins. The winner is then *rolled* about one of its axes until another
   axis is a world axis, when that is more world-aligned and still near-minimal (round
   parts: knobs, caps, a nail lying on its side). As ``V*`` is never above trimesh's
   volume, the result is at most ``1 + volume_tolerance`` times trimesh's.

   Ties, roll and subsample make the box of a set turned a quarter turn about a world axis
   the turned box (issue 36's rotation criterion: before, a round part's box was rolled by
   another angle in each turn of the asset, and the motion GNN answered differently). A
   part whose own symmetry maps it onto its mirror image can still tie between the two
   mirror-image boxes.
4. *Flat* sets (smallest box thinner than ``1e-4`` of its longest side, e.g. panels whose
   thickness is rounding noise of the OBJ coordinates) keep the normal of the smallest box
   and choose the in-plane rectangle (minimum-area, 2D PCA, or ``up`` projected on the
   plane) by area with the same rule.
5. Half-extents are measured over **all** points along the chosen axes, from a center
   computed relative to the points' minimum corner (small parts far from the origin keep
   their precision), so every point is inside up to rounding.
6. Canonical frame: rows sorted by half-extent, largest first; a run of half-extents each
   within ``1e-6 * max(half_extents)`` of the run's first is tied, and tied rows are ordered
   by the world axis they are closest to, ``y`` then ``x`` then ``z`` (then by the larger
   such component). Rows 0 and 1 are signed so that their largest-magnitude
   component is positive (exact ties: ``y``, ``x``, ``z``); ``axes[2] = cross(axes[0],
   axes[1])`` (right-handed).

The result does not depend on the order of the points or on duplicates. Degenerate sets
do not fail: all-equal points give zero half-extents and the axes ``(y, x, -z)``; collinear
points give the line direction and zero half-extents across it (the second axis is ``up``
projected across the line when possible); coplanar points give a zero half-extent along the
plane normal (the last row) and the in-plane rectangle chosen as above by area.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import numpy as np
import numpy.typing as npt

from kinmo import _core

#: The default up direction (PartNet and PartNet-Mobility objects are y-up).
Y_UP = (0.0, 1.0, 0.0)


class OBB(NamedTuple):
    """An oriented bounding box.

    Attributes
    ----------
    center : (3,) float64
        Box center, in the frame (and units) of the input points.
    axes : (3, 3) float64
        Orthonormal rows, right-handed (``axes[2] = cross(axes[0], axes[1])``), in the
        canonical order and signs of :func:`fit_obb`.
    half_extents : (3,) float64
        Half side length along each row of ``axes``, non-increasing (up to the tie of
        ``1e-6`` times the largest half-extent of the canonical order).
    """

    center: np.ndarray
    axes: np.ndarray
    half_extents: np.ndarray

    @property
    def volume(self) -> float:
        """Box volume (cube of the input units)."""
        return float(8.0 * np.prod(self.half_extents))

    def corners(self) -> np.ndarray:
        """The 8 corners, ``(8, 3) float64``, in binary order of the signs (-,-,-), (-,-,+), ..."""
        s = np.array([[i, j, k] for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)], float)
        return self.center + (s * self.half_extents) @ self.axes

    def to_local(self, points: np.ndarray) -> np.ndarray:
        """Coordinates of ``points (N, 3)`` in the box frame, ``(N, 3) float64``."""
        return (np.asarray(points, float) - self.center) @ self.axes.T

    def contains(self, points: np.ndarray, tol: float = 0.0) -> np.ndarray:
        """``(N,) bool``: is each point inside the box inflated by ``tol`` along every axis?"""
        return np.all(np.abs(self.to_local(points)) <= self.half_extents + tol, axis=-1)


def _up(up: npt.ArrayLike | None) -> tuple[float, float, float] | None:
    if up is None:
        return None
    u = np.asarray(up, dtype=np.float64)
    if u.shape != (3,):
        raise ValueError(f"up: expected shape (3,) or None, got {u.shape}")
    return (float(u[0]), float(u[1]), float(u[2]))


def fit_obb(
    points: npt.ArrayLike,
    *,
    volume_tolerance: float = 0.01,
    up: npt.ArrayLike | None = Y_UP,
    symmetry: bool = True,
) -> OBB:
    """Fit a tight, up- and symmetry-aligned OBB to a point set.

    See the module documentation for the algorithm, the selection rule and the canonical
    axis order. Typically called on the vertices of a part's meshes (which contain its
    surface). Deterministic: independent of the order of the points and of duplicates.

    Parameters
    ----------
    points : (N, 3) float64
        N >= 1, finite, any frame and units. Degenerate sets (all equal, collinear,
        coplanar) give zero half-extents along the missing directions.
    volume_tolerance : float, default 0.01
        Relative volume slack of the near-minimal boxes among which the up-aligned and most
        symmetric one is chosen; ``0`` returns the smallest box found.
    up : (3,) array-like or None, default (0, 1, 0)
        The object's up direction (need not be unit); ``None`` disables the up preference.
    symmetry : bool, default True
        Prefer boxes whose mid-planes are reflective-symmetry planes of the points.

    Returns
    -------
    OBB
        Its volume is at most ``1 + volume_tolerance`` times the minimum-volume box of
        ``trimesh.bounds.oriented_bounds`` (smaller where the refinement finds a tighter
        box), and it contains every point up to rounding.

    Raises
    ------
    ValueError
        Empty input, shape other than ``(N, 3)``, NaN/inf (naming the flat index), or bad
        options.

    References
    ----------
    J. O'Rourke, *Finding minimal enclosing boxes*, Int. J. Comput. Inf. Sci. 14, 1985.
    N. Fish et al., *Meta-representation of shape families*, ACM TOG 33(4), 2014.
    """
    arr = np.ascontiguousarray(points, dtype=np.float64)
    if arr.ndim != 2:
        raise ValueError(f"points: expected shape (N, 3), got {arr.shape}")
    c, a, h = _core.fit_obb(
        arr, volume_tolerance=float(volume_tolerance), up=_up(up), symmetry=bool(symmetry)
    )
    return OBB(c, a, h)


def fit_obb_batch(
    point_sets: Sequence[npt.ArrayLike],
    *,
    volume_tolerance: float = 0.01,
    up: npt.ArrayLike | None = Y_UP,
    symmetry: bool = True,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Fit one OBB per point set, in parallel (Rust threads, GIL released).

    Same rule and options as :func:`fit_obb`; box ``i`` equals ``fit_obb(point_sets[i])``.

    Parameters
    ----------
    point_sets : sequence of (N_i, 3) float64
        Each N_i >= 1, finite.

    Returns
    -------
    centers : (B, 3) float64
    axes : (B, 3, 3) float64
        Rows of each box's axes.
    half_extents : (B, 3) float64

    Raises
    ------
    ValueError
        The first bad set in input order, named ``point_sets[i]``.
    """
    arrays = []
    for i, p in enumerate(point_sets):
        arr = np.ascontiguousarray(p, dtype=np.float64)
        if arr.ndim != 2:
            raise ValueError(f"point_sets[{i}]: expected shape (N, 3), got {arr.shape}")
        arrays.append(arr)
    return _core.fit_obb_batch(
        arrays, volume_tolerance=float(volume_tolerance), up=_up(up), symmetry=bool(symmetry)
    )
