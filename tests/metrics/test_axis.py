"""Axis metrics: angle between axis lines, point-to-line and line-to-line distances."""

from __future__ import annotations

import numpy as np
import pytest

from kinmo.metrics.axis import axis_angle_deg, line_distance, point_line_distance


def test_angle_parallel_antiparallel_perpendicular():
    assert axis_angle_deg([0, 1, 0], [0, 2, 0]) == pytest.approx(0.0, abs=1e-12)
    assert axis_angle_deg([0, 1, 0], [0, -3, 0]) == pytest.approx(0.0, abs=1e-12)
    assert axis_angle_deg([1, 0, 0], [0, 0, 1]) == pytest.approx(90.0)
    assert axis_angle_deg([1, 1, 0], [1, 0, 0]) == pytest.approx(45.0)
    # 135 degrees between directions is 45 degrees between lines
    assert axis_angle_deg([-1, 1, 0], [1, 0, 0]) == pytest.approx(45.0)


def test_angle_small_is_accurate_and_batched():
    eps = 1e-7
    a = axis_angle_deg([1.0, eps, 0.0], [1.0, 0.0, 0.0])
    assert a == pytest.approx(np.degrees(eps), rel=1e-6)
    out = axis_angle_deg(np.array([[0, 1, 0], [1, 0, 0], [0, 0, -1]]), np.array([0, 1, 0]))
    np.testing.assert_allclose(out, [0.0, 90.0, 90.0], atol=1e-12)


def test_skew_lines_distance_hand_computed():
    # Line 1: the x axis. Line 2: through (0, 0, 2) along (0, 1, 0) -> common perpendicular is z, length 2.
    assert line_distance([0, 0, 0], [1, 0, 0], [0, 0, 2], [0, 1, 0]) == pytest.approx(2.0)
    # Line 2 through (5, 3, -1.5) along (0, 1, 1): n = x x (0,1,1) = (0,-1,1)/sqrt2; w=(5,3,-1.5)
    # |w . n| = |-3 - 1.5| / sqrt2 = 4.5 / sqrt2
    assert line_distance([0, 0, 0], [1, 0, 0], [5, 3, -1.5], [0, 1, 1]) == pytest.approx(4.5 / np.sqrt(2))


def test_intersecting_and_parallel_lines():
    assert line_distance([0, 0, 0], [1, 0, 0], [3, -1, 0], [0, 1, 0]) == pytest.approx(0.0, abs=1e-12)
    # parallel: distance between them, independent of where the points sit along the lines
    assert line_distance([0, 0, 0], [0, 1, 0], [3, 7, 4], [0, -2, 0]) == pytest.approx(5.0)
    assert line_distance([1, 2, 3], [1, 1, 1], [1, 2, 3], [2, 2, 2]) == pytest.approx(0.0, abs=1e-12)


def test_point_line_distance():
    assert point_line_distance([0, 3, 4], [0, 0, 0], [1, 0, 0]) == pytest.approx(5.0)
    assert point_line_distance([7, 0, 0], [0, 0, 0], [2, 0, 0]) == pytest.approx(0.0)
    out = point_line_distance(np.array([[0, 1, 0], [0, 0, 2]]), np.zeros(3), np.array([1, 0, 0]))
    np.testing.assert_allclose(out, [1.0, 2.0])


def test_bad_input_raises():
    with pytest.raises(ValueError, match="d_pred"):
        axis_angle_deg([0, 0, 0], [0, 1, 0])
    with pytest.raises(ValueError, match="shape"):
        line_distance([0, 0], [1, 0, 0], [0, 0, 1], [0, 1, 0])
    with pytest.raises(ValueError, match="finite"):
        point_line_distance([np.nan, 0, 0], [0, 0, 0], [1, 0, 0])
