"""Interaction region between a moving part and its reference part.

The interaction region of two parts is the set of points of each part within a radius of the
other part (Hu et al., *Interaction Context (ICON): Towards a Geometric Functionality
Descriptor*, SIGGRAPH 2015). Its centroid is the pivot candidate of the motion refinement
stage of Liu et al., *Semi-Weakly Supervised Object Kinematic Motion Prediction*, CVPR 2023,
Sec. 3.3 (see :mod:`kinmo.refine.candidates`).

Rust (``kinmo-geometry/src/interaction.rs``): a k-d tree per point set (median split,
bounding box per node) queried with early exit, ``O((Na + Nb) log(Na + Nb))``.
"""

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
        Points of the moving part (e.g. surface samples), ``Na >= 1``.
    reference : (Nb, 3) float64
        Points of the reference part, same frame and units, ``Nb >= 1``.
    radius : float
        Absolute distance, finite and > 0, in the units of the points; a point is selected
        when its nearest point of the other part is at distance ``<= radius``.

    Returns
    -------
    InteractionRegion
        Masks, centroid (mean of the selected points of both parts, or the midpoint of the
        closest pair when nothing is selected) and the ``empty`` flag.

    Raises
    ------
    ValueError
        Bad shapes, empty or non-finite point sets (naming ``moving`` / ``reference``), or a
        radius that is not finite and positive.
    """
    ma, mb, c, empty = _core.interaction_region(
        np.ascontiguousarray(moving, dtype=np.float64),
        np.ascontiguousarray(reference, dtype=np.float64),
        float(radius),
    )
    return InteractionRegion(ma, mb, c, bool(empty))
