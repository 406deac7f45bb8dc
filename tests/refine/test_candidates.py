"""Candidate axes from OBBs and interaction regions (kinmo.refine.candidates)."""

from __future__ import annotations

import numpy as np
import pytest

from kinmo.geometry import fit_obb, interaction_region
from kinmo.refine.candidates import (
    MOVING_TYPES,
    candidate_axes,
    canonical_direction,
    frame_box,
    merge_candidates,
    motion_of,
)

from .refine_boxes import box_points


def _line_dist(origins, directions, point):
    return np.linalg.norm(np.cross(np.asarray(point) - origins, directions), axis=1)


def _rot_y(deg):
    a = np.radians(deg)
    return np.array([[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]])


def test_door_slab_has_its_hinge_edge_among_side_pivots():
    rng = np.random.default_rng(0)
    # A door 0.8 wide (x), 2 high (y), 0.04 thick (z), rotated 30 deg about y: the OBB is
    # fitted (Rust) to its surface points, as in a part graph.
    rot = _rot_y(30)
    pts = box_points((0, 0, 0), (0.8, 2.0, 0.04), 2000, rng) @ rot.T + [1.0, 0.5, -2.0]
    obb = fit_obb(pts)
    hinge_o = np.array([0.0, 0.0, 0.0]) @ rot.T + [1.0, 0.5, -2.0]  # left back vertical edge
    c = candidate_axes(obb, "R_V_S")
    assert len(c) == 4 and set(c.kinds) == {"edge"}
    np.testing.assert_allclose(np.abs(c.directions[:, 1]), 1.0, atol=1e-6)  # all vertical
    d = _line_dist(c.origins, c.directions, hinge_o)
    assert d.min() < 1e-3
    # the four edges are distinct lines (two 0.04 apart, the others 0.8 apart)
    assert np.sum(d < 1e-3) == 1
    # horizontal side pivots of the same slab: the 8 edges along x and z
    ch = candidate_axes(obb, "R_H_S")
    assert len(ch) == 8
    assert np.all(np.abs(ch.directions[:, 1]) < 1e-6)


def test_drawer_yields_its_sliding_direction():
    rng = np.random.default_rng(1)
    pts = box_points((0, 0, 0), (0.5, 0.2, 0.6), 2000, rng)  # deep along z
    obb = fit_obb(pts)
    c = candidate_axes(obb, "P_H")
    assert c.motion == "P" and set(c.kinds) == {"axis"}
    assert len(c) == 2  # the two horizontal OBB axes: x and z
    assert np.max(np.abs(c.directions @ [0.0, 0.0, 1.0])) > 1 - 1e-6
    np.testing.assert_allclose(c.origins, np.tile(obb.center, (2, 1)))
    cv = candidate_axes(obb, "P_V")
    assert len(cv) == 1 and abs(cv.directions[0, 1]) > 1 - 1e-6


def test_knob_centre_pivot_through_obb_centre_and_interaction_region():
    rng = np.random.default_rng(2)
    # A knob (0.1 x 0.1 x 0.05) sticking out of a front panel (z = 0 plane) along +z.
    knob = box_points((-0.05, -0.05, 0.0), (0.05, 0.05, 0.05), 800, rng) + [0.3, 0.6, 0.0]
    panel = box_points((-0.5, 0.0, -0.02), (0.5, 1.0, 0.0), 2000, rng)
    obb = fit_obb(knob)
    c = candidate_axes(obb, "R_H_C", knob, panel)
    assert set(c.kinds) <= {"center", "interaction"} and "center" in c.kinds
    # the knob's true axis: through (0.3, 0.6, *) along z
    true_o, true_d = np.array([0.3, 0.6, 0.025]), np.array([0.0, 0.0, 1.0])
    along = np.abs(c.directions @ true_d) > 1 - 1e-6
    assert along.any()
    centre = np.array([k == "center" for k in c.kinds])
    np.testing.assert_allclose(c.origins[centre], np.tile(obb.center, (centre.sum(), 1)))
    assert _line_dist(c.origins[along & centre], c.directions[along & centre], true_o).min() < 1e-3
    # all centre-pivot directions are horizontal
    assert np.all(np.abs(c.directions[:, 1]) < np.cos(np.pi / 4))


def test_interaction_centroid_of_touching_boxes_lies_on_contact_face():
    rng = np.random.default_rng(3)
    a = box_points((0, 0, 0), (1, 1, 1), 4000, rng)
    b = box_points((1, 0.25, 0.25), (1.5, 0.75, 0.75), 4000, rng)  # touches x = 1
    region = interaction_region(a, b, 0.05)
    assert not region.empty
    assert abs(region.centroid[0] - 1.0) < 0.02
    # inside the contact patch (the smaller box's face)
    assert 0.25 <= region.centroid[1] <= 0.75 and 0.25 <= region.centroid[2] <= 0.75
    assert np.all(a[region.mask_moving][:, 0] >= 0.95)


def test_coarse_types_cover_every_orientation_and_pivot():
    obb = (np.zeros(3), np.eye(3), np.array([0.5, 1.0, 0.1]))
    r = candidate_axes(obb, "R")
    assert r.kinds.count("edge") == 12 and r.kinds.count("center") == 3
    assert len(candidate_axes(obb, "P")) == 3
    assert len(candidate_axes(obb, "PR")) == 3
    # fine index input
    assert len(candidate_axes(obb, 5)) == 4  # FINE_TYPES[5] = R_V_S


def test_flat_box_edges_are_merged_and_tilted_box_falls_back_to_most_vertical_axis():
    flat = (np.zeros(3), np.eye(3), np.array([0.5, 1.0, 0.0]))  # zero thickness
    c = candidate_axes(flat, "R_V_S")
    assert len(c) == 2  # the 4 vertical edges collapse into 2 lines
    # a box tilted so that no axis is within 45 degrees of y: row k has |y| = s[k] < cos 45
    s3 = np.array([1.0, 1.2, 0.9]) / np.linalg.norm([1.0, 1.2, 0.9])
    w = np.array([0.0, 1.0, 0.0]) - s3
    w /= np.linalg.norm(w)
    axes = np.eye(3) - 2 * np.outer(w, w)  # Householder: column 1 is s3
    axes[2] *= -1  # right-handed
    assert np.all(np.abs(axes[:, 1]) < np.cos(np.pi / 4))
    c = candidate_axes((np.zeros(3), axes, np.array([0.3, 0.2, 0.1])), "P_V")
    assert len(c) == 1  # the most vertical one: row 1
    np.testing.assert_allclose(np.abs(c.directions[0]), np.abs(axes[1]), atol=1e-9)
    assert len(candidate_axes((np.zeros(3), axes, np.array([0.3, 0.2, 0.1])), "P_H")) == 3


def test_canonical_direction_and_errors():
    d = canonical_direction(np.array([[0.0, -2.0, 0.0], [0.0, 2.0, 0.0], [-1.0, 0.5, 0.0]]))
    np.testing.assert_allclose(d[0], [0, 1, 0])
    np.testing.assert_allclose(d[1], [0, 1, 0])
    assert d[2, 0] > 0
    assert motion_of("PR_V") == "PR" and "Fixed" not in MOVING_TYPES
    obb = (np.zeros(3), np.eye(3), np.ones(3))
    with pytest.raises(ValueError, match="motion_type"):
        candidate_axes(obb, "Fixed")
    with pytest.raises(ValueError, match="moving_obb"):
        candidate_axes((np.zeros(3), np.ones((3, 3)), np.ones(3)), "P_H")
    with pytest.raises(ValueError, match="moving_obb"):
        candidate_axes((np.zeros(2), np.eye(3), np.ones(3)), "P_H")
    with pytest.raises(ValueError, match="moving_points"):
        candidate_axes(obb, "R_V_C", np.zeros((0, 3)), np.zeros((5, 3)))


def _rot_z(deg):
    a = np.radians(deg)
    return np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])


def test_frame_box_bounds_the_points_in_the_given_axes():
    rng = np.random.default_rng(3)
    rot = _rot_y(25)
    pts = box_points((0, 0, 0), (0.6, 0.2, 0.4), 800, rng) @ rot.T + [0.3, 1.0, -0.5]
    # in its own (rotated) frame: the exact box
    c, ax, h = frame_box(pts, rot.T)
    np.testing.assert_allclose(h, [0.3, 0.1, 0.2], atol=1e-9)
    np.testing.assert_allclose(c, np.array([0.3, 0.1, 0.2]) @ rot.T + [0.3, 1.0, -0.5], atol=1e-9)
    np.testing.assert_allclose(ax, rot.T)
    # in the shape frame: the axis-aligned bounding box
    c, ax, h = frame_box(pts, np.eye(3))
    np.testing.assert_allclose(c, 0.5 * (pts.min(0) + pts.max(0)))
    np.testing.assert_allclose(h, 0.5 * (pts.max(0) - pts.min(0)))
    with pytest.raises(ValueError, match="orthonormal"):
        frame_box(pts, 2 * np.eye(3))
    with pytest.raises(ValueError):
        frame_box(np.zeros((0, 3)), np.eye(3))


def test_reference_frame_box_recovers_a_hinge_the_tilted_obb_misses():
    # A lid 0.6 wide, yawed 35 deg about y (an irregular mesh whose OBB is not aligned with
    # its hinge), hinged to its base along x at its lowest, backmost edge: no axis of its own
    # OBB is within 30 deg of x; its box in the base's (here the shape's) frame has that edge.
    rng = np.random.default_rng(4)
    pts = box_points((0, 0, 0), (0.6, 0.05, 0.4), 1500, rng) @ _rot_y(35).T
    own = candidate_axes(fit_obb(pts), "R_H_S")
    assert np.max(np.abs(own.directions @ [1.0, 0.0, 0.0])) < np.cos(np.radians(30))
    ref = candidate_axes(frame_box(pts, np.eye(3)), "R_H_S")
    hinge = [0.0, pts[:, 1].min(), pts[:, 2].min()]
    d = _line_dist(ref.origins, ref.directions, hinge)
    k = int(np.argmin(d))
    assert d[k] < 1e-9 and abs(ref.directions[k] @ [1.0, 0.0, 0.0]) == pytest.approx(1.0)
    # merged after the OBB's own candidates: all of those first, then the new lines
    m = merge_candidates(own, ref, angle_deg=2.0, distance=0.01)
    assert len(m) == len(own) + len(ref)
    np.testing.assert_array_equal(m.origins[: len(own)], own.origins)


def test_merge_candidates_drops_covered_lines_only():
    box = (np.zeros(3), np.eye(3), np.array([0.5, 1.0, 0.025]))
    a = candidate_axes(box, "R_V_S")
    assert len(merge_candidates(a, a, angle_deg=0.0, distance=0.0)) == len(a)  # all covered
    # the same box shifted by 0.05 along x: covered at distance 0.06, not at 0.04
    b = candidate_axes((np.array([0.05, 0, 0]), np.eye(3), box[2]), "R_V_S")
    assert len(merge_candidates(a, b, angle_deg=1.0, distance=0.06)) == len(a)
    assert len(merge_candidates(a, b, angle_deg=1.0, distance=0.04)) == 2 * len(a)
    # rotated by 5 deg: parallel within 6 deg, not within 4 deg
    r = (np.zeros(3), _rot_z(5).T, box[2])
    c = candidate_axes(r, "R_V_S")
    assert len(merge_candidates(a, c, angle_deg=6.0, distance=0.01)) == len(a)
    assert len(merge_candidates(a, c, angle_deg=4.0, distance=0.01)) == 2 * len(a)
    # lines of ``extra`` also merge among themselves (its edges 0.05 apart, distance 0.1)
    assert len(merge_candidates(a, c, angle_deg=4.0, distance=0.1)) == len(a) + 2
    # prismatic axes have no position: a parallel axis elsewhere is covered
    p1 = candidate_axes(box, "P_H")
    p2 = candidate_axes((np.array([3.0, 2.0, 1.0]), np.eye(3), box[2]), "P_H")
    assert len(merge_candidates(p1, p2, angle_deg=1.0, distance=0.0)) == len(p1)
    with pytest.raises(ValueError, match="R_V_S vs P_H"):
        merge_candidates(a, p1, angle_deg=1.0, distance=0.0)
