"""One predictor, one model bundle (issue 22): a bundle folder written by ``kinmo train all``
is read back whole, a ranker beside ``--axis-model`` is found (the learned selector is the
default), the paper's selector stays a switch, and a missing mesh is never silent."""

from __future__ import annotations

import json
import logging
from pathlib import Path

import numpy as np
import pytest
from conftest import write_untrained_models

from kinmo.errors import KinmoDataError
from kinmo.inference.bundle import find_ranker, read_bundle, resolve_bundle, write_bundle
from kinmo.inference.predictor import Predictor
from kinmo.mobility_tree import ShapePrediction
from kinmo.refine.axis_io import load_axis_models
from kinmo.refine.selector import FEATURES
from kinmo.refine.ranker import Ranker


@pytest.fixture(scope="module")
def runs(tmp_path_factory) -> Path:
    """``runs/all``-like folder: gnn_fine/, axis/, ranker/ranker.json (untrained networks)."""
    root = tmp_path_factory.mktemp("all")
    write_untrained_models(root, "gnn_fine")
    n = len(FEATURES)
    (root / "ranker").mkdir()
    Ranker(FEATURES, np.linspace(-1, 1, n), np.zeros(n), np.ones(n)).save(root / "ranker" / "ranker.json")
    return root


def test_a_bundle_is_read_back_whole(runs, tmp_path) -> None:
    b = write_bundle(tmp_path / "model", runs / "gnn_fine", runs / "axis", runs / "ranker" / "ranker.json",
                     ["b", "a"])
    doc = json.loads((tmp_path / "model" / "bundle.json").read_text())
    assert doc["selector"] == "ranker" and doc["trained_on"] == ["a", "b"]
    assert b == read_bundle(tmp_path / "model") and b.has_axis_network
    assert b.gnn == tmp_path / "model" / "gnn" and b.ranker == tmp_path / "model" / "ranker.json"
    assert resolve_bundle(tmp_path / "model") == b
    p = Predictor.from_bundle(tmp_path / "model", device="cpu")
    assert p.selector == "ranker" and "learned selector" in p.describe()
    paper = Predictor.from_bundle(tmp_path / "model", device="cpu", selector="paper")
    assert paper.selector == "paper" and paper.axis_net is not None
    assert "paper selector" in paper.describe()


def test_a_bundle_naming_a_path_outside_is_refused(runs, tmp_path) -> None:
    write_bundle(tmp_path / "model", runs / "gnn_fine")
    f = tmp_path / "model" / "bundle.json"
    doc = json.loads(f.read_text())
    assert doc["selector"] == "none" and doc["axis"] is None
    f.write_text(json.dumps({**doc, "gnn": "../../etc"}))
    with pytest.raises(KinmoDataError, match="must name an entry"):
        read_bundle(tmp_path / "model")


def test_a_bundle_takes_the_axis_networks_its_run_uses(runs, tmp_path) -> None:
    """Only model.pt, config.json, categories.json and the networks it lists are copied: not
    the last epoch, nor a per-category file an earlier run left in the same folder."""
    import shutil

    axis = tmp_path / "axis"
    shutil.copytree(runs / "axis", axis)
    (axis / "categories").mkdir(exist_ok=True)
    shutil.copy2(axis / "model.pt", axis / "categories" / "Box.pt")
    shutil.copy2(axis / "model.pt", axis / "categories" / "Stale.pt")
    shutil.copy2(axis / "model.pt", axis / "last.pt")
    (axis / "categories.json").write_text(json.dumps(
        {"categories": {"Box": {"file": "categories/Box.pt"}}}))
    b = write_bundle(tmp_path / "model", runs / "gnn_fine", axis)
    got = sorted(str(f.relative_to(b.axis)) for f in b.axis.rglob("*") if f.is_file())
    assert "categories/Box.pt" in got and "model.pt" in got and "categories.json" in got
    assert "categories/Stale.pt" not in got and "last.pt" not in got
    assert set(load_axis_models(b.axis).categories) == {"Box"}
    # the index is read from a file: a name that leaves categories/ is refused, never opened
    for bad in ("../model.pt", "categories/../../x.pt", "/etc/x.pt", "categories/sub/x.pt"):
        (axis / "categories.json").write_text(json.dumps({"categories": {"Box": {"file": bad}}}))
        with pytest.raises(KinmoDataError, match="categories/<name>.pt"):
            load_axis_models(axis)
        with pytest.raises(KinmoDataError, match="categories/<name>.pt"):
            write_bundle(tmp_path / "bad", runs / "gnn_fine", axis)
    # a listed network that is missing is one clear error
    (axis / "categories.json").write_text(json.dumps(
        {"categories": {"Pen": {"file": "categories/Pen.pt"}}}))
    with pytest.raises(KinmoDataError, match="missing"):
        write_bundle(tmp_path / "bad", runs / "gnn_fine", axis)


def test_the_ranker_beside_the_axis_model_is_found(runs) -> None:
    # `--axis-model runs/all/axis` no longer silently picks the paper selector
    assert find_ranker(runs / "axis") == runs / "ranker" / "ranker.json"
    b = resolve_bundle(runs / "gnn_fine", runs / "axis")
    assert b.ranker == runs / "ranker" / "ranker.json" and b.axis == runs / "axis"
    assert Predictor.from_bundle(runs / "gnn_fine", "cpu", axis_model=runs / "axis").selector == "ranker"
    assert Predictor.from_bundle(runs / "gnn_fine", "cpu").selector == "none"


def test_predict_refines_and_a_missing_mesh_is_logged(runs, graph, caplog) -> None:
    p = Predictor.from_bundle(runs / "gnn_fine", "cpu", axis_model=runs / "axis")
    g = graph
    g.meta["source"] = "/nonexistent/shape"  # the meshes cannot be read
    with caplog.at_level(logging.WARNING):
        pred = p.predict(g)
    assert isinstance(pred, ShapePrediction) and pred.edges.direction.shape == (len(g.sibling_edges), 3)
    caplog.clear()
    with caplog.at_level(logging.WARNING):
        assert p._meshes(g, None) is None  # what a refinement of a moving edge gets
    assert any("no meshes" in r.getMessage() and g.shape_id in r.getMessage() for r in caplog.records)
    # meshes the caller has are used as given
    sentinel = object()
    assert p._meshes(g, lambda _: sentinel) is sentinel
    # the GNN's own prediction is what `none` gives
    plain = Predictor.from_bundle(runs / "gnn_fine", "cpu").predict(g)
    assert plain.edges.probs.shape == pred.edges.probs.shape
