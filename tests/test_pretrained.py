"""The pretrained model bundle shipped in the package (issue 22 part 3): what a fresh clone
gets after the README's set-up command, with no training run and no --model."""

from __future__ import annotations

import json

from typer.testing import CliRunner

from kinmo.cli import app
from kinmo.data.readers import read_shape
from kinmo.inference.bundle import read_bundle
from kinmo.pretrained import DEFAULT_MODEL, PRETRAINED_DIR, default_model, installed_models, is_pretrained


def test_the_default_bundle_is_installed_with_its_license_and_training_ids():
    path = default_model()
    assert path == PRETRAINED_DIR / DEFAULT_MODEL and is_pretrained(path / "gnn")
    b = read_bundle(path)
    assert b.has_axis_network and b.ranker is not None  # the learned selector by default
    # the coarse GNN that pseudo-labelling requires to agree (issue 34)
    assert b.check is not None and json.loads((b.check / "config.json").read_text())["model"]["types"] == "coarse"
    assert len(b.trained_on) >= 200  # every labelled shared object plus kept pseudo-labels
    lic = (path / "LICENSE").read_text()
    assert "non-commercial" in lic.splitlines()[0]
    size = sum(p.stat().st_size for p in path.rglob("*") if p.is_file())
    assert size < 8e6  # a few MB inside the wheel
    [m] = [m for m in installed_models() if m.name == DEFAULT_MODEL]
    assert m.n_trained_on == len(b.trained_on) and m.selector == "ranker"


def test_kinmo_models_lists_the_default_bundle():
    r = CliRunner().invoke(app, ["models"])
    assert r.exit_code == 0, r.output
    assert DEFAULT_MODEL in r.output and "non-commercial" in r.output


def test_predict_on_a_glb_needs_no_training_and_no_model(tmp_path):
    runner = CliRunner()
    # the README's quick start: a generated cabinet exported as a GLB scene (a node per link)
    r = runner.invoke(app, ["synth", str(tmp_path / "objs"), "--n", "1", "--seed", "0",
                            "--categories", "StorageFurniture", "-q"])
    assert r.exit_code == 0, r.output
    [obj] = [p for p in (tmp_path / "objs").iterdir() if p.is_dir()]
    r = runner.invoke(app, ["export", str(obj), "--format", "gltf", "--out", str(tmp_path / "asset")])
    assert r.exit_code == 0, r.output
    glb = tmp_path / "asset" / "mobility.glb"  # one object: OUT/mobility.glb
    r = runner.invoke(app, ["predict", str(glb), "--out", str(tmp_path / "pred"), "--device", "cpu", "-q"])
    assert r.exit_code == 0, r.output
    out = " ".join(r.output.split())
    assert f"pretrained model {DEFAULT_MODEL}" in out and "non-commercial" in out
    final = tmp_path / "pred" / "mobility"
    for name in ("mobility_v2.json", "mobility.urdf", "view.html", "frame.json"):
        assert (final / name).is_file(), name
    shape = read_shape(final)
    assert any(link.joint.direction is not None for link in shape.links), "no moving joint predicted"
    assert json.loads((final / "frame.json").read_text())["up"] == "y"  # glTF: y-up by its spec


def test_pseudo_label_needs_no_model_and_writes_convex_collision(tmp_path):
    runner = CliRunner()
    r = runner.invoke(app, ["synth", str(tmp_path / "pn"), "--n", "2", "--seed", "1", "--partnet",
                            "--categories", "StorageFurniture", "-q"])
    assert r.exit_code == 0, r.output
    r = runner.invoke(app, ["pseudo-label", str(tmp_path / "pn"), "-o", str(tmp_path / "out"),
                            "-t", "0", "-q"])
    assert r.exit_code == 0, r.output
    assert f"pretrained model {DEFAULT_MODEL}" in " ".join(r.output.split())
    kept = [p for p in (tmp_path / "out").iterdir() if (p / "mobility.urdf").is_file()]
    assert kept, r.output
    for obj in kept:  # the bundle's check/ model agreed on every kept joint
        scores = json.loads((obj / "scores.json").read_text())
        assert scores["models"]["check"] and all(j["check_agrees"] is True for j in scores["joints"])
    for obj in kept:  # the default collision: at least one convex piece per leaf mesh
        shape = read_shape(obj)
        n_leaves = sum(len(shape.hierarchy.mesh_names(pid)) for l in shape.links for pid in l.parts)
        assert len(list((obj / "collision").glob("link_*_*.obj"))) >= n_leaves
