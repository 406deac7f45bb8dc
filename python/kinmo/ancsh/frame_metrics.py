"""Per-frame ground truth and errors of ANCSH estimates (Table 2 of Liu et al. CVPR 2023).

:func:`frame_truth` reads a rendered frame's ground truth in ANCSH order; :func:`frame_errors`
compares an :class:`~kinmo.ancsh.postprocess.ANCSHEstimate` with it (the metrics are defined
in :mod:`kinmo.ancsh.evaluate`). :func:`ground_truth_estimate` and
:func:`ground_truth_predictions` give a perfect estimate / network output, the identity checks
of the metric path and of the post-processing.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from kinmo.ancsh.pose_fitting import Similarity
from kinmo.ancsh.postprocess import ANCSHEstimate, JointEstimate, PartPose
from kinmo.ancsh.structure import KinematicStructure, ObjectParts
from kinmo.ancsh.symmetry import align_about_axis
from kinmo.errors import KinmoDataError
from kinmo.metrics.axis import axis_angle_deg, line_distance
from kinmo.metrics.pose import box_iou_3d, rotation_error_deg

__all__ = [
    "FrameErrors",
    "FrameTruth",
    "frame_errors",
    "frame_truth",
    "ground_truth_estimate",
    "ground_truth_predictions",
]


# ---------------------------------------------------------------------------- ground truth


@dataclass
class FrameTruth:
    """Ground truth of one rendered frame in ANCSH order (camera frame, mesh units).

    Attributes
    ----------
    parts : list of PartPose
        Per ANCSH part: NPCS -> camera similarity, ``box_half`` the half extents of its full
        rest box in NPCS, ``n_points`` visible points.
    joints : list of JointEstimate
        Per joint: origin and unit direction in the camera frame, state (radians / mesh
        units, 0 at rest), type.
    """

    parts: list[PartPose]
    joints: list[JointEstimate]


def _orthonormal(r: Any) -> np.ndarray:
    """The rotation nearest to ``r`` (frames store float32 matrices)."""
    u, _, vt = np.linalg.svd(np.asarray(r, dtype=np.float64))
    m = u @ vt
    if np.linalg.det(m) < 0:
        u[:, -1] *= -1
        m = u @ vt
    return m


def frame_truth(frame: Mapping[str, Any], parts: ObjectParts) -> FrameTruth:
    """Ground truth of a frame (:func:`kinmo.render.dataset.load_frame`) in ANCSH order.

    Parameters
    ----------
    frame : mapping
    parts : ObjectParts
        The object's mapping onto ANCSH parts (:func:`kinmo.ancsh.objects.object_parts_of`).

    Returns
    -------
    FrameTruth

    Raises
    ------
    KinmoDataError
        A part or joint of ``parts`` is missing from the frame.
    """
    meta = frame.get("meta", {})
    where = f"frame {meta.get('frame', '?')} of {meta.get('key', '?')}"
    pids = [int(p) for p in np.asarray(frame["part_ids"])]
    k = parts.structure.n_parts
    row_of_part: dict[int, int] = {}
    for r, pid in enumerate(pids):
        if pid in parts.link_part:
            row_of_part.setdefault(parts.link_part[pid], r)
    if sorted(row_of_part) != list(range(k)):
        raise KinmoDataError(where, f"rigid parts {pids} do not cover the {k} ANCSH parts")
    point_part = np.array([parts.link_part.get(int(l), -1) for l in np.asarray(frame["link"])], dtype=np.int64)
    vis = [int((point_part == a).sum()) for a in range(k)]
    out_parts = []
    for a in range(k):
        r = row_of_part[a]
        lo, hi = np.asarray(frame["part_bounds"][r], dtype=np.float64)
        out_parts.append(PartPose(
            _orthonormal(frame["part_rotation"][r]),
            np.asarray(frame["part_translation"][r], dtype=np.float64),
            float(frame["part_scale"][r]), (hi - lo) / 2.0, vis[a],
        ))
    jids = [int(j) for j in np.asarray(frame["joint_ids"])]
    kinds = ("revolute", "prismatic", "cylindrical")
    out_joints = []
    for j, lid in enumerate(parts.joint_links):
        if lid not in jids:
            raise KinmoDataError(where, f"joint {j} (moving link {lid}) is missing")
        r = jids.index(lid)
        kind = kinds[int(frame["joint_type"][r])]
        d = np.asarray(frame["joint_direction"][r], dtype=np.float64)
        state = float(frame["joint_angle"][r]) if kind == "revolute" else float(frame["joint_translation"][r])
        out_joints.append(JointEstimate(np.asarray(frame["joint_origin"][r], dtype=np.float64),
                                        d / np.linalg.norm(d), state, kind))
    return FrameTruth(out_parts, out_joints)


def ground_truth_estimate(truth: FrameTruth, segmentation: np.ndarray | None = None) -> ANCSHEstimate:
    """An :class:`~kinmo.ancsh.postprocess.ANCSHEstimate` equal to the ground truth (the
    identity check of the metric path: :func:`frame_errors` of it is zero, IoU one)."""

    parts = [PartPose(p.rotation.copy(), p.translation.copy(), p.scale, p.box_half.copy(), p.n_points)
             for p in truth.parts]
    joints = [JointEstimate(j.origin.copy(), j.direction.copy(), j.state, j.type) for j in truth.joints]
    seg = np.zeros(0, dtype=np.int64) if segmentation is None else np.asarray(segmentation)
    return ANCSHEstimate(parts, joints, Similarity(np.eye(3), np.zeros(3), 1.0), seg)


def ground_truth_predictions(sample: Any, structure: KinematicStructure, logit: float = 10.0) -> dict[str, np.ndarray]:
    """Per-point "predictions" equal to a sample's targets (one-hot logits), the input of
    :func:`kinmo.ancsh.postprocess.estimate` a perfect network would give.

    Parameters
    ----------
    sample : FrameSample
    structure : KinematicStructure
    logit : float
        Logit of the true class (others 0).

    Returns
    -------
    dict of numpy arrays, ANCSH output layout without batch dimension.
    """
    k, j = structure.n_parts, structure.n_joints
    return {
        "seg_logits": np.eye(k)[sample.seg] * logit,
        "npcs": np.repeat(np.asarray(sample.npcs, dtype=np.float64)[:, None], k, axis=1),
        "naocs": np.asarray(sample.naocs, dtype=np.float64),
        "heatmap": np.asarray(sample.heatmap, dtype=np.float64),
        "unitvec": np.asarray(sample.unitvec, dtype=np.float64),
        "axis": np.asarray(sample.axis, dtype=np.float64),
        "joint_logits": np.eye(j + 1)[sample.joint] * logit,
    }


# --------------------------------------------------------------------------------- errors


@dataclass
class FrameErrors:
    """Errors of one estimate against one frame's truth (module docstring).

    Attributes
    ----------
    rotation_deg, translation, iou : (K,) float64
    state, angle_deg, distance : (J,) float64
        ``state``: degrees (revolute) or mesh units (prismatic); ``distance``: NaN for
        prismatic joints.
    """

    rotation_deg: np.ndarray
    translation: np.ndarray
    iou: np.ndarray
    state: np.ndarray
    angle_deg: np.ndarray
    distance: np.ndarray


def _center(p: PartPose) -> np.ndarray:
    return p.scale * p.rotation @ np.full(3, 0.5) + p.translation


def frame_errors(est: ANCSHEstimate, truth: FrameTruth,
                 symmetry: Sequence[np.ndarray | None] | None = None) -> FrameErrors:
    """Per-part and per-joint errors of an estimate (module docstring).

    Parameters
    ----------
    est : ANCSHEstimate
    truth : FrameTruth
    symmetry : sequence of (3,) float or None, optional
        Per part: its continuous symmetry axis in NPCS
        (:func:`kinmo.ancsh.symmetry.part_symmetry_axes`) or None. The pose of a symmetric
        part is first replaced by its symmetric equivalent closest to the truth
        (:func:`kinmo.ancsh.symmetry.align_about_axis`), so its rotation error is the angle
        between the predicted and true axis. Default: no part is symmetric.

    Raises
    ------
    ValueError
        Different numbers of parts or joints (or of symmetry entries).
    """
    if len(est.parts) != len(truth.parts) or len(est.joints) != len(truth.joints):
        raise ValueError(f"estimate has {len(est.parts)} parts / {len(est.joints)} joints, truth "
                         f"{len(truth.parts)} / {len(truth.joints)}")
    if symmetry is not None and len(symmetry) != len(truth.parts):
        raise ValueError(f"{len(symmetry)} symmetry entries for {len(truth.parts)} parts")
    rot, tra, iou = [], [], []
    for k, (p, t) in enumerate(zip(est.parts, truth.parts)):
        if symmetry is not None and symmetry[k] is not None:
            p = align_about_axis(p, t, symmetry[k])
        rot.append(rotation_error_deg(p.rotation, t.rotation))
        tra.append(float(np.linalg.norm(_center(p) - _center(t))))
        iou.append(box_iou_3d(*p.box(), *t.box()))
    state, ang, dist = [], [], []
    for p, t in zip(est.joints, truth.joints):
        d = np.asarray(p.direction, dtype=np.float64)
        s = -p.state if float(d @ t.direction) < 0 else p.state
        if t.type == "revolute":  # angle difference wrapped to [0, 180] degrees
            state.append(float(np.degrees(abs((s - t.state + np.pi) % (2 * np.pi) - np.pi))))
            dist.append(float(line_distance(p.origin, d, t.origin, t.direction)))
        else:
            state.append(abs(s - t.state))
            dist.append(float("nan"))
        ang.append(float(axis_angle_deg(d, t.direction)))
    f = lambda x: np.asarray(x, dtype=np.float64)  # noqa: E731
    return FrameErrors(f(rot), f(tra), f(iou), f(state), f(ang), f(dist))
