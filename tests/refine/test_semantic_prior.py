"""The category / part-name direction prior of the learned selector
(kinmo.refine.semantic_prior)."""

from __future__ import annotations

import numpy as np
import pytest

from kinmo.refine.selector import FEATURES, Ranker, candidate_features, edge_candidates, load_ranker
from kinmo.refine.semantic_prior import SemanticPrior, motion_of

from motion_cabinet import cabinet_graph

Y, X, Z = np.array([0.0, 1, 0]), np.array([1.0, 0, 0]), np.array([0.0, 0, 1])


def _prior() -> SemanticPrior:
    j = [("a", "R", "Microwave", "door", "frame", Y), ("b", "R", "Microwave", "door", "frame", -Y),
         ("c", "R", "Microwave", "door", "frame", X), ("d", "R", "Oven", "door", "frame", X),
         ("e", "R", "Oven", "door", "frame", X), ("f", "P", "Microwave", "door", "frame", Z)]
    return SemanticPrior(j, alpha=2.0)


def test_motion_of_types():
    assert [motion_of(t) for t in ("P_H", "P_V", "R_H_C", "R_V_S", "PR_H", "R", "P", "PR")] == \
        ["P", "P", "R", "R", "R", "R", "P", "R"]


def test_prior_follows_the_category_and_is_sign_free():
    p = _prior()
    mw = p.probability("R", "Microwave", "door", "frame", np.stack([Y, -Y, X, Z]))
    ov = p.probability("R", "Oven", "door", "frame", np.stack([Y, X]))
    assert mw[0] == mw[1] > mw[2] > mw[3]  # 2 of 3 microwave hinges vertical, sign ignored
    assert ov[1] > ov[0]  # ovens: horizontal
    assert np.all((mw > 0) & (mw < 1))
    # unseen category backs off to the part name, then to the motion, then to 1/3
    un = p.probability("R", "Cabinet", "door", "frame", np.stack([X, Y, Z]))
    assert un[0] > un[1] > un[2]
    np.testing.assert_allclose(SemanticPrior([]).probability("R", "X", "lid", "y", np.eye(3)), 1 / 3)
    # the prismatic joint does not count for revolute candidates
    assert p.probability("P", "Microwave", "door", "frame", Z[None])[0] > 0.5


def test_a_shape_is_left_out_of_its_own_prior():
    p = _prior()
    with_c = p.probability("R", "Microwave", "door", "frame", X[None])[0]
    without_c = p.probability("R", "Microwave", "door", "frame", X[None], exclude="c")[0]
    assert without_c < with_c


def test_prior_from_graphs_and_json_round_trip(tmp_path):
    g = cabinet_graph(n_points=32)
    p = SemanticPrior.from_graphs([g])
    moving = {(m, r) for _, _, _, m, r, _ in p.joints}
    assert len(p) >= 2 and ("door", "body") in moving
    q = SemanticPrior.from_json(p.to_json())
    d = np.random.default_rng(0).normal(size=(5, 3))
    np.testing.assert_allclose(q.probability("R", g.category, "door", "body", d),
                               p.probability("R", g.category, "door", "body", d), atol=1e-6)
    with pytest.raises(ValueError):
        SemanticPrior.from_json({"joints": [["a", "Q", "c", "m", "r", [0, 1, 0]]]})
    # stored inside ranker.json, read back by load_ranker
    n = len(FEATURES)
    r = Ranker(FEATURES, np.zeros(n), np.zeros(n), np.ones(n), semantic=p)
    load = load_ranker(r.save(tmp_path / "ranker.json"))
    assert load.semantic is not None and len(load.semantic) == len(p)


def test_an_object_of_unknown_facing_gets_the_prior_averaged_over_quarter_turns():
    """Issue 36: for an object whose GNN answer is the average of its four quarter turns (no
    known part names), the prior no longer prefers PartNet's front (+z) over the side (+x),
    and keeps the vertical apart."""
    p = _prior()
    d = np.stack([X, Z, Y, (X + Z) / np.sqrt(2)])
    plain = p.probability("P", "Microwave", "door", "frame", d)
    assert plain[1] > plain[0]  # the one slider slides along PartNet's front
    turned = p.probability("P", "Microwave", "door", "frame", d, turns=True)
    assert turned[0] == pytest.approx(turned[1]) and turned[1] < plain[1]
    assert turned[2] == pytest.approx(plain[2])  # the vertical is the same at every turn
    for q in range(4):  # the same answer for the object turned any quarter
        c, s = (1.0, 0.0, -1.0, 0.0)[q], (0.0, 1.0, 0.0, -1.0)[q]
        r = np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])
        np.testing.assert_allclose(p.probability("P", "Microwave", "door", "frame", d @ r.T, turns=True),
                                   turned)


def test_candidate_features_average_the_prior_over_turns_for_turned_priors():
    g = cabinet_graph(n_points=64)
    k = int(np.flatnonzero((g.sibling_edges[:, 0] == 3) & (g.sibling_edges[:, 1] == 1))[0])
    from kinmo.data.model import FINE_TYPES
    from kinmo.refine.selector import GNNPriors

    probs = np.full((len(g.sibling_edges), 10), 0.1)
    cands, frames = edge_candidates(g, 3, 1, "P_H", Z, g.obb_center[3])
    f = FEATURES.index("sem_prior")
    other = SemanticPrior.from_graphs([cabinet_graph(n_points=32, shape_id="other")])
    sem = dict(semantic=other)
    x0, _ = candidate_features(g, 3, 1, k, cands, frames, GNNPriors(probs, FINE_TYPES), Z, g.obb_center[3], **sem)
    x1, _ = candidate_features(g, 3, 1, k, cands, frames, GNNPriors(probs, FINE_TYPES, turned=True), Z,
                               g.obb_center[3], **sem)
    front = np.abs(cands.directions[:, 2]) > 0.99
    side = np.abs(cands.directions[:, 0]) > 0.99
    assert front.any() and side.any()
    assert x0[front, f].min() > x0[side, f].max()  # the other cabinet's drawer slides out the front
    np.testing.assert_allclose(x1[front, f].min(), x1[side, f].max())  # facing unknown: alike


def test_candidate_features_take_the_semantic_prior_and_leave_out_the_shape():
    g = cabinet_graph(n_points=64)
    k = int(np.flatnonzero((g.sibling_edges[:, 0] == 2) & (g.sibling_edges[:, 1] == 1))[0])
    from kinmo.data.model import FINE_TYPES
    from kinmo.refine.selector import GNNPriors

    pri = GNNPriors(np.full((len(g.sibling_edges), 10), 0.1), FINE_TYPES)
    cands, frames = edge_candidates(g, 2, 1, "R", Y, g.obb_center[2])
    f = FEATURES.index("sem_prior")
    other = SemanticPrior.from_graphs([cabinet_graph(n_points=32, shape_id="other")])
    x0, _ = candidate_features(g, 2, 1, k, cands, frames, pri, Y, g.obb_center[2])
    np.testing.assert_allclose(x0[:, f], 1 / 3)
    x1, _ = candidate_features(g, 2, 1, k, cands, frames, pri, Y, g.obb_center[2], semantic=other)
    vertical = np.abs(cands.directions[:, 1]) > 0.99
    assert x1[vertical, f].min() > x1[~vertical, f].max()  # the other cabinet's door: vertical
    x2, _ = candidate_features(g, 2, 1, k, cands, frames, pri, Y, g.obb_center[2], semantic=other,
                               exclude="other")
    np.testing.assert_allclose(x2[:, f], x2[0, f])  # its own joints left out: no information


def test_a_ranker_with_the_semantic_prior_repairs_a_flip_the_gnn_is_sure_of(tmp_path):
    """The GNN puts all its axis mass on x for the door; the prior of another cabinet (its
    door hinge vertical), stored in ranker.json, turns the selection to a vertical line."""
    from kinmo.data.model import FINE_INDEX, FINE_TYPES
    from kinmo.mobility_tree import EdgePrediction
    from kinmo.refine.refine import RefineConfig, refine_predictions
    from kinmo.refine.selector import GNNPriors

    g = cabinet_graph(n_points=128)
    k = int(np.flatnonzero((g.sibling_edges[:, 0] == 2) & (g.sibling_edges[:, 1] == 1))[0])
    e = len(g.sibling_edges)
    probs = np.full((e, 10), 0.01)
    probs[:, FINE_INDEX["None"]] = 0.91
    probs[k] = 0.01
    probs[k, FINE_INDEX["R_H_S"]] = 0.91
    dirs = np.tile(np.eye(3), (e, 4, 1))[:, :10]
    ap = np.zeros((e, 10))
    ap[:, 0] = 1.0  # all mass on x
    pri = GNNPriors(probs, FINE_TYPES, ap, dirs)
    d = np.tile([0.0, 1.0, 0.0], (e, 1))
    d[k] = X
    pred = EdgePrediction(probs.copy(), d, np.tile(g.obb_center[2], (e, 1)))
    n = len(FEATURES)
    outs = {}
    for name, w_sem in (("without", 0.0), ("with", 4.0)):
        w = np.zeros(n)
        w[FEATURES.index("log_dir_prior")] = 1.0
        w[FEATURES.index("log_sem_prior")] = w_sem
        w[FEATURES.index("attach_ref")] = -3.0
        r = Ranker(FEATURES, w, np.zeros(n), np.ones(n) * 0.1,
                   semantic=SemanticPrior.from_graphs([cabinet_graph(n_points=32, shape_id="b")]))
        path = r.save(tmp_path / f"{name}.json")
        cfg = RefineConfig(selector="ranker", ranker=str(path))
        outs[name] = refine_predictions(g, pred, None, cfg, only=[k], priors=pri).axis_direction[k]
    assert abs(outs["without"][1]) < 0.5  # the GNN's horizontal axis kept
    assert abs(outs["with"][1]) > 0.99  # the prior's vertical hinge
