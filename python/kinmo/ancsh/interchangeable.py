"""Interchangeable parts and permutation-matched part errors (``kinmo eval``).

ANCSH's protocol (Li et al. CVPR 2020, as NOCS, Wang et al. CVPR 2019, for whole objects)
scores predicted part ``k`` against true part ``k``: the part order of the category's
structure (:func:`kinmo.ancsh.structure.object_parts`: siblings by joint type, name, then top
to bottom and left to right) is taken as the parts' identity. Two parts that play the same
kinematic role (the two temples of eyeglasses, the two doors of a cabinet) can be told apart
only by that order; a network that segments them the other way round gets both poses right
and both errors large. kinmo keeps that raw metric, and reports beside it the errors under the
assignment of predicted to true parts that minimises the summed rotation error within each
group of interchangeable parts.

**The rule** (:func:`interchangeable_groups`, from the structure alone): parts are
interchangeable when they

1. have the same parent part,
2. are attached to it by joints of the same type (revolute or prismatic), and
3. are leaves of the kinematic tree (no child parts).

Limits: the rule reads the structure, not the geometry, so two doors of different widths are
interchangeable as well as two mirror-image temples (the matching can only lower an error,
and the raw error stays the default). Parts with children are never matched: swapping two
of them would swap their whole sub-trees (no structure of the shared data has such a pair).
The base (part 0) has no parent and is never matched, so objects whose two halves are the
base and its only child (PartNet-Mobility's Pliers and Scissors: structure ``0<R-1``) have
nothing to match; ANCSH's base is the frame of reference, not a part to swap.

**The matching** (:func:`part_permutation`): per group, the cost of scoring predicted part
``b`` against true part ``a`` is their geodesic rotation error (degrees; up to ``a``'s
continuous symmetry axis when it has one, :func:`kinmo.ancsh.symmetry.align_about_axis`),
and :func:`scipy.optimize.linear_sum_assignment` picks the assignment of least summed cost.
The identity is kept unless the best assignment is lower by more than
:data:`TIE_TOLERANCE_DEG`, so ties never swap. The joint heading a matched part (joint
``k - 1`` heads part ``k``) follows its part: the axis and state errors of a swapped part are
those of the predicted joint of the predicted part it was assigned.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from scipy.optimize import linear_sum_assignment

from kinmo.ancsh.frame_metrics import FrameErrors, FrameTruth, frame_errors
from kinmo.ancsh.postprocess import ANCSHEstimate
from kinmo.ancsh.structure import KinematicStructure
from kinmo.ancsh.symmetry import align_about_axis
from kinmo.metrics.pose import rotation_error_deg

__all__ = ["TIE_TOLERANCE_DEG", "describe_groups", "interchangeable_groups", "matched_frame_errors",
           "part_permutation", "permute_estimate"]

#: A permutation other than the identity is kept only when it lowers the summed rotation
#: error of its group by more than this (degrees).
TIE_TOLERANCE_DEG: float = 1e-6
#: Cost of a pair whose rotation error is not finite (degrees; above the largest error, 180).
_UNDEFINED_COST = 1e3


def interchangeable_groups(structure: KinematicStructure) -> list[tuple[int, ...]]:
    """Groups of interchangeable parts of a structure (module docstring for the rule).

    Parameters
    ----------
    structure : KinematicStructure

    Returns
    -------
    list of tuple of int
        Each group: two or more ANCSH part indices in increasing order, never part 0; groups
        ordered by their first part. Empty when no parts are interchangeable.
    """
    parents = structure.parents
    has_child = {p for p in parents[1:]}
    by_role: dict[tuple[int, str], list[int]] = {}
    for k in range(1, structure.n_parts):
        if k not in has_child:
            by_role.setdefault((parents[k], structure.joint_types[k - 1]), []).append(k)
    return sorted(tuple(g) for g in by_role.values() if len(g) > 1)


def describe_groups(groups: Sequence[Sequence[int]], structure: KinematicStructure) -> str:
    """One line naming the groups, e.g. ``"parts 1, 2 (revolute children of part 0)"``; an
    empty string without groups."""
    return "; ".join(f"parts {', '.join(map(str, g))} ({structure.joint_types[g[0] - 1]} children of part "
                     f"{structure.parents[g[0]]})" for g in groups)


def part_permutation(est: ANCSHEstimate, truth: FrameTruth, groups: Sequence[Sequence[int]],
                     symmetry: Sequence[np.ndarray | None] | None = None) -> np.ndarray:
    """The assignment of predicted to true parts of least summed rotation error per group.

    Parameters
    ----------
    est : ANCSHEstimate
        K predicted parts (NPCS -> camera similarities).
    truth : FrameTruth
        K true parts, same frame (camera).
    groups : sequence of sequence of int
        Interchangeable parts (:func:`interchangeable_groups`).
    symmetry : sequence of (3,) float or None, optional
        Per true part: its continuous symmetry axis in NPCS, or None
        (:func:`kinmo.ancsh.symmetry.part_symmetry_axes`); the cost of a symmetric true part
        is its symmetry-aware rotation error.

    Returns
    -------
    (K,) int64
        ``perm[k]``: the predicted part scored against true part ``k``; the identity outside
        the groups, and inside a group unless a swap lowers the group's summed rotation error
        by more than :data:`TIE_TOLERANCE_DEG` degrees.

    Raises
    ------
    ValueError
        Different numbers of parts, or a group index out of range or equal to 0.
    """
    k = len(truth.parts)
    if len(est.parts) != k:
        raise ValueError(f"estimate has {len(est.parts)} parts, truth {k}")
    perm = np.arange(k, dtype=np.int64)
    for g in groups:
        g = [int(x) for x in g]
        if any(not 0 < x < k for x in g) or len(set(g)) != len(g):
            raise ValueError(f"group {g}: parts must be distinct, in 1..{k - 1}")
        cost = np.empty((len(g), len(g)))
        for i, a in enumerate(g):
            t = truth.parts[a]
            axis = symmetry[a] if symmetry is not None else None
            for j, b in enumerate(g):
                p = est.parts[b]
                if axis is not None:
                    p = align_about_axis(p, t, axis)
                c = rotation_error_deg(p.rotation, t.rotation)
                cost[i, j] = c if np.isfinite(c) else _UNDEFINED_COST
        rows, cols = linear_sum_assignment(cost)
        if cost[rows, cols].sum() < np.trace(cost) - TIE_TOLERANCE_DEG:
            for i, j in zip(rows, cols):
                perm[g[i]] = g[j]
    return perm


def permute_estimate(est: ANCSHEstimate, perm: Sequence[int] | np.ndarray) -> ANCSHEstimate:
    """The estimate with its parts reordered: part ``k`` of the result is part ``perm[k]`` of
    ``est``, the joint heading it is the joint heading ``perm[k]`` (joint ``perm[k] - 1``),
    and the per-point segmentation labels are renamed alike.

    Parameters
    ----------
    est : ANCSHEstimate
    perm : (K,) int
        A permutation of ``0..K-1`` with ``perm[0] == 0`` (the base stays the base).

    Returns
    -------
    ANCSHEstimate
        Shares the part and joint objects of ``est`` (not copied); same NAOCS -> camera
        similarity.

    Raises
    ------
    ValueError
        ``perm`` is not such a permutation.
    """
    perm = np.asarray(perm, dtype=np.int64)
    k = len(est.parts)
    if perm.shape != (k,) or sorted(perm.tolist()) != list(range(k)) or perm[0] != 0:
        raise ValueError(f"{perm.tolist()} is not a permutation of the {k} parts fixing part 0")
    parts = [est.parts[int(p)] for p in perm]
    joints = [est.joints[int(p) - 1] for p in perm[1:]]
    seg = np.asarray(est.segmentation)
    if seg.size:
        new_label = np.empty(k, dtype=np.int64)
        new_label[perm] = np.arange(k)
        ok = (seg >= 0) & (seg < k)
        seg = np.where(ok, new_label[np.clip(seg, 0, k - 1)], seg)
    return ANCSHEstimate(parts, joints, est.naocs_to_camera, seg)


def matched_frame_errors(est: ANCSHEstimate, truth: FrameTruth, groups: Sequence[Sequence[int]],
                         symmetry: Sequence[np.ndarray | None] | None = None) -> tuple[FrameErrors, np.ndarray]:
    """Permutation-matched errors of one estimate (module docstring).

    Parameters
    ----------
    est, truth, groups, symmetry
        As :func:`part_permutation` (``symmetry`` is also passed to
        :func:`kinmo.ancsh.frame_metrics.frame_errors`).

    Returns
    -------
    errors : FrameErrors
        :func:`~kinmo.ancsh.frame_metrics.frame_errors` of the permuted estimate: per true part
        (K,) and per true joint (J,), same units as the raw errors (degrees, mesh units). Equal
        to the raw errors when ``perm`` is the identity.
    perm : (K,) int64
        :func:`part_permutation`.
    """
    perm = part_permutation(est, truth, groups, symmetry)
    if len(est.joints) != len(truth.joints):  # frame_errors' own message
        return frame_errors(est, truth, symmetry), perm
    return frame_errors(permute_estimate(est, perm), truth, symmetry), perm
