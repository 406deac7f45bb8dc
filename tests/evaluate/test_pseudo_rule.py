"""The pseudo-label rule graded on labelled objects (kinmo.evaluate.pseudo_rule, issue 34)."""

from __future__ import annotations

import json

import numpy as np
import pytest
import torch
from conftest import write_untrained_models
from motion_cabinet import cabinet_graph, oracle_prediction

from kinmo.data.model import FINE_INDEX
from kinmo.evaluate.pseudo_rule import grade_pseudo_rule, write_pseudo_rule
from kinmo.inference.predictor import Predictor
from kinmo.pseudo_label import PseudoLabelConfig
from kinmo.refine.config import RefineConfig

torch.set_num_threads(1)


@pytest.fixture(scope="module")
def predictor(tmp_path_factory) -> Predictor:
    gnn, axis = write_untrained_models(tmp_path_factory.mktemp("runs"))
    return Predictor.from_parts(gnn, axis, RefineConfig(), device="cpu")


def _graphs():
    return [cabinet_graph(n_points=64, seed=s, jitter=0.1, shape_id=f"cab{s}") for s in range(3)]


def _gnn(monkeypatch, door_as_slider: bool = False):
    """The GNN answers with the truth, or with the door (a hinge) as a horizontal slider."""
    import kinmo.inference.gnn
    from kinmo.mobility_tree import EdgePrediction
    from kinmo.refine.selector import GNNPriors

    def fake(run, graphs, batch_size=8, turns="unnamed"):
        out = []
        for g in graphs:
            e = oracle_prediction(g)
            if door_as_slider:
                p = e.probs.copy()
                hinge = np.asarray(g.edge_fine) == FINE_INDEX["R_V_S"]
                p[hinge] = 0.0
                p[hinge, FINE_INDEX["P_H"]] = 1.0
                e = EdgePrediction(p, e.direction, e.origin)
            out.append(e)
        names = tuple(run.config.model.type_names)
        return out, [GNNPriors(e.probs.copy(), names) for e in out]

    monkeypatch.setattr(kinmo.inference.gnn, "infer_edges_with_priors", fake)


def test_right_answers_grade_right_and_a_wrong_type_is_counted(predictor, monkeypatch):
    _gnn(monkeypatch)
    cfg = PseudoLabelConfig(threshold=0.0, refine=RefineConfig())
    rep = grade_pseudo_rule(predictor, _graphs(), cfg)
    s = rep.summary()
    # each cabinet: a door (hinge) and a drawer (slider), and nothing else moves
    assert rep.n_objects == 3 and sorted(rep.kept) == ["cab0", "cab1", "cab2"]
    assert s["joints"] == 6 and s["joint_precision"] == 1.0
    assert s["type_acc"] == 1.0 and s["fine_type_acc"] == 1.0
    assert 0.0 <= s["axis_mean_deg"] <= 90.0
    # per link: the door and the drawer of each cabinet, matched to the true links
    assert s["links"] == 6 and s["link_precision"] == 1.0 and s["link_type_acc"] == 1.0
    assert 0.0 <= s["link_axis_mean_deg"] <= 90.0
    _gnn(monkeypatch, door_as_slider=True)
    wrong = grade_pseudo_rule(predictor, _graphs(), cfg).summary()
    assert wrong["joint_precision"] == 1.0 and wrong["type_acc"] == pytest.approx(0.5)
    assert wrong["link_precision"] == 1.0 and wrong["link_type_acc"] == pytest.approx(0.5)


def test_a_rule_that_keeps_nothing_writes_null_not_nan(predictor, monkeypatch, tmp_path):
    _gnn(monkeypatch)
    rep = grade_pseudo_rule(predictor, _graphs(), PseudoLabelConfig(threshold=1.0, refine=RefineConfig()))
    assert rep.kept == [] and len(rep.joints) == 6 and not any(j.kept for j in rep.joints)
    doc = write_pseudo_rule(rep, tmp_path)
    text = (tmp_path / "summary.json").read_text()
    assert "NaN" not in text and json.loads(text) == doc
    assert doc["all"]["kept"] == 0 and doc["all"]["type_acc"] is None
    md = (tmp_path / "summary.md").read_text()
    assert "| **all** | 3 | 0 | – |" in md and "link precision" in md
    assert len(rep.links) == 6 and doc["all"]["links"] == 0 and doc["all"]["link_precision"] is None


def test_reports_of_batches_extend_into_the_report_of_all(predictor, monkeypatch):
    _gnn(monkeypatch)
    cfg = PseudoLabelConfig(threshold=0.0, refine=RefineConfig())
    graphs = _graphs()
    whole = grade_pseudo_rule(predictor, graphs, cfg)
    parts = grade_pseudo_rule(predictor, graphs[:1], cfg)
    parts.extend(grade_pseudo_rule(predictor, graphs[1:], cfg))
    assert parts.n_objects == whole.n_objects == 3
    assert parts.kept == whole.kept and parts.joints == whole.joints and parts.links == whole.links
    assert parts.summary() == whole.summary()
    other = grade_pseudo_rule(predictor, graphs[:1], PseudoLabelConfig(threshold=0.5, refine=RefineConfig()))
    with pytest.raises(ValueError, match="threshold 0.5"):
        parts.extend(other)
    assert parts.n_objects == 3  # a refused report adds nothing


def test_the_summary_line_reads_a_summary_and_its_json_alike(predictor, monkeypatch, tmp_path):
    from kinmo.evaluate.pseudo_rule import summary_line

    _gnn(monkeypatch)
    rep = grade_pseudo_rule(predictor, _graphs(), PseudoLabelConfig(threshold=1.0, refine=RefineConfig()))
    doc = write_pseudo_rule(rep, tmp_path)
    line = summary_line(rep.summary())  # NaN where nothing is kept
    assert line == summary_line(doc["all"])  # null in the JSON
    assert line == "0 kept, joint precision –, type accuracy – (fine –), axis error –°; per link –, –, –°"
    _gnn(monkeypatch)
    kept = grade_pseudo_rule(predictor, _graphs(), PseudoLabelConfig(threshold=0.0, refine=RefineConfig()))
    assert summary_line(kept.summary()).startswith("3 kept, joint precision 1.000, type accuracy 1.000 (fine 1.000)")
