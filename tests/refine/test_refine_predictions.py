"""Refinement of a shape's GNN predictions (kinmo.refine.refine)."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from kinmo.data.model import COARSE_INDEX, FINE_INDEX, FINE_TYPES
from kinmo.refine.axis_net import AxisNetConfig, AxisSelectionNet
from kinmo.refine.refine import (
    EdgePredictions,
    RefineConfig,
    as_edge_predictions,
    refine_predictions,
)
from kinmo.refine.scoring import ScoringConfig

from .refine_boxes import box_cabinet, edge_index

torch.set_num_threads(1)


@pytest.fixture(scope="module")
def model():
    torch.manual_seed(0)
    cfg = AxisNetConfig(n_points=64, k=8, widths=[8, 8, 16], emb_dim=16, head=[16], dropout=0.0)
    return AxisSelectionNet(cfg).eval()


def _gnn_like(graph, noise=0.0, seed=0, coarse=False):
    """Predictions equal to the labels, axes perturbed by ``noise`` (mesh units / radians)."""
    rng = np.random.default_rng(seed)
    e = len(graph.sibling_edges)
    probs = np.full((e, 10), 0.01)
    probs[np.arange(e), graph.edge_fine] = 0.91
    d = np.where(np.isfinite(graph.edge_axis_direction), graph.edge_axis_direction, 0.0)
    d[~np.isfinite(graph.edge_axis_direction).all(1)] = [0.0, 1.0, 0.0]
    d = d + noise * rng.normal(size=d.shape)
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    o = np.where(np.isfinite(graph.edge_axis_origin), graph.edge_axis_origin, 0.0)
    o = o + noise * rng.normal(size=o.shape)
    if coarse:
        from kinmo.mobility_tree import coarse_probs

        probs = coarse_probs(probs)
    return {"probs": probs, "direction": d, "origin": o}


def test_refined_axes_snap_to_the_true_candidates_without_the_network(model):
    g = box_cabinet(128)
    pred = _gnn_like(g, noise=0.003)  # the door's two front edges are 0.02 apart
    # no feasibility weight: selection by agreement with the (slightly wrong) GNN axes
    cfg = RefineConfig(scoring=ScoringConfig(w_feasibility=0.0))
    out = refine_predictions(g, pred, model, cfg)
    door, drawer, knob = edge_index(g, 2, 1), edge_index(g, 3, 1), edge_index(g, 4, 2)
    np.testing.assert_array_equal(np.flatnonzero(out.refined), sorted([door, drawer, knob]))
    for k in (door, drawer, knob):
        true_o, true_d = g.edge_axis_origin[k], g.edge_axis_direction[k]
        assert abs(abs(out.axis_direction[k] @ true_d) - 1) < 1e-9  # exactly the OBB direction
        assert np.linalg.norm(np.cross(out.axis_origin[k] - true_o, true_d)) < 1e-9
        i = g.sibling_edges[k, 0]
        # canonical origin: the point of the line nearest the moving part's OBB centre
        assert abs((g.obb_center[i] - out.axis_origin[k]) @ out.axis_direction[k]) < 1e-9
        assert 0 <= out.confidence[k] <= 1 and 0 <= out.feasibility[k] <= 1
    assert out.kind[door] == "edge" and out.kind[drawer] == "axis"
    assert out.n_candidates[door] == 4 and out.n_candidates[drawer] == 2
    # non-moving edges keep the GNN's axes and have no confidence
    rest = ~out.refined
    np.testing.assert_array_equal(out.axis_direction[rest], pred["direction"][rest])
    assert np.all(np.isnan(out.confidence[rest]))
    assert out.types[door] == "R_V_S"
    js = out.to_json()["edges"]
    assert [r["edge"] for r in js] == sorted([door, drawer, knob])


def test_network_score_counts_and_results_are_reproducible(model):
    g = box_cabinet(128)
    pred = _gnn_like(g, noise=0.03)
    a = refine_predictions(g, pred, model)
    b = refine_predictions(g, pred, model)
    np.testing.assert_array_equal(a.axis_origin, b.axis_origin)
    np.testing.assert_array_equal(a.confidence, b.confidence)
    door = edge_index(g, 2, 1)
    sc = a.details[door].scores
    np.testing.assert_allclose(sc.total, 0.5 * sc.feasibility + 0.3 * sc.direction
                               + 0.2 * sc.position)
    only = refine_predictions(g, pred, model,
                              RefineConfig(scoring=ScoringConfig(feasibility_only=True)))
    assert only.confidence[door] == pytest.approx(only.details[door].scores.feasibility.max())


def test_coarse_predictions_use_all_orientations_and_pivots(model):
    g = box_cabinet(128)
    pred = _gnn_like(g, coarse=True)
    out = refine_predictions(g, pred, model, RefineConfig(scoring=ScoringConfig(w_feasibility=0)))
    door = edge_index(g, 2, 1)
    assert out.type_names[out.type_index[door]] == "R"
    assert out.n_candidates[door] == 12 + 3 + 3 - 0  # edges, centre and interaction lines
    assert np.linalg.norm(np.cross(out.axis_origin[door] - g.edge_axis_origin[door],
                                   g.edge_axis_direction[door])) < 1e-9
    assert COARSE_INDEX["R"] == out.type_index[door]


def test_only_and_input_adapters(model):
    from kinmo.mobility_tree import EdgePrediction

    g = box_cabinet(64)
    p = _gnn_like(g)
    door = edge_index(g, 2, 1)
    ep = EdgePrediction(p["probs"], p["direction"], p["origin"])
    out = refine_predictions(g, ep, model, only=[door])
    np.testing.assert_array_equal(np.flatnonzero(out.refined), [door])
    ours = as_edge_predictions(ep, g)
    assert isinstance(ours, EdgePredictions) and ours.type_names == FINE_TYPES
    np.testing.assert_array_equal(ours.edges, g.sibling_edges)
    assert ours.types[door] == "R_V_S" and ours.type_index[door] == FINE_INDEX["R_V_S"]
    with pytest.raises(ValueError, match="type_prob"):
        as_edge_predictions({"direction": p["direction"], "origin": p["origin"]}, g)
    with pytest.raises(ValueError, match="type_prob"):
        EdgePredictions(g.sibling_edges, p["probs"][:, :7], p["direction"], p["origin"])
    with pytest.raises(ValueError, match="out of range"):
        refine_predictions(g, {**p, "edges": g.sibling_edges + 10}, model)


def test_shape_prediction_refinement_and_the_four_settings(model, tmp_path):
    from kinmo.features import SemanticVocab
    from kinmo.mobility_tree import EdgePrediction, build_mobility_tree
    from kinmo.models.motion_gnn import MotionGNN
    from kinmo.predict import ShapePrediction
    from kinmo.refine.refine import refine_shape_prediction
    from kinmo.evaluate.settings import four_settings
    from kinmo.train.config import preset
    from kinmo.train.gnn import load_run, save_checkpoint

    g = box_cabinet(128)
    p = _gnn_like(g, noise=0.003)
    ep = EdgePrediction(p["probs"], p["direction"], p["origin"])
    sp = ShapePrediction(g, ep, build_mobility_tree(g, ep), FINE_TYPES)
    cfg = RefineConfig(scoring=ScoringConfig(w_feasibility=0.0))
    new, details = refine_shape_prediction(sp, model, cfg)
    assert new.type_names == FINE_TYPES and new.graph is g
    np.testing.assert_array_equal(new.edges.probs, ep.probs)
    assert len(new.tree.moving_links) == 3
    door = next(lk for lk in new.tree.links if 2 in lk.parts)
    # the door's joint sits exactly on the hinge edge after refinement
    true_o, true_d = g.edge_axis_origin[edge_index(g, 2, 1)], np.array([0.0, 1.0, 0.0])
    assert np.linalg.norm(np.cross(door.joint.origin - true_o, true_d)) < 1e-9
    assert details.refined.sum() == 3

    runs = []
    for types in ("fine", "coarse"):
        torch.manual_seed(0)
        c = preset("quick", types=types)
        save_checkpoint(tmp_path / types / "model.pt", MotionGNN(c.model), c, SemanticVocab(),
                        None, 0)
        runs.append(load_run(tmp_path / types, "cpu"))
    graphs = [box_cabinet(128, seed=s, jitter=0.1, shape_id=f"t{s}") for s in range(2)]
    rep = four_settings(graphs, runs[0], runs[1], model)
    assert rep.models == ["GNN_coarse", "GNN_fine", "OBB_coarse", "OBB_fine"]
    for kind in ("coarse", "fine"):
        gnn, obb = rep.table[(f"GNN_{kind}", "mean")], rep.table[(f"OBB_{kind}", "mean")]
        assert gnn["edge_acc"] == obb["edge_acc"]  # the refinement keeps the types
        assert gnn["n_shapes"] == obb["n_shapes"] == 2


def test_abstention_keeps_the_gnn_axis_when_no_candidate_agrees(model):
    g = box_cabinet(128)
    p = _gnn_like(g)
    drawer = edge_index(g, 3, 1)
    p["direction"][drawer] = [0.0, 1.0, 0.0]  # a vertical axis for a P_H drawer
    cfg = RefineConfig(min_agreement=np.cos(np.radians(45)))
    out = refine_predictions(g, p, model, cfg)
    assert out.kind[drawer] == "gnn" and out.details[drawer].abstained
    np.testing.assert_allclose(out.axis_direction[drawer], [0, 1, 0])
    np.testing.assert_allclose(out.axis_origin[drawer], p["origin"][drawer])
    paper = refine_predictions(g, p, model)  # without: a horizontal OBB axis, 90 deg away
    assert abs(paper.axis_direction[drawer][1]) < 1e-9 and paper.kind[drawer] == "axis"
    door = edge_index(g, 2, 1)
    assert out.kind[door] == "edge" and not out.details[door].abstained


def test_snap_angle_restricts_candidates_to_the_gnn_orientation(model):
    g = box_cabinet(128)
    p = _gnn_like(g, coarse=True)  # coarse R: every orientation and pivot kind competes
    door, drawer = edge_index(g, 2, 1), edge_index(g, 3, 1)
    free = refine_predictions(g, p, model)
    snap = refine_predictions(g, p, model, RefineConfig(snap_angle_deg=10.0))
    # the door's GNN axis is vertical: 4 vertical edges + centre + interaction line remain
    assert free.n_candidates[door] == 18 and snap.n_candidates[door] == 6
    assert abs(snap.axis_direction[door] @ [0.0, 1.0, 0.0]) == pytest.approx(1.0)
    # a P_H drawer whose GNN axis is vertical has no horizontal candidate within 10 deg:
    # the refinement abstains, keeps the GNN's axis and gives no confidence
    f = _gnn_like(g)
    f["direction"][drawer] = [0.0, 1.0, 0.0]
    out = refine_predictions(g, f, model, RefineConfig(snap_angle_deg=10.0))
    assert out.kind[drawer] == "gnn" and out.details[drawer].abstained
    assert out.n_candidates[drawer] == 0 and np.isnan(out.confidence[drawer])
    np.testing.assert_allclose(out.axis_direction[drawer], [0, 1, 0])
    np.testing.assert_allclose(out.axis_origin[drawer], f["origin"][drawer])
    assert out.to_json()["edges"]  # serialisable with an empty candidate set
    with pytest.raises(ValueError):
        RefineConfig(snap_angle_deg=0.0)


def test_keep_gnn_adds_the_gnn_line_as_a_candidate(model):
    g = box_cabinet(128)
    p = _gnn_like(g, noise=0.03)
    door = edge_index(g, 2, 1)
    base = refine_predictions(g, p, model)
    kept = refine_predictions(g, p, model, RefineConfig(keep_gnn=True))
    assert kept.n_candidates[door] == base.n_candidates[door] + 1
    r = kept.details[door]
    assert r.candidates.kinds[-1] == "gnn"
    # the GNN's line agrees with itself exactly; the other candidates keep their scores
    assert r.scores.direction[-1] == pytest.approx(1.0) and r.scores.position[-1] == pytest.approx(1.0)
    np.testing.assert_allclose(r.scores.direction[:-1], base.details[door].scores.direction)
    # without the network's vote the noisy GNN line beats every snapped candidate
    agree = refine_predictions(g, p, model, RefineConfig(keep_gnn=True,
                                                         scoring=ScoringConfig(w_feasibility=0.0)))
    assert agree.kind[door] == "gnn" and not agree.details[door].abstained
    # its confidence stays that of the best geometric candidate (self-agreement is no evidence)
    sc = agree.details[door].scores
    assert sc.total[-1] == pytest.approx(1.0) and sc.best == len(sc.total) - 1
    assert agree.confidence[door] == pytest.approx(sc.total[:-1].max())
    assert agree.confidence[door] < 1.0
    d = p["direction"][door] / np.linalg.norm(p["direction"][door])
    assert abs(agree.axis_direction[door] @ d) == pytest.approx(1.0)
    assert np.linalg.norm(np.cross(agree.axis_origin[door] - p["origin"][door], d)) < 1e-9


def test_box_frames_add_candidates_from_other_frames(model):
    g = box_cabinet(128)
    p = _gnn_like(g, noise=0.01)
    door = edge_index(g, 2, 1)
    base = refine_predictions(g, p, model)
    # the cabinet is axis-aligned: the other frames' boxes repeat the OBB's lines (merged)
    same = refine_predictions(g, p, model, RefineConfig(box_frames=("moving", "reference", "shape")))
    assert same.n_candidates[door] == base.n_candidates[door]
    np.testing.assert_allclose(same.axis_direction, base.axis_direction)
    # rotate the door's OBB axes 40 deg about z: its own vertical edges are gone, the
    # reference (body) frame brings the hinge back
    r = np.radians(40)
    rz = np.array([[np.cos(r), -np.sin(r), 0], [np.sin(r), np.cos(r), 0], [0, 0, 1]])
    g.obb_axes[2] = (rz @ g.obb_axes[2].T).T
    tilted = refine_predictions(g, p, model, RefineConfig(scoring=ScoringConfig(w_feasibility=0.0)))
    both = refine_predictions(g, p, model, RefineConfig(box_frames=("moving", "reference"),
                                                        scoring=ScoringConfig(w_feasibility=0.0)))
    assert abs(tilted.axis_direction[door] @ [0.0, 1.0, 0.0]) < np.cos(np.radians(30))
    assert abs(both.axis_direction[door] @ [0.0, 1.0, 0.0]) == pytest.approx(1.0)
    hinge = np.array([-0.5, 0.0, 0.3])
    assert np.linalg.norm(np.cross(both.axis_origin[door] - hinge, [0.0, 1.0, 0.0])) < 0.03
    with pytest.raises(ValueError):
        RefineConfig(box_frames=())
    with pytest.raises(ValueError):
        RefineConfig(box_frames=("world",))
