import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from kinmo.metrics.pose import box_iou_3d, joint_state_error, rotation_error_deg, translation_error


def test_rotation_error_identical_is_zero_and_quarter_turn_is_90():
    r = Rotation.random(random_state=0).as_matrix()
    assert rotation_error_deg(r, r) == pytest.approx(0.0, abs=1e-5)
    q = Rotation.from_rotvec([0, np.pi / 2, 0]).as_matrix()
    assert rotation_error_deg(q @ r, r) == pytest.approx(90.0)
    assert rotation_error_deg(Rotation.from_rotvec([np.pi, 0, 0]).as_matrix(), np.eye(3)) == pytest.approx(180.0)


def test_translation_and_joint_state_errors():
    assert translation_error([1, 2, 3], [1, 2, 3]) == 0.0
    assert translation_error([0, 0, 0], [3, 4, 0]) == pytest.approx(5.0)
    assert joint_state_error(np.pi / 2, 0.0, revolute=True) == pytest.approx(90.0)
    assert joint_state_error(0.25, 0.5, revolute=False) == pytest.approx(0.25)


def test_box_iou_identical_disjoint_and_half_overlap():
    c, a, h = np.zeros(3), np.eye(3), np.ones(3)
    assert box_iou_3d(c, a, h, c, a, h) == pytest.approx(1.0)
    assert box_iou_3d(c, a, h, c + [5, 0, 0], a, h) == 0.0
    # shifted by one half-width along x: intersection is half of each box -> IoU 1/3
    assert box_iou_3d(c, a, h, c + [1, 0, 0], a, h) == pytest.approx(1 / 3)
    # a box inside another: IoU = volume ratio
    assert box_iou_3d(c, a, h, c, a, h / 2) == pytest.approx(1 / 8)


def test_box_iou_rotated_against_monte_carlo():
    rng = np.random.default_rng(0)
    ra = Rotation.from_rotvec([0, 0.4, 0]).as_matrix()
    rb = Rotation.from_rotvec([0.3, 0, 0.2]).as_matrix()
    ca, cb = np.zeros(3), np.array([0.3, 0.1, -0.2])
    ha, hb = np.array([1, 0.5, 0.7]), np.array([0.8, 0.6, 0.5])
    iou = box_iou_3d(ca, ra, ha, cb, rb, hb)
    p = rng.uniform(-2, 2, size=(400_000, 3))
    in_a = np.all(np.abs((p - ca) @ ra.T) <= ha, axis=1)
    in_b = np.all(np.abs((p - cb) @ rb.T) <= hb, axis=1)
    mc = (in_a & in_b).sum() / (in_a | in_b).sum()
    assert iou == pytest.approx(mc, abs=0.01)
