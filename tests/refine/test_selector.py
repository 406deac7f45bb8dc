"""The learned candidate selector (kinmo.refine.selector): candidates of every orientation,
soft GNN priors, geometric terms, the ranker fit and its calibration."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from kinmo.data.model import FINE_INDEX, FINE_TYPES
from kinmo.errors import KinmoDataError
from kinmo.refine.refine import RefineConfig, refine_predictions
from kinmo.refine.selector import (
    FEATURES,
    GNNPriors,
    calibrate,
    candidate_features,
    candidate_labels,
    edge_candidates,
    fit_ranker,
    _point_line,
    load_ranker,
)
from kinmo.evaluate.settings import failure_kind

from motion_cabinet import cabinet_graph

torch.set_num_threads(1)
F = {n: k for k, n in enumerate(FEATURES)}


def _door_edge(g):
    return int(np.flatnonzero((g.sibling_edges[:, 0] == 2) & (g.sibling_edges[:, 1] == 1))[0])


def _priors(g, k, fine: str, axis_mass: dict[int, float] | None = None):
    e = len(g.sibling_edges)
    probs = np.full((e, 10), 0.01)
    probs[:, FINE_INDEX["None"]] = 0.91
    probs[k] = 0.01
    probs[k, FINE_INDEX[fine]] = 0.91
    dirs = np.zeros((e, 10, 3))
    dirs[:, :3] = np.eye(3)
    dirs[:, 3:6] = np.eye(3)
    dirs[:, 6:9] = np.eye(3)
    dirs[:, 9] = [1.0, 0.0, 0.0]
    ap = np.full((e, 10), 0.1)
    if axis_mass:
        ap[k] = 0.0
        for a, m in axis_mass.items():
            ap[k, a] = m
    return GNNPriors(probs, FINE_TYPES, ap, dirs)


def test_candidates_of_every_orientation_contain_the_hinge_for_a_flipped_gnn_axis():
    g = cabinet_graph(n_points=64)
    k = _door_edge(g)
    # the GNN says "horizontal" (x) for the vertical door hinge
    cands, frames = edge_candidates(g, 2, 1, "R_H_S", np.array([1.0, 0, 0]), g.obb_center[2])
    assert len(frames) == len(cands) and frames[-1] == "gnn" and cands.kinds[-1] == "gnn"
    vertical = np.abs(cands.directions[:, 1]) > 0.99
    assert vertical.any() and (~vertical).any()
    ok = candidate_labels(cands, g.edge_axis_origin[k], g.edge_axis_direction[k], g.scale, True)
    assert ok.any() and not ok[-1]  # the truth is a candidate, the GNN's own line is not it


def test_priors_direction_orientation_and_pivot():
    g = cabinet_graph(n_points=64)
    k = _door_edge(g)
    pri = _priors(g, k, "R_H_S", {1: 0.7, 7: 0.2, 0: 0.1})  # y twice (part y, shape y)
    dp = pri.direction_prior(k, np.array([[0, 1.0, 0], [1.0, 0, 0], [0, 0, 1.0]]))
    np.testing.assert_allclose(dp, [0.9, 0.1, 0.0])
    ph, pv = pri.orientation(k)
    assert ph > 0.95 and abs(ph + pv - 1) < 1e-12
    pc, ps = pri.pivot(k)
    assert ps > 0.95
    coarse = GNNPriors(np.full((len(g.sibling_edges), 5), 0.2), ("Fixed", "None", "P", "R", "PR"))
    assert coarse.orientation(k) == (0.5, 0.5) and coarse.pivot(k) == (0.5, 0.5)
    np.testing.assert_allclose(coarse.direction_prior(k, np.eye(3)), 0.1)


def test_features_see_collision_and_attachment():
    g = cabinet_graph(n_points=256)
    k = _door_edge(g)
    cands, frames = edge_candidates(g, 2, 1, "R", np.array([0, 1.0, 0]), g.obb_center[2])
    x, sign = candidate_features(g, 2, 1, k, cands, frames, _priors(g, k, "R_V_S"),
                                 np.array([0, 1.0, 0]), g.obb_center[2])
    assert x.shape == (len(cands), len(FEATURES)) and np.all(np.isfinite(x))
    assert set(np.unique(sign)) <= {-1, 1}
    hinge = candidate_labels(cands, g.edge_axis_origin[k], g.edge_axis_direction[k], g.scale, True)
    h = int(np.flatnonzero(hinge)[0])
    # the true hinge lets the door swing out in one sign; the vertical edge at the door's
    # other side (x = 0, at the body's front face) sweeps through the body in both signs
    other = int(np.flatnonzero((np.abs(cands.directions[:, 1]) > 0.99)
                               & (np.abs(cands.origins[:, 0]) < 1e-6)
                               & (cands.origins[:, 2] < 0.31) & np.array([c == "edge" for c in cands.kinds]))[0])
    assert x[h, F["collide_min"]] < x[other, F["collide_min"]]
    assert x[h, F["attach_ref"]] < 0.05  # the hinge touches the body


def test_ranker_fit_is_deterministic_and_learns_a_rule():
    rng = np.random.default_rng(0)
    groups = []
    for _ in range(200):
        c = int(rng.integers(3, 9))
        x = rng.normal(size=(c, len(FEATURES)))
        y = np.zeros(c, bool)
        y[int(np.argmax(x[:, F["attach_ref"]] * -1.0))] = True  # the smallest attachment wins
        groups.append((x, y))
    r1 = fit_ranker(groups, seed=3)
    r2 = fit_ranker(groups, seed=3)
    np.testing.assert_array_equal(r1.weights, r2.weights)
    assert r1.weights[F["attach_ref"]] < 0
    assert abs(r1.weights[F["attach_ref"]]) == pytest.approx(np.abs(r1.weights).max())
    hits = [bool(y[np.argmax(r1.probabilities(x))]) for x, y in groups]
    assert np.mean(hits) > 0.9


def test_ranker_weights_count_groups_and_are_checked():
    rng = np.random.default_rng(2)

    def group(col):
        x = rng.normal(size=(5, len(FEATURES)))
        y = np.zeros(5, bool)
        y[int(np.argmax(x[:, F[col]]))] = True
        return x, y

    # 40 groups ruled by attach_ref, 10 by attach_any
    groups = [group("attach_ref") for _ in range(40)] + [group("attach_any") for _ in range(10)]
    uniform = fit_ranker(groups)
    np.testing.assert_allclose(fit_ranker(groups, weights=np.ones(50)).weights, uniform.weights)
    # weight 0 is the same as leaving the group out
    w = np.r_[np.ones(40), np.zeros(10)]
    np.testing.assert_allclose(fit_ranker(groups, weights=w).weights,
                               fit_ranker(groups[:40]).weights, rtol=1e-6, atol=1e-9)
    # weighting the minority up turns the fit towards its rule
    up = fit_ranker(groups, weights=np.r_[np.ones(40) / 40, np.ones(10) / 2])
    assert up.weights[F["attach_any"]] > uniform.weights[F["attach_any"]]
    for bad in (np.ones(3), -np.ones(50), np.full(50, np.nan), np.zeros(50)):
        with pytest.raises(ValueError):
            fit_ranker(groups, weights=bad)


def test_calibration_matches_frequencies_and_roundtrip(tmp_path):
    rng = np.random.default_rng(1)
    p = rng.uniform(0.2, 0.99, size=4000)
    true = 1 / (1 + np.exp(-(2.0 * np.log(p / (1 - p)) - 1.0)))
    y = rng.uniform(size=p.size) < true
    a, b = calibrate(p, y)
    assert a == pytest.approx(2.0, abs=0.3) and b == pytest.approx(-1.0, abs=0.3)
    assert calibrate(np.array([0.5, 0.6]), np.array([True, True])) == (1.0, 0.0)
    groups = [(rng.normal(size=(4, len(FEATURES))), np.array([True, False, False, False]))
              for _ in range(10)]
    r = fit_ranker(groups)
    r.platt = (a, b)
    back = load_ranker(r.save(tmp_path / "ranker.json"))
    np.testing.assert_allclose(back.weights, r.weights)
    assert back.confidence(0.9) == pytest.approx(r.confidence(0.9))


def test_calibration_with_the_gnn_direction_prior(tmp_path):
    """Issue 34: the confidence also reads the GNN's mass on the chosen direction."""
    import json

    rng = np.random.default_rng(2)
    p = rng.uniform(0.2, 0.99, size=4000)
    q = rng.uniform(0.0, 1.0, size=p.size)
    t = 1.0 * np.log(p / (1 - p)) + 0.8 * np.log(q + 1e-3) + 0.5
    y = rng.uniform(size=p.size) < 1 / (1 + np.exp(-t))
    a, b, c = calibrate(p, y, q)
    assert a == pytest.approx(1.0, abs=0.3) and b == pytest.approx(0.5, abs=0.3)
    assert c == pytest.approx(0.8, abs=0.15)
    assert calibrate(np.array([0.5, 0.6]), np.array([True, True]), np.ones(2)) == (1.0, 0.0, 0.0)
    groups = [(rng.normal(size=(4, len(FEATURES))), np.array([True, False, False, False]))
              for _ in range(10)]
    r = fit_ranker(groups)
    r.platt, r.prior_weight = (a, b), c
    path = r.save(tmp_path / "ranker.json")
    back = load_ranker(path)
    assert back.prior_weight == pytest.approx(c)
    assert back.confidence(0.9, 0.05) == pytest.approx(r.confidence(0.9, 0.05))
    assert r.confidence(0.9, 0.05) < r.confidence(0.9, 0.95)  # a GNN-doubted direction: lower
    # a ranker file of before issue 34 (no prior_weight) reads the winner's probability only
    d = json.loads(path.read_text())
    del d["prior_weight"]
    (tmp_path / "old.json").write_text(json.dumps(d))
    old = load_ranker(tmp_path / "old.json")
    assert old.prior_weight == 0.0
    assert old.confidence(0.9, 0.05) == pytest.approx(old.confidence(0.9, 0.95))


def test_selected_axis_repairs_a_flip_and_the_fine_type_follows(tmp_path):
    from kinmo.mobility_tree import EdgePrediction
    from kinmo.predict import consistent_fine

    g = cabinet_graph(n_points=128)
    k = _door_edge(g)
    # a ranker that trusts the GNN's axis-candidate prior and the attachment
    w = np.zeros(len(FEATURES))
    w[F["log_dir_prior"]] = 2.0
    w[F["attach_ref"]] = -3.0
    w[F["collide_min"]] = -3.0
    from kinmo.refine.selector import Ranker

    r = Ranker(FEATURES, w, np.zeros(len(FEATURES)), np.ones(len(FEATURES)) * 0.1)
    path = r.save(tmp_path / "ranker.json")
    e = len(g.sibling_edges)
    pri = _priors(g, k, "R_H_S", {1: 0.6, 0: 0.4})  # types say H, axis head leans to y
    d = np.tile([0.0, 1.0, 0.0], (e, 1))
    d[k] = [1.0, 0.0, 0.0]  # the GNN's chosen (flipped) direction
    pred = EdgePrediction(pri.probs.copy(), d, np.tile(g.obb_center[2], (e, 1)))
    cfg = RefineConfig(selector="ranker", ranker=str(path))
    out = refine_predictions(g, pred, None, cfg, only=[k], priors=pri)
    assert abs(out.axis_direction[k, 1]) > 0.99
    assert failure_kind(out.axis_direction[k], out.axis_origin[k], g.edge_axis_direction[k],
                        g.edge_axis_origin[k], g.scale, True) in ("ok", "sign")
    assert 0.0 < out.confidence[k] < 1.0
    fixed = consistent_fine(g, EdgePrediction(pred.probs, out.axis_direction, out.axis_origin))
    assert FINE_TYPES[int(np.argmax(fixed.probs[k]))] == "R_V_S"


def test_ranker_selector_needs_a_file():
    with pytest.raises(ValueError, match="ranker"):
        RefineConfig(selector="ranker")


def test_failure_kinds():
    o, t = np.zeros(3), np.array([0, 1.0, 0])
    assert failure_kind(np.array([1.0, 0, 0]), o, t, o, 1.0, True) == "orientation flip"
    assert failure_kind(np.array([0.2, 1.0, 0]), o, t, o, 1.0, True) == "tilted box"
    assert failure_kind(t, o + [0.5, 0, 0], t, o, 1.0, True) == "wrong parallel edge"
    assert failure_kind(-t, o, t, o, 1.0, True) == "sign"
    assert failure_kind(t, o + [0.5, 0, 0], t, o, 1.0, False) == "ok"


def test_fold_ids_stratified_and_seeded():
    from kinmo.refine.fit_selector import fold_ids

    ids = [f"s{n}" for n in range(12)]
    cats = ["a"] * 6 + ["b"] * 4 + ["c"] * 2
    f1 = fold_ids(ids, cats, 3, seed=0)
    assert f1 == fold_ids(ids, cats, 3, seed=0)
    assert sorted(f1[:6]) == [0, 0, 1, 1, 2, 2]  # each category spread over the folds
    assert len(set(f1[10:])) == 2
    with pytest.raises(ValueError):
        fold_ids(ids, cats, 1)


def test_collect_groups_and_fit_selector_on_oracle_predictions():
    from motion_cabinet import oracle_prediction

    from kinmo.mobility_tree import build_mobility_tree
    from kinmo.predict import ShapePrediction
    from kinmo.refine.fit_selector import collect_groups, fit_selector

    preds = []
    for s in range(6):
        g = cabinet_graph(n_points=64, seed=s, jitter=0.2, shape_id=f"cab{s}")
        e = oracle_prediction(g)
        preds.append(ShapePrediction(g, e, build_mobility_tree(g, e), FINE_TYPES))
    groups = collect_groups(preds)
    assert len(groups.y) == 12  # door and drawer of each cabinet
    assert all(y.any() for y in groups.y)  # the truth is always a candidate
    assert all(y[-1] for y in groups.y)  # the oracle GNN's own line is right
    ranker, st = fit_selector(groups, k=2)
    assert st["recall"] == 1.0 and 0.0 <= st["oof_top1"] <= 1.0
    assert ranker.meta["cv"]["groups"] == 12
    assert len(set(groups.joint)) == 12 and st["joints"] == 12.0
    assert st["oof_joint_angle"] >= 0.0 and st["gnn_joint_angle"] >= 0.0


def test_per_joint_statistics_weigh_each_moving_part_once():
    from kinmo.refine.fit_selector import _joint_stats
    from kinmo.refine.groups import EdgeGroups, joint_weights

    # part A has three sibling edges (all chose a 90-degree line), part B one (0 degrees):
    # per edge the mean is 67.5, per joint 45.
    n = 4
    g = EdgeGroups(
        x=[np.zeros((2, 1))] * n, y=[np.array([True, False])] * n,
        angle=[np.array([90.0, 0.0])] * 3 + [np.array([0.0, 90.0])],
        dist=[np.array([0.2, 0.0])] * 3 + [np.array([0.0, 0.2])],
        shape_id=["s"] * n, category=["c"] * n, edge=[0, 1, 2, 3],
        gnn_angle=[0.0, 0.0, 0.0, 90.0], gnn_dist=[0.0] * n, revolute=[True] * n,
        joint=["s/1/fine"] * 3 + ["s/2/fine"])
    st = _joint_stats(g, np.zeros(n, np.int64), joint_weights(g))
    assert st["joints"] == 2.0
    assert st["oof_joint_angle"] == 45.0 and st["gnn_joint_angle"] == 45.0
    assert abs(st["oof_joint_dist"] - 0.1) < 1e-12
    g.joint = []  # groups without parts: no per-joint statistics
    np.testing.assert_array_equal(joint_weights(g), np.ones(n))
    assert _joint_stats(g, np.zeros(n, np.int64), joint_weights(g)) == {}


@pytest.mark.exactdata
def test_sweep_terms_on_a_real_door_prefer_the_true_hinge(mobility_root):
    from kinmo.data.build import build_graph
    from kinmo.data.readers import read_shape
    from kinmo.refine.selector import shape_meshes

    folder = mobility_root / "45001"  # a cabinet with a hinged door
    if not folder.is_dir():
        folder = sorted(p for p in mobility_root.iterdir() if p.is_dir())[0]
    g = build_graph(read_shape(folder), n_points=256)
    meshes = shape_meshes(g)
    assert meshes is not None and set(meshes.leaves) == set(np.flatnonzero(g.is_leaf).tolist())
    hinges = [k for k, t in enumerate(g.edge_fine) if FINE_TYPES[int(t)].startswith("R_")]
    assert hinges
    k = hinges[0]
    i, j = (int(x) for x in g.sibling_edges[k])
    pri = GNNPriors(np.full((len(g.sibling_edges), 10), 0.1), FINE_TYPES)
    d, o = g.edge_axis_direction[k], g.edge_axis_origin[k]
    cands, frames = edge_candidates(g, i, j, "R", d, o)
    x, sign = candidate_features(g, i, j, k, cands, frames, pri, d, o, None, meshes)
    y = candidate_labels(cands, o, d, g.scale, True)
    assert y.any() and (~y).any()
    # the true hinge swings free in one sign; the wrong lines on average do not
    assert x[y, F["sweep_free_max"]].max() > x[~y, F["sweep_free_max"]].mean()
    assert x[y, F["attach_mesh"]].min() < x[~y, F["attach_mesh"]].mean()


def test_hinge_lies_away_from_the_moving_parts_handle():
    g = cabinet_graph(n_points=64)
    k = _door_edge(g)
    cands, frames = edge_candidates(g, 2, 1, "R", np.array([0, 1.0, 0]), g.obb_center[2])
    args = (g, 2, 1, k, cands, frames, _priors(g, k, "R_V_S"), np.array([0, 1.0, 0]),
            g.obb_center[2])
    x, _ = candidate_features(*args)
    assert np.all(x[:, F["d_child"]] == 0) and np.all(x[:, F["d_child_edge"]] == 0)  # no child
    hinge = candidate_labels(cands, g.edge_axis_origin[k], g.edge_axis_direction[k], g.scale, True)
    h = int(np.flatnonzero(hinge)[0])
    other = int(np.flatnonzero((np.abs(cands.directions[:, 1]) > 0.99)
                               & (np.abs(cands.origins[:, 0]) < 1e-6)
                               & (cands.origins[:, 2] < 0.31) & np.array([c == "edge" for c in cands.kinds]))[0])
    # give the door a handle at its free side (the edge opposite the hinge)
    g.parent[5] = 2
    rng = np.random.default_rng(0)
    g.points[5] = cands.origins[other] + 0.01 * rng.standard_normal(np.shape(g.points[5]))
    x, _ = candidate_features(*args)
    assert x[h, F["d_child"]] > 0.5 > 0.05 > x[other, F["d_child"]]
    np.testing.assert_allclose(x[:, F["d_child_edge"]],
                               x[:, F["d_child"]] * x[:, F["kind_edge"]])


def test_sweeps_of_a_shape_are_computed_once_per_line_with_the_same_results(monkeypatch):
    import trimesh

    import kinmo.refine.selector
    from kinmo.geometry import SweepObstacle, sweep_collisions
    from kinmo.refine.selector import ShapeMeshes

    box = trimesh.creation.box((1.0, 1.0, 1.0))
    wall = (np.asarray(box.vertices) * [0.1, 2, 2] + [0.6, 0, 0], np.asarray(box.faces, np.int64))
    meshes = ShapeMeshes({1: wall, 2: (np.asarray(box.vertices), np.asarray(box.faces, np.int64))})
    rng = np.random.default_rng(0)
    pts = rng.uniform(-0.5, 0.5, size=(64, 3))
    o = rng.normal(size=(6, 3)) * 0.5
    d = rng.normal(size=(6, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    kinds = np.array([0, 0, 0, 1, 1, 1])
    ranges = np.array([1.5, 1.5, 1.5, 0.5, 0.5, 0.5])
    ov, of = meshes.union([1])
    want = sweep_collisions(pts, ov, of, o, d, kinds, ranges, n_steps=8)
    calls, built = [], []

    class Counting(SweepObstacle):
        def __init__(self, v, f):
            built.append(len(f))
            super().__init__(v, f)

        def sweep(self, p, oo, *a, **k):
            calls.append(len(oo))
            return super().sweep(p, oo, *a, **k)

    monkeypatch.setattr(kinmo.refine.selector, "SweepObstacle", Counting)
    first = meshes.sweep(2, np.array([1]), pts, o[:4], d[:4], kinds[:4], ranges[:4], 8)
    again = meshes.sweep(2, np.array([1]), pts, o, d, kinds, ranges, 8)  # two new lines
    assert calls == [4, 2]
    np.testing.assert_array_equal(first[0], want[0][:4])
    np.testing.assert_array_equal(again[0], want[0])
    np.testing.assert_array_equal(again[1], want[1])
    assert 0 < want[1].max() and want[0].min() < 1  # the wall is hit: a check that can fail
    meshes.sweep(2, np.array([1]), pts[:32], o[:1], d[:1], kinds[:1], ranges[:1], 8)
    assert calls == [4, 2, 1]  # other points of the part: not the same key
    assert built == [len(of)]  # ... but the same obstacle: its BVH was built once


def test_point_line_distance_is_the_norm_of_the_cross_product_bit_for_bit():
    # the written-out cross product gives the bytes np.cross + np.linalg.norm gave (the
    # ranker's features must not move when the code gets faster)
    rng = np.random.default_rng(3)
    for n_points, n_lines in [(1, 1), (7, 3), (500, 12), (2048, 20)]:
        pts = rng.normal(size=(n_points, 3)) * rng.uniform(0.01, 10.0)
        o = rng.normal(size=(n_lines, 3))
        d = rng.normal(size=(n_lines, 3))
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        w = pts[None] - o[:, None]
        expected = np.linalg.norm(np.cross(w, d[:, None]), axis=2).min(axis=1)
        assert np.array_equal(_point_line(pts, o, d), expected)
    # a point on the line is at distance 0; no points: infinitely far
    assert _point_line(np.array([[1.0, 2.0, 3.0]]), np.array([[0.0, 2.0, 3.0]]),
                       np.array([[1.0, 0.0, 0.0]]))[0] == 0.0
    assert _point_line(np.zeros((0, 3)), o, d).tolist() == [np.inf] * len(o)


def _groups_of(categories, angles, gnn, joints=None):
    from kinmo.refine.groups import EdgeGroups

    n = len(categories)
    return EdgeGroups(
        x=[np.zeros((2, 1))] * n, y=[np.array([True, False])] * n,
        angle=[np.array([a, 90.0]) for a in angles], dist=[np.zeros(2)] * n,
        shape_id=[f"s{k}" for k in range(n)], category=list(categories), edge=list(range(n)),
        gnn_angle=list(gnn), gnn_dist=[0.0] * n, revolute=[True] * n,
        joint=joints if joints is not None else [f"s{k}/1/fine" for k in range(n)])


def test_category_weights_shrink_large_categories():
    from kinmo.refine.groups import category_weights

    g = _groups_of(["a", "a", "a", "a", "b"], [0] * 5, [0] * 5)
    np.testing.assert_allclose(category_weights(g, 0.0), np.ones(5))
    w = category_weights(g, 0.5)  # a: 4 joints -> 1/2 each; b: 1 joint -> 1
    np.testing.assert_allclose(w, [0.5, 0.5, 0.5, 0.5, 1.0])
    w = category_weights(g, 1.0)  # every category weighs one in all
    assert abs(w[:4].sum() - 1.0) < 1e-12 and w[4] == 1.0


def test_selection_error_is_per_category_and_pooled_per_type_set():
    from kinmo.refine.groups import selection_error

    # fine: a (0, 0, 0) and b (90): pooled 22.5, per category (0 + 90) / 2 = 45;
    # coarse: a (10): 10 both ways; the type sets are averaged
    joints = [f"s{k}/1/fine" for k in range(4)] + ["s4/1/coarse"]
    g = _groups_of(["a", "a", "a", "b", "a"], [0, 0, 0, 90, 10], [0] * 5, joints)
    e = selection_error(g, np.array([0.0, 0.0, 0.0, 90.0, 10.0]))
    assert e == {"all": (22.5 + 10) / 2, "mean": (45 + 10) / 2}


def test_fit_selector_chooses_its_regularisation_by_cross_validation():
    from kinmo.refine.fit_selector import CATEGORY_POWERS, DEFAULT_L2, L2_GRID, fit_selector

    rng = np.random.default_rng(0)
    groups = _groups_of(["a", "b", "c"] * 8, [0.0] * 24, [90.0] * 24)
    # feature 0 marks the right candidate (with noise): any L2 finds it
    groups.x = [np.column_stack([np.array([1.0, 0.0]) + 0.1 * rng.normal(size=2),
                                 np.zeros((2, len(FEATURES) - 1))]) for _ in range(24)]
    # by default the L2 weight is DEFAULT_L2 (issue 34, session 39) and the category
    # weighting is chosen
    ranker, _ = fit_selector(groups, features=(FEATURES[0],), k=3)
    assert [(t["l2"], t["category_power"]) for t in ranker.meta["selection"]] == [
        (DEFAULT_L2, p) for p in CATEGORY_POWERS]
    assert ranker.meta["l2"] == DEFAULT_L2 == 0.01
    # l2=None chooses it among the grid too
    ranker, st = fit_selector(groups, features=(FEATURES[0],), k=3, l2=None)
    tried = ranker.meta["selection"]
    assert [(t["l2"], t["category_power"]) for t in tried] == [
        (lam, p) for p in CATEGORY_POWERS for lam in L2_GRID]
    assert (ranker.meta["l2"], ranker.meta["category_power"]) in [
        (t["l2"], t["category_power"]) for t in tried]
    assert st["oof_cat_angle"] == 0.0 and st["gnn_cat_angle"] == 90.0
    # given values are used as given
    ranker, _ = fit_selector(groups, features=(FEATURES[0],), k=3, l2=0.5, category_power=1.0)
    assert (ranker.meta["l2"], ranker.meta["category_power"]) == (0.5, 1.0)
    assert len(ranker.meta["selection"]) == 1


def test_a_ranker_per_type_set_in_one_file(tmp_path):
    """Issue 34: fine and coarse GNNs get their own rankers (fit_type_rankers), kept in one
    file; Ranker.for_types picks the coarse one for coarse predictions, refine uses it."""
    import json

    from kinmo.data.model import COARSE_TYPES
    from kinmo.refine.fit_selector import COARSE_L2, DEFAULT_L2, fit_selector, fit_type_rankers

    rng = np.random.default_rng(0)

    def marked(sign: float, type_set: str):
        g = _groups_of(["a", "b", "c"] * 8, [0.0] * 24, [90.0] * 24,
                       joints=[f"s{k}/1/{type_set}" for k in range(24)])
        # feature 0 marks the right candidate in the fine groups, the wrong one in the coarse
        g.x = [np.column_stack([sign * np.array([1.0, 0.0]) + 0.1 * rng.normal(size=2),
                                np.zeros((2, len(FEATURES) - 1))]) for _ in range(24)]
        return g

    ranker, stats = fit_type_rankers({"fine": marked(1.0, "fine"), "coarse": marked(-1.0, "coarse")},
                                     features=(FEATURES[0],), k=3, l2=0.01, category_power=0.0,
                                     coarse_from="coarse")
    assert set(stats) == {"fine", "coarse"} and ranker.coarse is not None
    # the coarse ranker takes its own L2 weight, by default COARSE_L2 (issue 34, session 39)
    assert (ranker.meta["l2"], ranker.coarse.meta["l2"]) == (0.01, COARSE_L2)
    assert COARSE_L2 == 0.003 and DEFAULT_L2 == 0.01
    x = np.zeros((2, len(FEATURES)))
    x[:, 0] = [1.0, 0.0]
    assert np.argmax(ranker.for_types(FINE_TYPES).probabilities(x)) == 0
    assert np.argmax(ranker.for_types(COARSE_TYPES).probabilities(x)) == 1
    back = load_ranker(ranker.save(tmp_path / "ranker.json"))
    assert back.coarse is not None and back.for_types(COARSE_TYPES) is back.coarse
    np.testing.assert_allclose(back.coarse.weights, ranker.coarse.weights)
    assert np.argmax(back.for_types(COARSE_TYPES).probabilities(x)) == 1
    # a file without a coarse ranker serves both type sets (files of before issue 34)
    d = json.loads((tmp_path / "ranker.json").read_text())
    del d["coarse"]
    (tmp_path / "one.json").write_text(json.dumps(d))
    one = load_ranker(tmp_path / "one.json")
    assert one.coarse is None and one.for_types(COARSE_TYPES) is one
    # a nested or malformed coarse entry is one clear error
    d["coarse"] = {"coarse": {}}
    (tmp_path / "bad.json").write_text(json.dumps(d))
    with pytest.raises(KinmoDataError, match="coarse"):
        load_ranker(tmp_path / "bad.json")
    with pytest.raises(ValueError, match="type sets"):
        fit_type_rankers({"medium": marked(1.0, "fine")})
    with pytest.raises(ValueError, match="coarse_from"):
        fit_type_rankers({"fine": marked(1.0, "fine")}, coarse_from="fine")
    # the default: the coarse ranker is fit on both sets' groups, without the fine-only priors
    feats = (FEATURES[0], "orient_prior")
    both, stats = fit_type_rankers({"fine": marked(1.0, "fine"), "coarse": marked(1.0, "coarse")},
                                   features=feats, k=3, l2=0.01, category_power=0.0)
    assert set(stats) == {"fine", "coarse"}
    assert stats["fine"]["groups"] == 24 and stats["coarse"]["groups"] == 48
    assert both.features == feats and both.coarse.features == (FEATURES[0],)
    assert both.for_types(COARSE_TYPES) is both.coarse
    # a type set without a right candidate in any group (tiny data: `train all` on six
    # objects) is left out, and the other set's ranker serves both
    none_right = marked(-1.0, "coarse")
    none_right.y = [np.zeros(2, bool)] * len(none_right.y)
    alone, stats = fit_type_rankers({"fine": marked(1.0, "fine"), "coarse": none_right},
                                    features=(FEATURES[0],), k=3, l2=0.01, category_power=0.0,
                                    coarse_from="coarse")
    assert set(stats) == {"fine"} and alone.coarse is None
    assert alone.for_types(COARSE_TYPES) is alone
    with pytest.raises(ValueError, match="positive"):
        fit_type_rankers({"coarse": none_right}, coarse_from="coarse")
    # two sets each too thin for the inner cross-validation: one ranker on both pooled
    thin = [marked(s, t).of_shapes({"s0", "s1"}) for s, t in ((1.0, "fine"), (1.0, "coarse"))]
    thin[1].shape_id = ["s2", "s3"]
    thin[0].y = [np.array([True, False]), np.zeros(2, bool)]
    thin[1].y = [np.zeros(2, bool), np.array([True, False])]
    with pytest.raises(ValueError):
        fit_selector(thin[0], features=(FEATURES[0],), k=2, l2=0.01, category_power=0.0)
    pooled, stats = fit_type_rankers({"fine": thin[0], "coarse": thin[1]}, features=(FEATURES[0],),
                                     k=2, l2=0.01, category_power=0.0, coarse_from="coarse")
    assert set(stats) == {"pooled"} and pooled.coarse is None


def test_part_shape_features_read_the_moving_parts_own_box():
    """The door (0.5 x 0.5 x 0.02, in front of the body along z) hinges about a long side: the
    vertical hinge runs along its largest extent and across its thin one and its offset from
    the body; a line along z (its thin axis, the offset) is what knobs turn about."""
    g = cabinet_graph(n_points=64)
    k = _door_edge(g)
    cands, frames = edge_candidates(g, 2, 1, "R", np.array([0, 1.0, 0]), g.obb_center[2])
    x, _ = candidate_features(g, 2, 1, k, cands, frames, _priors(g, k, "R_V_S"),
                              np.array([0, 1.0, 0]), g.obb_center[2])
    d = cands.directions / np.linalg.norm(cands.directions, axis=1, keepdims=True)
    y, z = np.abs(d[:, 1]) > 0.99, np.abs(d[:, 2]) > 0.99
    assert y.any() and z.any()
    np.testing.assert_allclose(x[y, F["ext_along"]], 1.0, atol=1e-9)  # 0.25 / 0.25
    np.testing.assert_allclose(x[z, F["ext_along"]], 0.04, atol=1e-9)  # 0.01 / 0.25
    thin = x[:, F["thin_r_center"]] + x[:, F["thin_r_edge"]]
    np.testing.assert_allclose(thin[y], 0.0, atol=1e-9)
    np.testing.assert_allclose(thin[z], 1 - 0.01 / 0.25, atol=1e-9)
    # a revolute edge fills the revolute columns only, each line in one pivot column
    assert np.all(x[:, F["thin_p"]] == 0) and np.all(x[:, F["offset_p"]] == 0)
    assert np.all((x[:, F["thin_r_center"]] == 0) | (x[:, F["thin_r_edge"]] == 0))
    off = x[:, F["offset_r_center"]] + x[:, F["offset_r_edge"]]
    u = g.obb_center[2] - g.obb_center[1]
    np.testing.assert_allclose(off, np.abs(d @ (u / np.linalg.norm(u))), atol=1e-9)
    # the drawer (node 3) slides: the prismatic columns, the revolute ones stay 0
    kd = int(np.flatnonzero((g.sibling_edges[:, 0] == 3) & (g.sibling_edges[:, 1] == 1))[0])
    cands, frames = edge_candidates(g, 3, 1, "P", np.array([0, 0, 1.0]), g.obb_center[3])
    x, _ = candidate_features(g, 3, 1, kd, cands, frames, _priors(g, kd, "P_H"),
                              np.array([0, 0, 1.0]), g.obb_center[3])
    for n in ("thin_r_center", "thin_r_edge", "offset_r_center", "offset_r_edge"):
        assert np.all(x[:, F[n]] == 0)
    assert np.all(np.isfinite(x)) and x[:, F["offset_p"]].max() > 0.5
