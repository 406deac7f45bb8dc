"""Range-of-motion metrics (kinmo.metrics.motion_range, issue 35)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from kinmo.metrics.motion_range import (
    continuity_correct,
    hinge_interval,
    onto_true_direction,
    range_iou,
    worst_endpoint_error,
)


def test_iou_of_intervals():
    assert range_iou((0, 90), (0, 90)) == 1.0
    assert range_iou((0, 90), (0, 45)) == pytest.approx(0.5)
    assert range_iou((0, 10), (20, 30)) == 0.0
    assert range_iou((90, 0), (45, 0)) == pytest.approx(0.5)  # ends in either order
    assert range_iou((0, 0), (0, 0)) == 0.0  # no union: no credit


def test_opposite_direction_negates_and_swaps():
    d = np.array([0.0, 1.0, 0.0])
    assert onto_true_direction((0.0, 90.0), d, d) == (0.0, 90.0)
    assert onto_true_direction((0.0, 90.0), -d, d) == (-90.0, 0.0)
    assert onto_true_direction((-10.0, 30.0), -2 * d, d) == (-30.0, 10.0)


def test_hinge_interval_shifts_whole_turns_towards_zero():
    assert hinge_interval(90, 0) == pytest.approx((0.0, 90.0))
    lo, hi = hinge_interval(350, 370)
    assert (lo, hi) == pytest.approx((-10.0, 10.0))
    assert hinge_interval(-180, 180) is None  # a full turn: continuous


def test_worst_end_point_error():
    assert worst_endpoint_error((0, 90), (10, 70)) == 20
    assert worst_endpoint_error((0.0, 0.3), (0.0, 0.1), relative=True) == pytest.approx(2.0)
    assert math.isnan(worst_endpoint_error((0, 1), (0.5, 0.5), relative=True))


def test_continuity():
    assert continuity_correct(True, True) and continuity_correct(False, False)
    assert not continuity_correct(True, False)
