"""Batched candidate motions (:mod:`kinmo.geometry.motion`, Rust) against scipy and numpy."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from kinmo import _core
from kinmo.geometry import apply_motions, motion_transforms


def _random_candidates(rng: np.random.Generator, c: int):
    o = rng.normal(size=(c, 3))
    d = rng.normal(size=(c, 3)) * rng.uniform(0.1, 5.0, size=(c, 1))  # not unit length
    a = rng.uniform(-2 * np.pi, 2 * np.pi, size=c)
    t = rng.normal(size=c)
    return o, d, a, t


def _scipy_reference(points, o, d, a, t):
    u = d / np.linalg.norm(d, axis=1, keepdims=True)
    out = []
    for k in range(len(o)):
        r = Rotation.from_rotvec(u[k] * a[k])
        out.append(r.apply(points - o[k]) + o[k] + t[k] * u[k])
    return np.stack(out)


def test_agrees_with_scipy_rotvec_plus_translation():
    rng = np.random.default_rng(0)
    points = rng.normal(size=(500, 3))
    o, d, a, t = _random_candidates(rng, 64)
    out = apply_motions(points, o, d, a, t)
    assert out.shape == (64, 500, 3) and out.dtype == np.float64
    np.testing.assert_allclose(out, _scipy_reference(points, o, d, a, t), rtol=0, atol=1e-12)


def test_matrices_agree_with_apply_and_numpy_einsum():
    rng = np.random.default_rng(1)
    points = rng.normal(size=(300, 3))
    o, d, a, t = _random_candidates(rng, 20)
    m = motion_transforms(o, d, a, t)
    assert m.shape == (20, 4, 4) and m.dtype == np.float64
    np.testing.assert_array_equal(m[:, 3], np.tile([0.0, 0.0, 0.0, 1.0], (20, 1)))
    r = m[:, :3, :3]
    rrt = np.einsum("cij,ckj->cik", r, r)
    np.testing.assert_allclose(rrt, np.tile(np.eye(3), (20, 1, 1)), atol=1e-14)
    np.testing.assert_allclose(np.linalg.det(r), 1.0, atol=1e-14)
    via_numpy = np.einsum("cij,nj->cni", r, points) + m[:, None, :3, 3]
    np.testing.assert_allclose(apply_motions(points, o, d, a, t), via_numpy, rtol=0, atol=1e-12)


def test_right_hand_rule_and_offset_axis():
    # +90 deg about +z through (1, 1, 0): (2, 1, 0) -> (1, 2, 0); +90 deg about +x: y -> z.
    out = apply_motions(
        np.array([[2.0, 1.0, 0.0], [1.0, 1.0, 5.0]]),
        np.array([[1.0, 1.0, 0.0]]),
        np.array([[0.0, 0.0, 3.0]]),
        np.array([np.pi / 2]),
    )
    np.testing.assert_allclose(out[0], [[1.0, 2.0, 0.0], [1.0, 1.0, 5.0]], atol=1e-15)
    m = motion_transforms(np.zeros((1, 3)), np.array([[1.0, 0.0, 0.0]]), np.array([np.pi / 2]))
    np.testing.assert_allclose(m[0, :3, :3] @ [0.0, 1.0, 0.0], [0.0, 0.0, 1.0], atol=1e-15)


def test_defaults_full_turn_and_prismatic():
    rng = np.random.default_rng(2)
    points = rng.normal(size=(50, 3))
    o, d, _, _ = _random_candidates(rng, 5)
    # No angle, no translation: identity.
    np.testing.assert_array_equal(apply_motions(points, o, d), np.broadcast_to(points, (5, 50, 3)))
    # 2 pi rotations are the identity.
    m = motion_transforms(o, d, np.full(5, 2 * np.pi))
    np.testing.assert_allclose(m, np.tile(np.eye(4), (5, 1, 1)), atol=1e-14)
    # Prismatic: translation along the unit direction, whatever the length of d.
    out = apply_motions(points, o, d, translations=np.full(5, 0.25))
    u = d / np.linalg.norm(d, axis=1, keepdims=True)
    shift = np.broadcast_to(0.25 * u[:, None], out.shape)
    np.testing.assert_allclose(out - points, shift, atol=1e-15)


def test_empty_batches():
    assert motion_transforms(np.zeros((0, 3)), np.zeros((0, 3))).shape == (0, 4, 4)
    assert apply_motions(np.zeros((4, 3)), np.zeros((0, 3)), np.zeros((0, 3))).shape == (0, 4, 3)
    out = apply_motions(np.zeros((0, 3)), np.zeros((2, 3)), np.eye(3)[:2], np.ones(2))
    assert out.shape == (2, 0, 3)


def test_non_contiguous_inputs():
    rng = np.random.default_rng(3)
    points = rng.normal(size=(40, 6))[:, ::2]
    o, d, a, t = _random_candidates(rng, 3)
    ref = _core.apply_motions(np.ascontiguousarray(points), o, d, a, t)
    got = _core.apply_motions(points, np.asfortranarray(o), np.asfortranarray(d), a[::1], t)
    np.testing.assert_array_equal(got, ref)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        (
            {"directions": np.array([[1.0, 0, 0], [0, 0, 0]])},
            r"directions\[1\]: zero-length axis direction of candidate 1",
        ),
        ({"angles": np.zeros(3)}, r"angles: expected shape \(2,\)"),
        ({"translations": np.zeros(1)}, r"translations: expected shape \(2,\)"),
        ({"directions": np.ones((3, 3))}, r"directions: expected shape \(C, 3\) with C = 2"),
        ({"origins": np.ones((2, 2))}, r"origins: expected shape \(N, 3\)"),
        ({"points": np.ones((5, 4))}, r"points: expected shape \(N, 3\)"),
        ({"points": np.array([[0.0, np.nan, 0.0]])}, "points: non-finite value at index 1"),
        ({"origins": np.array([[0.0, 0, 0], [0, 0, np.inf]])}, "origins: non-finite .* index 5"),
        ({"directions": np.array([[1.0, 0, 0], [np.nan, 1, 0]])}, "directions: non-finite"),
        ({"angles": np.array([0.0, np.inf])}, "angles: non-finite value at index 1"),
        ({"translations": np.array([np.nan, 0.0])}, "translations: non-finite"),
    ],
)
def test_bad_inputs_are_valueerrors(kwargs, match):
    args = {
        "points": np.zeros((4, 3)),
        "origins": np.zeros((2, 3)),
        "directions": np.eye(3)[:2],
        "angles": np.ones(2),
        "translations": np.ones(2),
    }
    args.update(kwargs)
    with pytest.raises(ValueError, match=match):
        apply_motions(**args)
    if "points" not in kwargs:
        args.pop("points")
        with pytest.raises(ValueError, match=match):
            motion_transforms(**args)
