"""Symmetry-aware part errors: detection of continuous symmetry axes on real parts and the
closed-form alignment of a predicted pose about the axis."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from kinmo.ancsh.dataset import object_parts_of
from kinmo.ancsh.evaluate import FrameTruth, frame_errors, ground_truth_estimate
from kinmo.ancsh.postprocess import PartPose
from kinmo.ancsh.symmetry import align_about_axis, axis_rotation, part_symmetry_axes, symmetry_ratio
from kinmo.metrics.pose import rotation_error_deg


def _angle(u: np.ndarray, v: np.ndarray) -> float:
    return float(np.degrees(np.arccos(np.clip(u @ v / np.linalg.norm(u) / np.linalg.norm(v), -1, 1))))


def test_axis_rotation_is_rodrigues():
    r = axis_rotation(np.array([0.0, 0.0, 2.0]), np.pi / 2)
    np.testing.assert_allclose(r @ [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(r @ r.T, np.eye(3), atol=1e-12)


@pytest.mark.parametrize("seed", range(5))
def test_alignment_error_is_the_angle_between_the_axis_images(seed):
    rng = np.random.default_rng(seed)
    axis = rng.normal(size=3)
    axis /= np.linalg.norm(axis)
    r_true = Rotation.random(random_state=seed).as_matrix()
    r_pred = Rotation.random(random_state=seed + 100).as_matrix()
    pred = PartPose(r_pred, rng.normal(size=3), 0.7, np.full(3, 0.3), 50)
    truth = PartPose(r_true, rng.normal(size=3), 0.7, np.full(3, 0.3), 50)
    al = align_about_axis(pred, truth, axis)
    err = rotation_error_deg(al.rotation, r_true)
    assert err == pytest.approx(_angle(r_pred @ axis, r_true @ axis), abs=1e-6)
    assert err <= rotation_error_deg(r_pred, r_true) + 1e-9
    # no other rotation about the axis does better
    for phi in np.linspace(0, 2 * np.pi, 37):
        assert rotation_error_deg(r_pred @ axis_rotation(axis, phi), r_true) >= err - 1e-6
    # the axis image and the points on the axis (through the box centre) do not move
    np.testing.assert_allclose(al.rotation @ axis, r_pred @ axis, atol=1e-12)
    c = np.full(3, 0.5) + 0.2 * axis
    np.testing.assert_allclose(al.scale * al.rotation @ c + al.translation,
                               pred.scale * r_pred @ c + pred.translation, atol=1e-12)


def test_a_pose_rotated_about_the_symmetry_axis_has_zero_error():
    """The true pose composed with a rotation about the axis through the box centre: zero
    rotation and translation error, IoU 1, only with the symmetry given."""
    axis = np.array([0.0, 1.0, 0.0])
    r_t = Rotation.from_euler("xyz", [10, 40, -20], degrees=True).as_matrix()
    truth_part = PartPose(r_t, np.array([0.1, -0.2, 1.5]), 0.8, np.array([0.3, 0.2, 0.3]), 100)
    other = PartPose(np.eye(3), np.array([0.0, 0.0, 2.0]), 0.5, np.array([0.2, 0.3, 0.1]), 80)
    truth = FrameTruth([truth_part, other], [])
    est = ground_truth_estimate(truth)
    a = axis_rotation(axis, np.radians(70))
    c = np.full(3, 0.5)
    est.parts[0] = PartPose(r_t @ a, truth_part.translation + truth_part.scale * r_t @ (c - a @ c),
                            0.8, truth_part.box_half.copy(), 100)
    plain = frame_errors(est, truth)
    assert plain.rotation_deg[0] == pytest.approx(70.0, abs=1e-6) and plain.iou[0] < 0.99
    sym = frame_errors(est, truth, [axis, None])
    assert sym.rotation_deg[0] == pytest.approx(0.0, abs=1e-5)
    assert sym.translation[0] == pytest.approx(0.0, abs=1e-9) and sym.iou[0] == pytest.approx(1.0, abs=1e-6)
    np.testing.assert_allclose(sym.rotation_deg[1:], plain.rotation_deg[1:])
    with pytest.raises(ValueError, match="symmetry entries"):
        frame_errors(est, truth, [axis])


def test_symmetry_ratio_separates_a_cylinder_from_a_box():
    rng = np.random.default_rng(0)

    def cylinder(n):
        t, z = rng.uniform(0, 2 * np.pi, n), rng.uniform(-1, 1, n)
        return np.stack([0.5 * np.cos(t), 0.5 * np.sin(t), z], axis=1)

    def box(n):
        p = rng.uniform(-1, 1, (n, 3)) * [0.5, 0.5, 1.0]
        face = rng.integers(0, 2, n)  # points on the x or y faces
        p[np.arange(n), face] = np.sign(rng.uniform(-1, 1, n)) * 0.5
        return p

    a, b = cylinder(3000), cylinder(3000)
    assert symmetry_ratio(a, b, np.array([0.0, 0.0, 1.0])) < 1.3
    assert symmetry_ratio(a, b, np.array([1.0, 0.0, 0.0])) > 3
    assert symmetry_ratio(box(3000), box(3000), np.array([0.0, 0.0, 1.0])) > 2  # 4-fold only


@pytest.mark.exactdata
def test_bucket_body_is_symmetric_about_up_and_laptop_parts_are_not(mobility_root):
    shape, parts = object_parts_of(mobility_root / "100441")  # bucket: body + handle
    axes = part_symmetry_axes(shape, parts)
    assert len(axes) == 2 and axes[1] is None
    assert axes[0] is not None and abs(axes[0][1]) == pytest.approx(1.0)  # mesh y-up
    shape, parts = object_parts_of(mobility_root / "10040")  # laptop: base + lid
    assert part_symmetry_axes(shape, parts) == [None, None]
