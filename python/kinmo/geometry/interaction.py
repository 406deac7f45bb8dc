"""Interaction region between a moving part and its reference part (Hu et al. 2015)."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from kinmo import _core


class InteractionRegion(NamedTuple):
    """Points of two parts near each other.

    Attributes
    ----------
    mask_moving : (Na,) bool
        Points of the moving part within ``radius`` of a reference point.
    mask_reference : (Nb,) bool
        Points of the reference part within ``radius`` of a moving point.
    centroid : (3,) float64
        Mean of all selected points of both parts: the pivot candidate of the refinement
        stage (Liu et al. 2023 Sec. 3.3). When nothing is within ``radius`` it is the midpoint
        of the closest pair of points, and ``empty`` is True.
    empty : bool
    """

    mask_moving: np.ndarray
    mask_reference: np.ndarray
    centroid: np.ndarray
    empty: bool


def interaction_region(
    moving: np.ndarray, reference: np.ndarray, radius: float
) -> InteractionRegion:
    """Interaction region of two point clouds (k-d tree, Rust).

    Parameters
    ----------
    moving : (Na, 3) float64
    reference : (Nb, 3) float64
    radius : float
        Absolute distance, > 0.

    Returns
    -------
    InteractionRegion
    """
    ma, mb, c, empty = _core.interaction_region(
        np.ascontiguousarray(moving, dtype=np.float64),
        np.ascontiguousarray(reference, dtype=np.float64),
        float(radius),
    )
    return InteractionRegion(ma, mb, c, bool(empty))
