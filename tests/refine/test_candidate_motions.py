"""Candidate motions and network inputs (kinmo.refine.motions)."""

from __future__ import annotations

import numpy as np
import pytest

from kinmo.refine.candidates import candidate_axes
from kinmo.refine.motions import (
    MotionAmounts,
    candidate_motions,
    extent_along,
    network_inputs,
    pair_cloud,
)


def _rotate(points, origin, direction, angle):
    d = direction / np.linalg.norm(direction)
    k = np.array([[0, -d[2], d[1]], [d[2], 0, -d[0]], [-d[1], d[0], 0]])
    r = np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * k @ k
    return (points - origin) @ r.T + origin


OBB = (np.array([0.0, 1.0, 0.0]), np.eye(3), np.array([0.5, 1.0, 0.1]))


def test_both_directions_of_every_line_and_amounts():
    c = candidate_axes(OBB, "R_V_S")
    m = candidate_motions(c, OBB, MotionAmounts((30.0, 60.0)))
    assert len(m) == 4 * 2 * 2
    np.testing.assert_array_equal(m.line, np.repeat(np.arange(4), 4))
    np.testing.assert_array_equal(m.sign, np.tile([1, 1, -1, -1], 4))
    np.testing.assert_allclose(m.directions, c.directions[m.line] * m.sign[:, None])
    np.testing.assert_allclose(m.angles, np.radians(np.tile([30, 60, 30, 60], 4)))
    assert np.all(m.translations == 0)
    p = candidate_motions(candidate_axes(OBB, "P_H"), OBB, MotionAmounts(translation_fraction=0.5))
    assert len(p) == 4 and np.all(p.angles == 0)
    # 0.5 x full extent along x (1.0) and z (0.2)
    np.testing.assert_allclose(np.sort(np.unique(p.translations)), [0.1, 0.5])
    np.testing.assert_allclose(extent_along(OBB, np.array([[0.6, 0.8, 0.0]])), [0.6 + 1.6])
    with pytest.raises(ValueError, match="angles_deg"):
        MotionAmounts(angles_deg=(0.0,))


def test_network_inputs_move_only_the_moving_points():
    rng = np.random.default_rng(0)
    mov = rng.uniform(-1, 1, (300, 3))
    ref = rng.uniform(2, 3, (200, 3))
    pair = pair_cloud(mov, ref, 101, rng=1)
    assert pair.n_moving == 51 and pair.points.shape == (101, 3)
    np.testing.assert_array_equal(pair.flags[:51], 1)
    np.testing.assert_array_equal(pair.flags[51:], 0)
    lo, hi = pair.points.min(0), pair.points.max(0)
    np.testing.assert_allclose(pair.center, (lo + hi) / 2)
    assert pair.scale == pytest.approx(np.linalg.norm(hi - lo))
    o = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, 0.0]])
    d = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0]])
    before, after = network_inputs(pair, o, d, np.array([0.7, 0.0]), np.array([0.0, 0.25]))
    assert before.shape == (101, 4) and after.shape == (2, 101, 4)
    assert before.dtype == np.float32 and after.dtype == np.float32
    np.testing.assert_allclose(before[:, :3], (pair.points - pair.center) / pair.scale, atol=1e-6)
    np.testing.assert_array_equal(after[:, 51:], np.broadcast_to(before[51:], (2, 50, 4)))
    rot = _rotate(pair.points[:51], o[0], d[0], 0.7)
    np.testing.assert_allclose(after[0, :51, :3] * pair.scale + pair.center, rot, atol=1e-5)
    np.testing.assert_allclose(after[1, :51, :3] * pair.scale + pair.center,
                               pair.points[:51] + [0.25, 0, 0], atol=1e-5)
    np.testing.assert_array_equal(after[..., 3], np.broadcast_to(pair.flags, (2, 101)))


def test_pair_cloud_is_seeded_and_checks_input():
    rng = np.random.default_rng(0)
    a, b = rng.normal(size=(10, 3)), rng.normal(size=(10, 3))
    np.testing.assert_array_equal(pair_cloud(a, b, 40, 3).points, pair_cloud(a, b, 40, 3).points)
    assert pair_cloud(a, b, 40, 3).points.shape == (40, 3)  # with replacement
    with pytest.raises(ValueError, match="reference_points"):
        pair_cloud(a, np.zeros((0, 3)), 8)
    with pytest.raises(ValueError, match="n_points"):
        pair_cloud(a, b, 1)


def test_shape_context_drops_the_moving_part_and_fills_the_static_share():
    from kinmo.refine.motions import shape_context

    rng = np.random.default_rng(0)
    mov = rng.uniform(0, 1, (400, 3)) * [1, 1, 0]  # a unit square at z = 0
    other = rng.uniform(0, 1, (300, 3)) * [1, 1, 0] + [0, 0, 2]  # a parallel one at z = 2
    shape = np.concatenate([rng.uniform(0, 1, (200, 3)) * [1, 1, 0], other[:200]])
    ctx = shape_context(shape, mov)
    assert len(ctx) == 200 and np.all(ctx[:, 2] == 2)  # only the other part is left
    pair = pair_cloud(mov, other, 100, 0, context_points=ctx, context_fraction=0.25)
    assert pair.n_moving == 50 and pair.points.shape == (100, 3)
    np.testing.assert_array_equal(pair.flags, [1] * 50 + [0] * 50)
    assert np.all(pair.points[:50, 2] == 0) and np.all(pair.points[50:, 2] == 2)
    with pytest.raises(ValueError, match="context_fraction"):
        pair_cloud(mov, other, 100, 0, context_points=ctx, context_fraction=0.5)
    # without context the static half is all reference points
    assert pair_cloud(mov, other, 100, 0, context_points=np.zeros((0, 3))).points.shape == (100, 3)


def test_crop_keeps_static_points_near_the_moving_part():
    rng = np.random.default_rng(1)
    knob = rng.uniform(0, 0.1, (200, 3))  # size ~0.17
    door = rng.uniform(-1, 1, (2000, 3)) * [1, 1, 0] + [0, 0, -0.01]
    pair = pair_cloud(knob, door, 100, 0, crop=0.5)
    static = pair.points[50:]
    # every static point within 0.5 x the knob's size of its box
    d = np.linalg.norm(np.maximum(0, np.maximum(-static, static - 0.1)), axis=1)
    assert np.all(d <= 0.5 * np.linalg.norm(knob.max(0) - knob.min(0)) + 1e-12)
    assert pair.scale < 0.5  # the frame is the knob's neighbourhood, not the door
    far = pair_cloud(knob, door[np.abs(door[:, 0]) > 0.9], 100, 0, crop=0.5)
    assert far.points.shape == (100, 3)  # nothing near: the 8 nearest are used
    assert len(np.unique(far.points[50:], axis=0)) <= 8
