"""The learned selector's position stage (kinmo.refine.position): parallel candidates, the
re-choice of a hinge line's position, the freer-line rule, its fit and cross-validated gate,
its file."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from kinmo.errors import KinmoDataError
from kinmo.evaluate.settings import failure_kind
from kinmo.refine.groups import EdgeGroups
from kinmo.refine.position import (
    FREER_GAIN,
    POSITION_FEATURES,
    fit_position,
    freer_line,
    parallel_candidates,
    position_groups,
    reposition,
)
from kinmo.refine.ranker import Ranker, _load_ranker_cached, fit_ranker, load_ranker
from kinmo.refine.refine import RefineConfig, refine_predictions
from kinmo.refine.selector import FEATURES

from motion_cabinet import cabinet_graph
from .test_selector import _door_edge, _priors

torch.set_num_threads(1)
F = {n: k for k, n in enumerate(FEATURES)}


def _linear(std: float = 0.1, **weights: float) -> Ranker:
    w = np.zeros(len(FEATURES))
    for name, v in weights.items():
        w[F[name]] = v
    return Ranker(FEATURES, w, np.zeros(len(FEATURES)), np.ones(len(FEATURES)) * std)


def test_parallel_candidates_ignore_the_sign_and_stop_at_the_angle():
    d = np.array([[0.0, 1.0, 0.0], [0.0, -1.0, 0.0], [1.0, 0.0, 0.0],
                  [np.sin(np.radians(1.0)), np.cos(np.radians(1.0)), 0.0],
                  [np.sin(np.radians(5.0)), np.cos(np.radians(5.0)), 0.0]])
    assert parallel_candidates(d, 0).tolist() == [0, 1, 3]
    assert parallel_candidates(d, 2).tolist() == [2]
    assert parallel_candidates(d, 0, max_deg=6.0).tolist() == [0, 1, 3, 4]


def test_reposition_moves_only_among_parallel_lines():
    x = np.zeros((4, len(FEATURES)))
    x[:, F["attach_ref"]] = [0.9, 0.5, 0.0, 0.1]  # line 2 is the most attached of all
    d = np.array([[0.0, 1.0, 0.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
    pos = _linear(std=1.0, attach_ref=-3.0)
    assert reposition(None, x, d, 0) == 0
    # line 2 is not parallel to line 0: the most attached parallel line is 3
    assert reposition(pos, x, d, 0) == 3
    assert reposition(pos, x, d, 2) == 2  # no parallel line: the winner stands
    assert reposition(pos, x, d, -1) == -1
    # on top of the first stage: a strong preference for line 0 stands against a weak
    # position score, a weak one does not
    strong, weak = np.log([0.97, 0.01, 0.01, 0.01]), np.log([0.4, 0.2, 0.2, 0.2])
    assert reposition(pos, x, d, 0, strong) == 0
    assert reposition(pos, x, d, 0, weak) == 3
    # never to a line the part can turn about less freely than the winner's (the swept test)
    x[:, F["sweep_free_max"]] = [1.0, 0.97, 1.0, 0.2]
    assert reposition(pos, x, d, 0) == 1
    x[:, F["sweep_free_max"]] = [0.2, 0.1, 1.0, 0.2]  # a blocked winner: equally blocked lines
    assert reposition(pos, x, d, 0) == 3


def test_freer_line_moves_only_to_a_likely_parallel_line_the_part_turns_about_more_freely():
    x = np.zeros((4, len(FEATURES)))
    d = np.array([[1.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])
    x[:, F["sweep_free_max"]] = 1.0
    x[:, F["sweep_free_min"]] = [0.35, 0.75, 1.0, 0.7]
    p = np.array([0.34, 0.32, 0.30, 0.04])
    assert freer_line(x, p, d, 0) == 1  # nearly as likely, freer on its blocked side
    assert freer_line(x, p, d, 2) == 2  # no parallel line
    assert freer_line(x, p, d, -1) == -1
    assert freer_line(x, p, d, 1) == 1  # never to a line less free than the winner
    # line 1 too unlikely against the winner; line 3 (antiparallel: a line up to its sign) is not
    assert freer_line(x, np.array([0.34, 0.10, 0.30, 0.26]), d, 0) == 3
    # neither freer by FREER_GAIN: the winner stands
    x[:, F["sweep_free_min"]] = [0.35, 0.35 + FREER_GAIN - 0.01, 1.0, 0.0]
    assert freer_line(x, p, d, 0) == 0
    # freer on the blocked side but blocked on the free one: no move
    x[:, F["sweep_free_min"]] = [0.35, 0.75, 1.0, 0.0]
    x[1, F["sweep_free_max"]] = 0.8
    assert freer_line(x, p, d, 0) == 0
    # no meshes: every swept term is 1 and nothing moves
    x[:, F["sweep_free_min"]] = x[:, F["sweep_free_max"]] = 1.0
    assert freer_line(x, p, d, 0) == 0


@pytest.mark.exactdata
def test_freer_line_brings_a_real_laptop_lid_nearer_its_hinge(mobility_root):
    """Laptop 11406 (the shared data's test split): its screen's parallel candidate lines
    near the hinge. Starting from the one farthest from the true hinge, with every line
    equally likely, the rule moves to a line nearer the truth: about the true hinge the
    screen closes onto the keyboard without meeting it (docs/results/ranges.md)."""
    from kinmo.data.build import build_graph
    from kinmo.data.model import FINE_TYPES
    from kinmo.data.readers import read_shape
    from kinmo.metrics.axis import line_distance
    from kinmo.refine.selector import GNNPriors, candidate_features, edge_candidates, shape_meshes

    g = build_graph(read_shape(mobility_root / "11406"), n_points=256)
    meshes = shape_meshes(g)
    assert meshes is not None
    k = next(k for k, t in enumerate(g.edge_fine) if FINE_TYPES[int(t)].startswith("R_")
             and g.node_names[int(g.sibling_edges[k][0])] == "screen_side")
    i, j = (int(v) for v in g.sibling_edges[k])
    d, o = g.edge_axis_direction[k], g.edge_axis_origin[k]
    cands, frames = edge_candidates(g, i, j, "R", d, o)
    pri = GNNPriors(np.full((len(g.sibling_edges), 10), 0.1), FINE_TYPES)
    x, _ = candidate_features(g, i, j, k, cands, frames, pri, d, o, None, meshes)
    dist = np.array([float(line_distance(cands.origins[n], cands.directions[n], o, d))
                     for n in range(len(cands.origins))]) / g.scale
    near = parallel_candidates(cands.directions, int(np.argmin(dist)))
    near = near[dist[near] < 0.05]
    start = int(near[np.argmax(dist[near])])
    assert dist[start] > 0.015
    moved = freer_line(x, np.ones(len(dist)), cands.directions, start)
    assert moved != start and dist[moved] < dist[start]
    assert x[moved, F["sweep_free_min"]] >= x[start, F["sweep_free_min"]] + FREER_GAIN


def test_fit_ranker_offsets_are_fixed_scores():
    rng = np.random.default_rng(0)
    groups = []
    for _ in range(40):
        x = np.zeros((3, len(FEATURES)))
        x[:, 0] = rng.normal(size=3)
        groups.append((x, np.array([True, False, False])))
    # the offsets alone tell the right line: the fit needs no weight on the noise feature
    off = [np.array([5.0, 0.0, 0.0])] * 40
    with_off = fit_ranker(groups, features=(FEATURES[0],), offsets=off, l2=0.1)
    alone = fit_ranker(groups, features=(FEATURES[0],), l2=0.1)
    assert abs(with_off.weights[0]) < abs(alone.weights[0]) + 1e-12
    with pytest.raises(ValueError, match="offsets"):
        fit_ranker(groups, features=(FEATURES[0],), offsets=[np.zeros(2)] * 40)
    with pytest.raises(ValueError, match="offsets"):
        fit_ranker(groups, features=(FEATURES[0],), offsets=off[:3])


def test_position_groups_keep_revolute_edges_with_a_position_choice():
    x = [np.arange(3 * len(FEATURES), dtype=float).reshape(3, -1)] * 4
    angle = [np.array([0.0, 1.0, 60.0])] * 4
    dist = [np.array([0.0, 0.2, 0.0]), np.array([0.0, 0.01, 0.3]), np.array([0.0, 0.2, 0.0]),
            np.array([0.3, 0.2, 0.0])]
    pairs, idx, kept = position_groups(_groups(x, angle, dist, [True, True, False, True]))
    # group 1: both right-direction lines right in position; group 2 a slider; group 3 none right
    assert idx.tolist() == [0] and kept[0].tolist() == [0, 1]
    np.testing.assert_array_equal(pairs[0][0], x[0][:2])
    assert pairs[0][1].tolist() == [True, False]


def _groups(x, angle, dist, revolute, directions=(), categories=None) -> EdgeGroups:
    n = len(x)
    return EdgeGroups(x=list(x), y=[np.asarray(d) < 0.05 for d in dist], angle=list(angle),
                      dist=list(dist), shape_id=[f"s{k}" for k in range(n)],
                      category=list(categories) if categories is not None else ["c"] * n,
                      edge=list(range(n)), gnn_angle=[0.0] * n, gnn_dist=[0.0] * n,
                      revolute=list(revolute), joint=[f"s{k}/1/fine" for k in range(n)],
                      directions=list(directions))


def _hinge_groups(n: int, informative: bool, seed: int = 0):
    """``n`` revolute edges, 4 lines each: 0-2 parallel (one right in position, at a random
    place), 3 of another direction. ``attach_ref`` marks the right position when informative."""
    rng = np.random.default_rng(seed)
    xs, angles, dists, dirs, chosen = [], [], [], [], []
    for _ in range(n):
        right = int(rng.integers(3))
        x = np.zeros((4, len(FEATURES)))
        x[:, F["attach_ref"]] = rng.normal(size=4) * 0.1 + 0.5
        if informative:
            x[right, F["attach_ref"]] = 0.0
        d = np.full(4, 0.2)
        d[right] = 0.0
        xs.append(x)
        angles.append(np.array([0.0, 0.0, 0.0, 90.0]))
        dists.append(d)
        dirs.append(np.array([[0.0, 1.0, 0.0]] * 3 + [[1.0, 0.0, 0.0]]))
        chosen.append(int(rng.integers(3)))  # the first stage: right direction, any position
    return xs, angles, dists, dirs, np.array(chosen)


def test_fit_position_is_kept_only_when_it_lowers_the_line_distance():
    n = 30
    folds = np.arange(n) % 3
    w = np.ones(n)
    cats = ["a", "b"] * (n // 2)
    xs, a, d, dirs, chosen = _hinge_groups(n, informative=True)
    base = [np.zeros(4)] * n  # a first stage with no preference
    stage, st = fit_position(_groups(xs, a, d, [True] * n, dirs, cats), chosen, base, folds, w)
    assert stage is not None and stage.features == POSITION_FEATURES
    assert st["position_dist_after"] < 0.5 * st["position_dist_before"]
    assert st["position_cat_dist_after"] < 0.5 * st["position_cat_dist_before"]
    assert st["position_angle_after"] == st["position_angle_before"] == 0.0
    assert stage.meta["stage"] == "position" and st["position_kept"] == 1.0
    # a feature that says nothing: the stage does not help out of fold and is not kept
    xs, a, d, dirs, chosen = _hinge_groups(n, informative=False, seed=1)
    chosen = np.array([int(np.argmin(dd)) for dd in d])  # the first stage is already right
    stage, st = fit_position(_groups(xs, a, d, [True] * n, dirs, cats), chosen, base, folds, w)
    assert stage is None and st["position_dist_before"] == 0.0 and st["position_kept"] == 0.0
    # sliders only: nothing to fit
    stage, st = fit_position(_groups(xs, a, d, [False] * n, dirs, cats), chosen, base, folds, w)
    assert stage is None and st == {"position_groups": 0.0}


def test_position_stage_roundtrips_in_the_ranker_file(tmp_path):
    import json

    from kinmo.data.model import COARSE_TYPES

    r = _linear(log_dir_prior=2.0)
    r.position = Ranker(POSITION_FEATURES, np.arange(len(POSITION_FEATURES), dtype=float),
                        np.zeros(len(POSITION_FEATURES)), np.ones(len(POSITION_FEATURES)))
    r.coarse = _linear(log_dir_prior=1.0)
    r.coarse.position = Ranker(POSITION_FEATURES, -np.ones(len(POSITION_FEATURES)),
                               np.zeros(len(POSITION_FEATURES)), np.ones(len(POSITION_FEATURES)))
    back = load_ranker(r.save(tmp_path / "ranker.json"))
    np.testing.assert_array_equal(back.position.weights, r.position.weights)
    assert back.position.position is None and back.position.coarse is None
    np.testing.assert_array_equal(back.for_types(COARSE_TYPES).position.weights,
                                  r.coarse.position.weights)
    # files without one load with none; a nested one is one clear error
    d = json.loads((tmp_path / "ranker.json").read_text())
    del d["position"]
    (tmp_path / "old.json").write_text(json.dumps(d))
    assert load_ranker(tmp_path / "old.json").position is None
    d["position"] = {**d["coarse"], "position": {}}
    (tmp_path / "bad.json").write_text(json.dumps(d))
    with pytest.raises(KinmoDataError, match="position"):
        load_ranker(tmp_path / "bad.json")


def test_refinement_moves_a_door_to_its_hinge_edge_and_keeps_its_confidence(tmp_path):
    """A first stage that picks the door's direction but the unattached (wrong) edge; the
    position stage, preferring the line attached to the body, moves it to the true hinge."""
    from kinmo.mobility_tree import EdgePrediction

    g = cabinet_graph(n_points=128)
    k = _door_edge(g)
    e = len(g.sibling_edges)
    pri = _priors(g, k, "R_V_S", {1: 0.9, 0: 0.1})
    pred = EdgePrediction(pri.probs.copy(), np.tile([0.0, 1.0, 0.0], (e, 1)),
                          np.tile(g.obb_center[2], (e, 1)))
    out = {}
    for name, stage in (("first", None), ("both", _linear(attach_ref=-9.0))):
        r = _linear(log_dir_prior=2.0, attach_ref=3.0)
        r.position = stage
        path = r.save(tmp_path / f"{name}.json")
        _load_ranker_cached.cache_clear()
        out[name] = refine_predictions(g, pred, None, RefineConfig(selector="ranker", ranker=str(path)),
                                       only=[k], priors=pri)
    kinds = {n: failure_kind(o.axis_direction[k], o.axis_origin[k], g.edge_axis_direction[k],
                             g.edge_axis_origin[k], g.scale, True) for n, o in out.items()}
    assert kinds == {"first": "wrong parallel edge", "both": "ok"}
    np.testing.assert_allclose(out["both"].axis_direction[k], out["first"].axis_direction[k])
    assert out["both"].confidence[k] == out["first"].confidence[k]


def test_train_ranker_command_reports_the_position_stage(monkeypatch, tmp_path):
    """``kinmo train ranker`` prints one line per type set on its position stage."""
    from typer.testing import CliRunner

    import kinmo.train.ranker as train_ranker_module
    from kinmo.cli import app

    stats = {"groups": 10, "recall": 1.0, "oof_top1": 0.8, "oof_angle": 3.0, "gnn_angle": 5.0,
             "position_groups": 4.0, "position_dist_before": 0.05, "position_dist_after": 0.04,
             "position_cat_dist_before": 0.06, "position_cat_dist_after": 0.05,
             "position_kept": 1.0}
    no_stage = {k: v for k, v in stats.items() if not k.startswith("position")}
    monkeypatch.setattr(train_ranker_module, "train_ranker",
                        lambda *a, **k: (None, {"fine": stats, "coarse": no_stage}))
    r = CliRunner().invoke(app, ["train", "ranker", "--data", str(tmp_path), "--out",
                                 str(tmp_path / "o"), "--split", str(tmp_path / "s.json")])
    assert r.exit_code == 0, r.output
    assert ("fine position stage kept: hinge line distance 0.0500 -> 0.0400, per category "
            "0.0600 -> 0.0500") in " ".join(r.output.split())
    assert "coarse position stage" not in r.output
