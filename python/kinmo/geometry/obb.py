"""Oriented bounding boxes (OBB) of point sets."""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import numpy as np

from kinmo import _core


class OBB(NamedTuple):
    """An oriented bounding box.

    Attributes
    ----------
    center : (3,) float64
    axes : (3, 3) float64
        Orthonormal rows, right-handed (``axes[2] = cross(axes[0], axes[1])``).
    half_extents : (3,) float64
        Half side length along each row of ``axes``.
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


def fit_obb(points: np.ndarray) -> OBB:
    """Fit a tight OBB to a point set (see the Rust ``obb`` module for the algorithm).

    Parameters
    ----------
    points : (N, 3) float64
        N >= 1, finite. Degenerate sets (all equal, collinear, coplanar) give zero
        half-extents along the missing directions.

    Returns
    -------
    OBB

    Raises
    ------
    ValueError
        Empty input, bad shape or non-finite values.
    """
    c, a, h = _core.fit_obb(np.ascontiguousarray(points, dtype=np.float64))
    return OBB(c, a, h)


def fit_obb_batch(point_sets: Sequence[np.ndarray]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Fit OBBs to many point sets in parallel.

    Parameters
    ----------
    point_sets : sequence of (N_i, 3) float64

    Returns
    -------
    centers : (B, 3) float64
    axes : (B, 3, 3) float64
    half_extents : (B, 3) float64
    """
    return _core.fit_obb_batch([np.ascontiguousarray(p, dtype=np.float64) for p in point_sets])
