"""Interaction regions (:mod:`kinmo.geometry.interaction`) against scipy's k-d tree."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.spatial import cKDTree

from kinmo.geometry import InteractionRegion, contact_pairs, interaction_region, sample_surface

from .test_contact import REL_TOL, leaf_meshes


def box_surface(rng: np.random.Generator, lo, size, n: int) -> np.ndarray:
    """``n`` points uniformly on the faces of the box ``[lo, lo + size]`` (by face count)."""
    lo, size = np.asarray(lo, float), np.asarray(size, float)
    u = rng.uniform(0, 1, (n, 3))
    face = rng.integers(0, 6, n)
    u[np.arange(n), face // 2] = face % 2
    return lo + u * size


def reference_masks(a: np.ndarray, b: np.ndarray, r: float) -> tuple[np.ndarray, np.ndarray]:
    """Points of each set within ``r`` of the other (scipy)."""
    da, _ = cKDTree(b).query(a)
    db, _ = cKDTree(a).query(b)
    return da <= r, db <= r


def check_region(reg: InteractionRegion, a: np.ndarray, b: np.ndarray, r: float) -> None:
    ma, mb = reference_masks(a, b, r)
    assert reg.mask_moving.dtype == bool and reg.mask_moving.shape == (len(a),)
    assert reg.mask_reference.dtype == bool and reg.mask_reference.shape == (len(b),)
    assert reg.centroid.dtype == np.float64 and reg.centroid.shape == (3,)
    assert isinstance(reg.empty, bool)
    # Distances exactly at r are not expected with random points: masks must agree.
    np.testing.assert_array_equal(reg.mask_moving, ma)
    np.testing.assert_array_equal(reg.mask_reference, mb)
    assert reg.empty == (not ma.any())
    if not reg.empty:
        want = np.concatenate([a[ma], b[mb]]).mean(0)
        np.testing.assert_allclose(reg.centroid, want, atol=1e-12)


def test_touching_boxes_centroid_on_contact_face() -> None:
    rng = np.random.default_rng(0)
    # A small box resting on a large one: contact face y = 1, centred at x = z = 1.
    reference = box_surface(rng, [0, 0, 0], [2, 1, 2], 20000)
    moving = box_surface(rng, [0.5, 1, 0.5], [1, 0.5, 1], 20000)
    r = 0.05
    reg = interaction_region(moving, reference, r)
    check_region(reg, moving, reference, r)
    assert not reg.empty
    assert abs(reg.centroid[1] - 1.0) < 0.01
    np.testing.assert_allclose(reg.centroid[[0, 2]], [1.0, 1.0], atol=0.02)
    # Only points near the contact plane are selected.
    assert np.all(moving[reg.mask_moving, 1] <= 1 + r)
    assert np.all(reference[reg.mask_reference, 1] >= 1 - r)


def test_empty_region_is_midpoint_of_closest_pair() -> None:
    rng = np.random.default_rng(1)
    a = rng.uniform(0, 1, (700, 3))
    b = rng.uniform(0, 1, (500, 3)) + [2.5, 0.3, 0]
    reg = interaction_region(a, b, 0.5)
    check_region(reg, a, b, 0.5)
    assert reg.empty
    d, j = cKDTree(b).query(a)
    i = int(np.argmin(d))
    np.testing.assert_allclose(reg.centroid, 0.5 * (a[i] + b[j[i]]), atol=1e-15)


@pytest.mark.parametrize("radius", [0.02, 0.1, 0.3, 10.0])
def test_masks_match_scipy_on_random_clouds(radius: float) -> None:
    rng = np.random.default_rng(2)
    a = rng.normal(size=(3000, 3))
    b = rng.normal(size=(2000, 3)) * [1, 0.5, 2] + [1.5, 0, 0]
    check_region(interaction_region(a, b, radius), a, b, radius)


@pytest.mark.exactdata
def test_real_parts_in_contact(mobility_root: Path) -> None:
    """Surface samples of the contacting leaves of a real object (keyboard 7619)."""
    meshes = leaf_meshes(mobility_root / "7619")
    allv = np.concatenate([v for v, _ in meshes])
    diag = float(np.linalg.norm(allv.max(0) - allv.min(0)))
    pairs, _ = contact_pairs(meshes, REL_TOL * diag)
    assert len(pairs) >= 100
    n_empty = 0
    for k, (i, j) in enumerate(pairs[:: max(1, len(pairs) // 10)]):
        a, _ = sample_surface(*meshes[i], 2048, seed=2 * k)
        b, _ = sample_surface(*meshes[j], 2048, seed=2 * k + 1)
        r = 0.02 * diag
        reg = interaction_region(a, b, r)
        check_region(reg, a, b, r)
        n_empty += reg.empty
    # Parts within 0.01 diag have samples within 0.02 diag of each other.
    assert n_empty == 0


def test_duplicates_and_single_points() -> None:
    a = np.zeros((50, 3))
    b = np.array([[1.0, 0, 0]])
    reg = interaction_region(a, b, 0.5)
    assert reg.empty and not reg.mask_moving.any() and not reg.mask_reference.any()
    np.testing.assert_array_equal(reg.centroid, [0.5, 0, 0])
    reg = interaction_region(a, b, 1.0)  # the boundary is inclusive
    assert not reg.empty and reg.mask_moving.all() and reg.mask_reference.all()
    np.testing.assert_allclose(reg.centroid, [1 / 51, 0, 0], atol=1e-15)


def test_input_conversions() -> None:
    a = np.asfortranarray(np.arange(12, dtype=np.float32).reshape(4, 3))
    reg = interaction_region(a, a[::2].tolist(), 0.1)
    assert reg.mask_moving.tolist() == [True, False, True, False]
    assert reg.mask_reference.tolist() == [True, True]


@pytest.mark.parametrize(
    ("moving", "reference", "radius", "match"),
    [
        (np.zeros((3, 3)), np.zeros((3, 3)), 0.0, "radius"),
        (np.zeros((3, 3)), np.zeros((3, 3)), -1.0, "radius"),
        (np.zeros((3, 3)), np.zeros((3, 3)), float("nan"), "radius"),
        (np.zeros((3, 3)), np.zeros((3, 3)), float("inf"), "radius"),
        (np.zeros((3, 2)), np.zeros((3, 3)), 1.0, "moving: expected shape"),
        (np.zeros((3, 3)), np.zeros((3, 4)), 1.0, "reference: expected shape"),
        (np.array([[0, 0, np.nan]]), np.zeros((3, 3)), 1.0, "moving: non-finite value at index 2"),
        (np.zeros((3, 3)), np.array([[0, np.inf, 0]]), 1.0, "reference: non-finite"),
        (np.zeros((0, 3)), np.zeros((3, 3)), 1.0, "moving: no points"),
        (np.zeros((3, 3)), np.zeros((0, 3)), 1.0, "reference: no points"),
    ],
)
def test_bad_inputs(moving, reference, radius, match) -> None:
    with pytest.raises(ValueError, match=match):
        interaction_region(moving, reference, radius)
