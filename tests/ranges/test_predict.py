"""Predicted ranges: the learned prior clipped by a sweep (kinmo.ranges.predict, issue 35)."""

from __future__ import annotations

import dataclasses
import logging
import math

import numpy as np
import pytest
import trimesh
from motion_cabinet import cabinet_graph, oracle_prediction

from kinmo.mobility_tree import ShapePrediction, build_mobility_tree
import kinmo.refine.selector as selector
from kinmo.ranges import RangeEntry, RangePrior, predict_ranges
from kinmo.refine.selector import ShapeMeshes


def _prediction(seed: int = 0) -> ShapePrediction:
    g = cabinet_graph(n_points=256, seed=seed)
    e = oracle_prediction(g)
    return ShapePrediction(g, e, build_mobility_tree(g, e), ())


def _meshes(g) -> ShapeMeshes:
    """Each leaf as the box its surface points span (the cabinet's geometry)."""
    out = {}
    for k in np.flatnonzero(g.is_leaf):
        p = np.asarray(g.points[k], float)
        lo, hi = p.min(0), p.max(0)
        m = trimesh.creation.box(extents=hi - lo, transform=trimesh.transformations.translation_matrix((lo + hi) / 2))
        out[int(k)] = (np.asarray(m.vertices, float), np.asarray(m.faces, np.int64))
    return ShapeMeshes(out)


def _prior(*entries) -> RangePrior:
    return RangePrior([RangeEntry(*e) for e in entries])


def _limits(pred):
    return {lk.name: lk.joint.limit for lk in pred.tree.moving_links}


def test_the_sweep_closes_the_blocked_side_and_keeps_the_learned_open_end():
    p = _prediction()
    # a learned lower end above -OPEN_AT_REST_MIN_DEG: a range annotated about a closed rest
    # (one below it is shifted when the part is closed at rest, the test of that rule below)
    prior = _prior(("hinge", None, None, 5, 0.0, -20.0, 120.0), ("slider", None, None, 5, 0.0, -0.5, 1.0))
    out = predict_ranges(p, prior, _meshes(p.graph))
    door, drawer = _limits(out)["door"], _limits(out)["drawer"]
    # the door cannot turn into the body (the tree's axis opens it outwards): closed at ~0
    assert -10.0 <= door[0] <= 0.0 and door[1] == pytest.approx(120.0)
    # the drawer cannot be pushed into the body (beyond the contact skin, 0.5 % of the
    # diagonal); it pulls out one depth (its extent along the axis, 0.06)
    ext = np.ptp(p.graph.points[[4, 5]].reshape(-1, 3)[:, 2])
    assert -0.01 * p.graph.scale <= drawer[0] <= 0.0 and drawer[1] == pytest.approx(ext, rel=0.05)
    # the other parts of the prediction are untouched
    assert out.tree.leaf_link.tolist() == p.tree.leaf_link.tolist()
    assert [lk.joint.direction.tolist() for lk in out.tree.moving_links] == \
           [lk.joint.direction.tolist() for lk in p.tree.moving_links]


def test_the_sweep_bounds_a_learned_range_that_would_pass_through_the_body():
    p = _prediction()
    out = predict_ranges(p, _prior(("hinge", None, None, 5, 0.0, 0.0, 300.0)), _meshes(p.graph))
    lo, hi = _limits(out)["door"]
    # hinged at the body's front-left edge, the door swings out, past the half turn (flat
    # beside the body), until it meets the body's left side at about three quarters of a turn
    assert lo == 0.0 and 240.0 <= hi <= 275.0


def test_continuous_groups_stay_continuous_and_unknown_joints_keep_the_default():
    p = _prediction()
    out = predict_ranges(p, _prior(("hinge", None, "door", 5, 0.8, 0.0, 90.0)), _meshes(p.graph))
    lim = _limits(out)
    assert lim["door"] is None
    assert lim["drawer"] == _limits(p)["drawer"]  # no slider group: the tree's default


def test_an_unnamed_hinge_is_continuous_as_its_predicted_fine_type_s_group_says():
    from kinmo.ranges.predict import _predicted_fine

    from kinmo.data.model import FINE_TYPES

    p = _prediction()
    door = next(lk for lk in p.tree.moving_links if lk.name == "door")
    assert _predicted_fine(p, door.id) is None  # no type names: no fine type
    p = dataclasses.replace(p, type_names=FINE_TYPES)
    fine = _predicted_fine(p, door.id)
    assert fine is not None and fine.startswith("R_")
    kind = ("hinge", None, None, 5, 0.0, 0.0, 120.0)
    free = _prior(kind, ("hinge", None, None, 5, 1.0, None, None, fine))
    unnamed = dataclasses.replace(p, graph=dataclasses.replace(p.graph, category=""), tree=dataclasses.replace(
        p.tree, links=[dataclasses.replace(lk, name=f"part_{lk.id}") for lk in p.tree.links]))
    assert _limits(predict_ranges(unnamed, free, _meshes(p.graph)))[f"part_{door.id}"] is None
    assert _limits(predict_ranges(unnamed, _prior(kind), _meshes(p.graph)))[f"part_{door.id}"] is not None
    # a named part keeps its name's group, whatever its fine type
    named = _prior(kind, ("hinge", None, "door", 5, 0.0, 0.0, 120.0), ("hinge", None, None, 5, 1.0, None, None, fine))
    assert _limits(predict_ranges(p, named, _meshes(p.graph)))["door"] is not None


def test_without_meshes_the_learned_range_is_kept_with_one_warning(caplog):
    p = _prediction()
    with caplog.at_level(logging.WARNING):
        out = predict_ranges(p, _prior(("hinge", None, None, 5, 0.0, -90.0, 120.0),
                                       ("slider", None, None, 5, 0.0, -0.5, 1.0)), None)
    assert _limits(out)["door"] == (-90.0, 120.0)
    lines = [r.getMessage() for r in caplog.records]
    assert len(lines) == 1 and "cabinet0" in lines[0] and "no meshes" in lines[0]


def test_blocked_everywhere_keeps_the_learned_range_with_a_warning_naming_the_part(caplog):
    p = _prediction()
    # a learned range entirely on the closing side of the door: blocked at every state
    with caplog.at_level(logging.WARNING):
        out = predict_ranges(p, _prior(("hinge", None, "door", 5, 0.0, -120.0, -30.0)), _meshes(p.graph))
    assert _limits(out)["door"] == (-120.0, 0.0)  # kept, widened to hold the rest state
    assert any("'door'" in r.getMessage() and "cabinet0" in r.getMessage() for r in caplog.records)


def _walled(g, reach_deg: float) -> ShapeMeshes:
    """The cabinet's meshes with a wall in front of the door (part of the body), where the
    door's free edge (0.5 from its hinge line) meets it after ``reach_deg`` degrees."""
    meshes = _meshes(g)
    z0 = 0.31 + 0.5 * math.sin(math.radians(reach_deg))
    wall = trimesh.creation.box(extents=(0.5, 0.5, 0.1),
                                transform=trimesh.transformations.translation_matrix((-0.25, 0.75, z0 + 0.05)))
    body = trimesh.util.concatenate([trimesh.Trimesh(*meshes.leaves[1], process=False), wall])
    return ShapeMeshes({**meshes.leaves, 1: (np.asarray(body.vertices, float), np.asarray(body.faces, np.int64))})


def test_a_part_the_sweep_frees_for_a_small_share_of_its_learned_range_keeps_that_range(caplog, monkeypatch):
    # the door meets the wall after ~13 of its learned 120 degrees (11 %, over the former 5 %
    # bar), and cannot close: a part annotated as moving that turns this little is held by
    # its meshes (a stapler's arm clipped into its base), not by a real stop (HINGE_BLOCKED_SHARE);
    # test_a_wall_across_the_door_bounds_its_opening_end is the real stop, at ~24 degrees
    import kinmo.ranges.predict as rp

    p = _prediction()
    prior = _prior(("hinge", None, "door", 5, 0.0, 0.0, 120.0))
    with caplog.at_level(logging.WARNING):
        out = predict_ranges(p, prior, _walled(p.graph, 14.0))
    assert _limits(out)["door"] == (0.0, 120.0)
    assert any("'door'" in r.getMessage() and "cabinet0" in r.getMessage() for r in caplog.records)
    # the sweep alone stops it at the wall: the share is what keeps the range
    monkeypatch.setattr(rp, "HINGE_BLOCKED_SHARE", 0.05)
    assert 5.0 <= _limits(predict_ranges(p, prior, _walled(p.graph, 14.0)))["door"][1] <= 20.0


@pytest.mark.parametrize("lo, hi", [(0.0, 0.0), (5.0, 5.0)])
def test_a_range_is_never_empty_or_nan(lo, hi):
    p = _prediction()
    out = predict_ranges(p, _prior(("hinge", None, None, 5, 0.0, lo, hi), ("slider", None, None, 5, 0.0, lo, hi)),
                         _meshes(p.graph))
    for a, b in _limits(out).values():
        assert math.isfinite(a) and math.isfinite(b) and b > a


@pytest.mark.parametrize("meshes", [True, False])
def test_every_range_holds_the_rest_state(meshes):
    # a prior written before the rule (the bundle's dishwasher shelves: 0.08 to 0.9 extents)
    p = _prediction()
    prior = _prior(("hinge", None, None, 5, 0.0, 30.0, 120.0), ("slider", None, None, 5, 0.0, 0.08, 0.9))
    out = predict_ranges(p, prior, _meshes(p.graph) if meshes else None)
    for name, (lo, hi) in _limits(out).items():
        assert lo <= 0.0 <= hi and hi > 0.0, name
    if not meshes:  # the learned ends, widened to 0
        assert _limits(out)["door"] == (0.0, 120.0)


def test_deterministic():
    p = _prediction()
    prior = _prior(("hinge", None, None, 5, 0.0, -90.0, 150.0), ("slider", None, None, 5, 0.0, -0.5, 1.5))
    assert _limits(predict_ranges(p, prior, _meshes(p.graph))) == _limits(predict_ranges(p, prior, _meshes(p.graph)))


def test_table1_scores_the_predicted_ranges_against_the_true_ones():
    """Table 1's range columns (kinmo.evaluate.shape_metrics): the swept prediction of the
    cabinet's door matches its true opening range; the tree's constant default does not."""
    from kinmo.evaluate.shape_metrics import evaluate_graphs

    g = cabinet_graph(n_points=256, seed=0)
    links = [dict(lk) for lk in g.meta["links"]]
    links[1]["limit"] = [-180.0, 0.0]  # about +y: the door swings out half a turn
    g.meta = {**g.meta, "links": links}
    e = oracle_prediction(g)
    p = ShapePrediction(g, e, build_mobility_tree(g, e), ())
    ranged = predict_ranges(p, _prior(("hinge", None, None, 5, 0.0, 0.0, 180.0),
                                      ("slider", None, None, 5, 0.0, 0.0, 0.4 / 0.06)), _meshes(g))
    rep = evaluate_graphs([g], {"default": [p], "ranged": [ranged]})
    d, r = rep.table[("default", "all")], rep.table[("ranged", "all")]
    assert d["range_iou_hinge"] == pytest.approx(0.5)  # 0-90 of 0-180
    assert r["range_iou_hinge"] == pytest.approx(1.0) and r["range_end_hinge"] == pytest.approx(0.0)
    assert r["range_iou_slider"] > 0.9 > d["range_iou_slider"]
    assert r["range_cont_acc"] == 1.0


def _with_obstacle(meshes: ShapeMeshes, lo, hi) -> ShapeMeshes:
    """The body (leaf 1) with an extra box ``lo``..``hi`` fixed to it."""
    v, f = meshes.leaves[1]
    b = trimesh.creation.box(extents=np.subtract(hi, lo),
                             transform=trimesh.transformations.translation_matrix(np.add(lo, hi) / 2))
    leaves = dict(meshes.leaves)
    leaves[1] = (np.vstack([v, b.vertices]), np.vstack([f, np.asarray(b.faces, np.int64) + len(v)]))
    return ShapeMeshes(leaves)


def test_a_wall_across_the_door_bounds_its_opening_end():
    """A slab 0.2 in front of the door, over its whole height: the door meets it at about
    asin(0.2 / 0.5) = 24 degrees, with most of its points, so the sweep bounds the end."""
    p = _prediction()
    m = _with_obstacle(_meshes(p.graph), (-0.6, 0.4, 0.5), (0.2, 1.1, 0.52))
    lo, hi = _limits(predict_ranges(p, _prior(("hinge", None, None, 5, 0.0, 0.0, 120.0)), m))["door"]
    assert lo == 0.0 and 15.0 <= hi <= 30.0


def test_a_graze_keeps_the_learned_opening_end():
    """The same slab over the top tenth of the door only: a few of its points graze it (an
    axis slightly off, a handle on a frame), so the learned end is kept (GRAZE_SHARE)."""
    from kinmo.ranges.predict import GRAZE_SHARE, OPEN_SIDE_TRUST

    p = _prediction()
    m = _with_obstacle(_meshes(p.graph), (-0.6, 0.9, 0.5), (0.2, 1.1, 0.52))
    prior = _prior(("hinge", None, None, 5, 0.0, 0.0, 120.0))
    assert _limits(predict_ranges(p, prior, m))["door"] == (0.0, 120.0)
    # the sweep alone stops the door at the slab: the graze rule is what keeps the end
    import kinmo.ranges.predict as rp

    old = rp.GRAZE_SHARE
    try:
        rp.GRAZE_SHARE = 0.0
        assert _limits(predict_ranges(p, prior, m))["door"][1] < OPEN_SIDE_TRUST * 120.0
    finally:
        rp.GRAZE_SHARE = old
    assert 0.0 < GRAZE_SHARE < 0.5


def test_a_slider_blocked_on_its_opening_side_and_free_the_other_way_is_turned_round():
    """A drawer whose predicted direction points into the body: pushed that way it is blocked
    at once, pulled the other way it is free, so its direction is negated and it pulls out."""
    p = _prediction()
    links = []
    for lk in p.tree.links:
        if lk.name == "drawer":
            lk = dataclasses.replace(lk, joint=dataclasses.replace(lk.joint, direction=-lk.joint.direction))
        links.append(lk)
    p = dataclasses.replace(p, tree=dataclasses.replace(p.tree, links=links))
    out = predict_ranges(p, _prior(("slider", None, None, 5, 0.0, 0.0, 1.0)), _meshes(p.graph))
    drawer = next(lk.joint for lk in out.tree.moving_links if lk.name == "drawer")
    assert np.allclose(drawer.direction, [0.0, 0.0, 1.0])
    ext = np.ptp(p.graph.points[[4, 5]].reshape(-1, 3)[:, 2])
    assert drawer.limit[0] <= 0.0 and drawer.limit[1] == pytest.approx(ext, rel=0.05)


def test_a_slider_learned_to_open_along_minus_its_axis_and_blocked_there_is_turned_round():
    """The mirror case: a prior that opens along -direction (the kind-level medoid of many
    buttons, which press inwards, ``[-1, 0]`` extents) on a drawer whose axis points out of
    the body. Pressed in it is blocked at once, pulled out it is free over the whole learned
    end: its direction is negated, and its learned lower end pulls it out. The one-sided rule
    left it at the contact skin, a drawer that does not open (foreign cabinets, issue 35)."""
    p = _prediction()
    before = next(lk.joint for lk in p.tree.moving_links if lk.name == "drawer")
    assert np.allclose(before.direction, [0.0, 0.0, 1.0])
    out = predict_ranges(p, _prior(("slider", None, None, 5, 0.0, -1.0, 0.0)), _meshes(p.graph))
    drawer = next(lk.joint for lk in out.tree.moving_links if lk.name == "drawer")
    assert np.allclose(drawer.direction, [0.0, 0.0, -1.0])
    ext = np.ptp(p.graph.points[[4, 5]].reshape(-1, 3)[:, 2])
    # along -direction = +z: out of the body by one depth; the other way, into it, barely
    assert drawer.limit[0] == pytest.approx(-ext, rel=0.05) and 0.0 <= drawer.limit[1] <= 0.01 * p.graph.scale


def test_opens_other_way_is_symmetric_in_the_sign_of_the_learned_range():
    from kinmo.ranges.predict import SLIDER_FLIP_SHARE, _opens_other_way

    for lo, hi, e_pos, e_neg in ((0.0, 1.0, 0.1, 2.0), (0.0, 1.0, 0.5, 2.0), (0.0, 1.0, 0.1, 0.9),
                                 (-0.2, 1.0, 0.1, 2.0), (0.0, 0.0, 0.0, 2.0)):
        assert _opens_other_way(lo, hi, e_pos, e_neg) == _opens_other_way(-hi, -lo, e_neg, e_pos)
    assert _opens_other_way(-1.0, 0.0, 2.0, 0.5 * SLIDER_FLIP_SHARE)
    assert not _opens_other_way(-1.0, 0.0, 2.0, 2.0 * SLIDER_FLIP_SHARE)  # not blocked early enough
    assert not _opens_other_way(-1.0, 0.0, 0.9, 0.0)  # not free over the whole learned end
    assert not _opens_other_way(-1.0, 1.0, 2.0, 0.0)  # no opening side


def test_hinge_hardware_at_the_axis_does_not_stop_the_sweep(monkeypatch):
    """A lug fixed to the body just in front of the door's hinge line, as PartNet models the
    pins and hooks of hinges: the door's points next to the axis meet it in the first
    degrees. Those points are left out of a hinge's sweep (HINGE_AXIS_SKIP), so the door
    keeps its learned end; with them (and the graze rule off) the lug stops it."""
    import kinmo.ranges.predict as rp

    p = _prediction()
    m = _with_obstacle(_meshes(p.graph), (-0.5, 0.5, 0.34), (-0.44, 1.0, 0.37))
    prior = _prior(("hinge", None, None, 5, 0.0, 0.0, 120.0))
    monkeypatch.setattr(rp, "GRAZE_SHARE", 0.0)
    assert _limits(predict_ranges(p, prior, m))["door"] == (0.0, 120.0)
    monkeypatch.setattr(rp, "HINGE_AXIS_SKIP", 0.0)
    lo, hi = _limits(predict_ranges(p, prior, m))["door"]
    assert lo == 0.0 and 5.0 <= hi <= 35.0


def test_off_axis_points_leave_out_the_points_near_the_line():
    from kinmo.ranges.predict import off_axis_points

    pts = np.column_stack([np.linspace(0.0, 1.0, 21), np.zeros(21), np.zeros(21)])
    o, d = np.zeros(3), np.array([0.0, 2.0, 0.0])  # the y axis, not unit
    kept = off_axis_points(pts, o, d, skip=0.38)
    np.testing.assert_allclose(kept[:, 0], np.linspace(0.4, 1.0, 13))
    # too few left, or no direction: every point
    assert len(off_axis_points(pts, o, d, skip=0.9)) == 21
    assert len(off_axis_points(pts, o, np.zeros(3), skip=0.3)) == 21


def _door_joint(p):
    return next(lk.joint for lk in p.tree.moving_links if lk.name == "door")


def _open_door(p, degrees: float):
    """The cabinet with its door turned ``degrees`` open about its predicted axis (points and
    mesh): a mesh that shows the door half open, as PartNet-Mobility's safes do."""
    j = _door_joint(p)
    rot = trimesh.transformations.rotation_matrix(math.radians(degrees), j.direction, j.origin)
    g = p.graph
    g.points[2] = trimesh.transform_points(np.asarray(g.points[2], float), rot)
    meshes = _meshes(g)
    box = trimesh.creation.box(extents=[0.5, 0.5, 0.02], transform=trimesh.transformations.translation_matrix(
        [-0.25, 0.75, 0.31]))
    box.apply_transform(rot)
    leaves = dict(meshes.leaves)
    leaves[2] = (np.asarray(box.vertices, float), np.asarray(box.faces, np.int64))
    return ShapeMeshes(leaves)


def test_a_door_open_at_rest_gets_its_closed_end_from_the_sweep():
    """The door shown 60 degrees open: turned back it meets the body at about -60, which
    becomes the closed end, and the learned 0-120 is shifted with it."""
    from kinmo.ranges.predict import protrusion

    p = _prediction()
    m = _open_door(p, 60.0)
    body = p.graph.points[[1, 4, 5]]
    assert protrusion(p.graph.points[2], body) > 0.3  # it sticks out of the body: open
    lo, hi = _limits(predict_ranges(p, _prior(("hinge", None, None, 5, 0.0, 0.0, 120.0)), m))["door"]
    assert -65.0 <= lo <= -50.0 and hi == pytest.approx(120.0 + lo)


def _hollow_body(p) -> ShapeMeshes:
    """The cabinet with its body a hollow box open at the front (the door closes it)."""
    slabs = [((-0.5, 0.0, -0.3), (0.5, 0.02, 0.3)), ((-0.5, 1.01, -0.3), (0.5, 1.03, 0.3)),
             ((-0.5, 0.0, -0.3), (-0.48, 1.0, 0.3)), ((0.48, 0.0, -0.3), (0.5, 1.0, 0.3)),
             ((-0.5, 0.0, -0.3), (0.5, 1.0, -0.28))]
    parts = [trimesh.creation.box(extents=np.subtract(hi, lo),
                                  transform=trimesh.transformations.translation_matrix(np.add(lo, hi) / 2))
             for lo, hi in slabs]
    hollow = trimesh.util.concatenate(parts)
    leaves = dict(_meshes(p.graph).leaves)
    leaves[1] = (np.asarray(hollow.vertices, float), np.asarray(hollow.faces, np.int64))
    return ShapeMeshes(leaves)


def test_a_closed_door_that_could_swing_into_a_hollow_body_stays_closed(monkeypatch):
    """A hollow body (open at the front): the closed door turns inwards freely until it meets
    a side wall, but it does not stick out of the body, so it is not taken as open."""
    import kinmo.ranges.predict as rp

    p = _prediction()
    m = _hollow_body(p)
    prior = _prior(("hinge", None, None, 5, 0.0, 0.0, 120.0))
    assert _limits(predict_ranges(p, prior, m))["door"] == (0.0, 120.0)
    # the sweep alone would call it open: the protrusion test is what keeps it closed
    monkeypatch.setattr(rp, "OPEN_AT_REST_PROTRUSION", 0.0)
    assert _limits(predict_ranges(p, prior, m))["door"][0] <= -rp.OPEN_AT_REST_MIN_DEG


def test_a_closed_door_with_a_range_learned_open_at_rest_opens_its_whole_span_from_closed(monkeypatch):
    """The fridge door case: its group's medoid, -110 to 60, was annotated on a door shown
    open. This door is closed (it does not stick out of the body) and turned inwards it meets
    the hollow body's side wall before -110, so it is closed at rest: the learned 170 degrees
    open from 0 instead of reaching 110 degrees into the body."""
    import kinmo.ranges.predict as rp

    p = _prediction()
    m = _hollow_body(p)
    prior = _prior(("hinge", None, None, 5, 0.0, -110.0, 60.0))
    lo, hi = _limits(predict_ranges(p, prior, m))["door"]
    assert lo == 0.0 and hi == pytest.approx(170.0)
    # without the rule the sweep alone bounds the closing side somewhere inside the body
    monkeypatch.setattr(rp, "CLOSED_AT_REST_PROTRUSION", -1.0)
    lo, hi = _limits(predict_ranges(p, prior, m))["door"]
    assert -110.0 < lo < -rp.OPEN_AT_REST_MIN_DEG and hi == pytest.approx(60.0)


def test_a_door_stopped_at_once_the_closing_way_is_closed_though_it_sticks_out(monkeypatch):
    """The solid body stops the closed door within CLOSED_AT_REST_FREE_DEG the closing way.
    Such a door is closed at rest even when it sticks out of the body more than
    CLOSED_AT_REST_PROTRUSION (a fridge door with its handle: 0.18 of its width), as long as
    it sticks out at most CLOSED_AT_REST_STOPPED_PROTRUSION (an open laptop lid, stopped by
    meshes interlocked at its hinge, sticks out by its whole height)."""
    import kinmo.ranges.predict as rp

    p = _prediction()
    m = _meshes(p.graph)
    prior = _prior(("hinge", None, None, 5, 0.0, -110.0, 60.0))
    monkeypatch.setattr(rp, "CLOSED_AT_REST_PROTRUSION", -1.0)  # "sticks out" by that test
    lo, hi = _limits(predict_ranges(p, prior, m))["door"]
    assert lo == 0.0 and hi == pytest.approx(170.0)
    # stopped later than the bound, or sticking out more: the sweep alone bounds the range
    free_deg = rp.CLOSED_AT_REST_FREE_DEG
    for name in ("CLOSED_AT_REST_FREE_DEG", "CLOSED_AT_REST_STOPPED_PROTRUSION"):
        with monkeypatch.context() as mp:
            mp.setattr(rp, name, -1.0)
            lo, hi = _limits(predict_ranges(p, prior, m))["door"]
            assert -free_deg <= lo <= 0.0 and hi == pytest.approx(60.0)


def test_a_part_free_both_ways_keeps_a_range_learned_about_a_mid_range_rest(monkeypatch):
    """A faucet handle annotated -90 to 90 about its rest and free both ways over it is not
    closed at rest, however little it sticks out: the rule needs a stop on the closing side
    before the learned lower end."""
    import kinmo.ranges.predict as rp

    p = _prediction()
    leaves = _meshes(p.graph).leaves
    m = ShapeMeshes({k: v for k, v in leaves.items() if k != 1})  # no body: nothing stops the door
    monkeypatch.setattr(rp, "CLOSED_AT_REST_PROTRUSION", 1e9)  # the protrusion test always passes
    prior = _prior(("hinge", None, None, 5, 0.0, -90.0, 90.0))
    assert _limits(predict_ranges(p, prior, m))["door"] == (-90.0, 90.0)


def test_protrusion_is_the_farthest_distance_outside_the_box():
    from kinmo.ranges.predict import protrusion

    box = np.array([[0.0, 0.0, 0.0], [1.0, 1.0, 1.0]])
    assert protrusion(np.array([[0.5, 0.5, 0.5], [0.2, 0.9, 0.1]]), box) == 0.0
    assert protrusion(np.array([[0.5, 0.5, 0.5], [1.3, 1.4, 0.5]]), box) == pytest.approx(0.5)
    assert protrusion(np.zeros((0, 3)), box) == 0.0 and protrusion(box, np.zeros((0, 3))) == 0.0


def test_predicted_slider_travel_uses_the_prior_s_own_floor():
    """The same learned travel in extents means more travel under a coarser floor, for a part
    thinner than the floors (the cabinet's drawer along x, 0.5 wide, is not; a floor of half
    the diagonal is)."""
    p = _prediction()
    ext = np.ptp(p.graph.points[[4, 5]].reshape(-1, 3)[:, 2])  # the drawer's depth, ~0.06
    fine = RangePrior([RangeEntry("slider", None, None, 5, 0.0, 0.0, 1.0)], min_extent=0.002)
    coarse = RangePrior([RangeEntry("slider", None, None, 5, 0.0, 0.0, 1.0)], min_extent=0.5)
    a = _limits(predict_ranges(p, fine, None))["drawer"]
    b = _limits(predict_ranges(p, coarse, None))["drawer"]
    assert a == pytest.approx((0.0, ext), rel=0.05)
    assert b == pytest.approx((0.0, 0.5 * p.graph.scale), rel=1e-6)


def test_the_range_sweeps_reuse_the_shapes_prepared_obstacles(monkeypatch):
    # one obstacle (parry BVH) per set of static leaves and shape, shared by the selector's
    # sweeps and the range sweeps: a second pass over the same meshes builds none
    built = []
    real = selector.SweepObstacle

    def counting(*args, **kw):
        built.append(1)
        return real(*args, **kw)

    monkeypatch.setattr(selector, "SweepObstacle", counting)
    p = _prediction()
    prior = _prior(("hinge", None, None, 5, 0.0, -20.0, 120.0), ("slider", None, None, 5, 0.0, -0.5, 1.0))
    meshes = _meshes(p.graph)
    first = predict_ranges(p, prior, meshes)
    n = len(built)
    assert n == len({lk.id for lk in p.tree.moving_links})  # door and drawer: one obstacle each
    again = predict_ranges(p, prior, meshes)
    assert len(built) == n and _limits(again) == _limits(first)
    assert _limits(predict_ranges(p, prior, _meshes(p.graph))) == _limits(first)  # fresh: same ranges
    leaves = np.flatnonzero(p.graph.is_leaf)
    assert meshes.obstacle(leaves) is meshes.obstacle(leaves.copy())
