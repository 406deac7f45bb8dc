"""End to end on real objects: train a tiny motion GNN, predict, write PartNet-Mobility files
and URDFs, evaluate; and the URDF of a predicted tree moves the right links about the right axes."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pybullet as p
import pytest
import torch
from PIL import Image
from scipy.spatial.transform import Rotation
from typer.testing import CliRunner

from kinmo.cli import app
from kinmo.data.build import build_graph
from kinmo.data.model import FINE_TYPES, JointType
from kinmo.data.readers import read_links, read_shape
from kinmo.geometry import load_obj
from kinmo.mobility_tree import build_mobility_tree
from kinmo.predict import ShapePrediction, predict_dataset, write_prediction
from kinmo.train.config import preset
from kinmo.train.gnn import train_gnn
from kinmo.train.split import Split
from motion_cabinet import oracle_prediction

torch.set_num_threads(1)

# refrigerator (hinge door, nested hierarchy), safe (door + 2 knobs), box (4 flaps),
# stapler, laptop, kitchen pot (sliding lid)
OBJECTS = ["10849", "101593", "100154", "103100", "11405", "100028"]


def tiny(**over):
    over = {"batch_size": 3, **over}
    cfg = preset("quick", n_points=32, threads=1, lr=5e-3, **over)
    small = cfg.model.model_copy(update=dict(point_widths=[16], geo_dim=16, node_dim=24, edge_dim=24,
                                             semantic_dim=4, gnn_layers=2))
    return cfg.model_copy(update={"model": small})


@pytest.fixture(scope="module")
def real(mobility_root: Path, tmp_path_factory):
    root = tmp_path_factory.mktemp("motion")
    data, cache = root / "data", root / "cache"
    data.mkdir()
    cache.mkdir()
    for oid in OBJECTS:
        (data / oid).symlink_to(mobility_root / oid)
        build_graph(read_shape(data / oid), n_points=64).save(cache / f"{oid}.npz")
    res = train_gnn(cache, root / "run", tiny(epochs=25, batch_size=2), split=Split(OBJECTS, []),
                    progress=False)
    return {"root": root, "data": data, "cache": cache, "run": root / "run", "result": res}


@pytest.fixture(scope="module")
def bullet():
    cid = p.connect(p.DIRECT)
    yield cid
    p.disconnect(cid)


@pytest.mark.exactdata
def test_training_on_real_objects_lowers_the_loss(real):
    h = real["result"].history
    assert len(h) == 25
    assert h[-1]["loss"] < 0.6 * h[0]["loss"]
    assert h[-1]["train_acc"] > h[0]["train_acc"]


@pytest.mark.exactdata
def test_predict_writes_well_formed_outputs(real):
    out = real["root"] / "out"
    rows = predict_dataset(real["data"], real["run"], out, cache=real["cache"], device="cpu",
                           progress=False, render=True)
    assert [r.status for r in rows] == ["ok"] * len(OBJECTS)
    assert sorted(r.id for r in rows) == sorted(OBJECTS)
    summary = (out / "predictions.csv").read_text().splitlines()
    assert summary[0] == "id,status,n_links,n_moving,error" and len(summary) == len(OBJECTS) + 1
    for r in rows:
        shape = read_shape(real["data"] / r.id)
        links = read_links(out / r.id / "mobility_v2.json", shape.hierarchy)  # validates ids, tree
        assert len(links) == r.n_links
        assert sum(lk.joint.type in (JointType.HINGE, JointType.SLIDER) for lk in links) == r.n_moving
        roots = [lk for lk in links if lk.parent == -1]
        assert len(roots) == 1 and roots[0].joint.type is JointType.FREE
        # every leaf of the hierarchy is in exactly one link
        leaves = [n for n in shape.hierarchy.order if shape.hierarchy.nodes[n].is_leaf]
        owned = [leaf for lk in links for part in lk.parts for leaf in shape.hierarchy.leaves(part)]
        assert sorted(owned) == sorted(leaves)
        edges = json.loads((out / r.id / "edges.json").read_text())
        g = build_graph(shape, n_points=8)
        assert len(edges["edges"]) == len(g.sibling_edges) and edges["types"] == list(FINE_TYPES)
        for e in edges["edges"]:
            assert sum(e["probs"].values()) == pytest.approx(1.0, abs=1e-4)
            assert np.linalg.norm(e["axis"]["direction"]) == pytest.approx(1.0, abs=1e-4)
            assert e["type"] == max(e["probs"], key=e["probs"].get)
        sem = (out / r.id / "semantics.txt").read_text().split("\n")
        assert len([s for s in sem if s]) == len(links)
        assert (out / r.id / "mobility.urdf").is_file()
        with Image.open(out / r.id / "prediction.png") as im:
            assert im.size[0] > 300 and im.size[1] > 300
    # without a cache the graph is built from the folder
    rows = predict_dataset(real["data"] / "100028", real["run"], real["root"] / "out2",
                           device="cpu", progress=False)
    assert rows[0].status == "ok" and (real["root"] / "out2" / "100028" / "mobility_v2.json").is_file()


def _world_vertices(body, cid, link_index, verts):
    st = p.getLinkState(body, link_index, computeForwardKinematics=True, physicsClientId=cid)
    rot = np.array(p.getMatrixFromQuaternion(st[5])).reshape(3, 3)
    out = []
    for vis in p.getVisualShapeData(body, physicsClientId=cid):
        if vis[1] == link_index:
            rv = np.array(p.getMatrixFromQuaternion(vis[6])).reshape(3, 3)
            out.append((verts @ rv.T + np.array(vis[5])) @ rot.T + np.array(st[4]))
    return out


@pytest.mark.exactdata
@pytest.mark.parametrize("oid", ["10849", "101593", "100028"])
def test_urdf_of_a_predicted_tree_moves_the_right_links(mobility_root, tmp_path, bullet, oid):
    shape = read_shape(mobility_root / oid)
    g = build_graph(shape, n_points=16)
    pred = oracle_prediction(g)
    tree = build_mobility_tree(g, pred)
    paths = write_prediction(ShapePrediction(g, pred, tree, FINE_TYPES), tmp_path / oid, shape)
    body = p.loadURDF(str(paths["urdf"]), useFixedBase=True, physicsClientId=bullet)
    try:
        infos = [p.getJointInfo(body, k, physicsClientId=bullet)
                 for k in range(p.getNumJoints(body, physicsClientId=bullet))]
        by_child = {i[12].decode(): i for i in infos}
        moving = tree.moving_links
        assert moving and sum(i[2] != p.JOINT_FIXED for i in infos) == len(moving)
        for lk in moving:
            info = by_child[f"link_{lk.id}"]
            names = [m for part in lk.parts for m in shape.hierarchy.mesh_names(part)]
            verts = np.concatenate([load_obj(shape.mesh_path(n))[0] for n in names])[::5][:150]
            o, d = np.asarray(lk.joint.origin), np.asarray(lk.joint.direction)
            q = 0.6 if lk.joint.type is JointType.HINGE else 0.04
            p.resetJointState(body, info[0], q, physicsClientId=bullet)
            if lk.joint.type is JointType.HINGE:
                assert info[2] == p.JOINT_REVOLUTE
                expect = (verts - o) @ Rotation.from_rotvec(q * d).as_matrix().T + o
            else:
                assert info[2] == p.JOINT_PRISMATIC
                expect = verts + q * d
            for got in _world_vertices(body, bullet, info[0], verts):
                assert np.abs(got - expect).max() < 1e-5
            # the moved vertices really moved, and the other links did not
            assert np.abs(expect - verts).max() > 1e-3
            for other in tree.links:
                if other.id != lk.id and other.parent != lk.id and f"link_{other.id}" in by_child:
                    oi = by_child[f"link_{other.id}"][0]
                    onames = [m for part in other.parts for m in shape.hierarchy.mesh_names(part)][:1]
                    if onames and other.parent == 0 and by_child[f"link_{other.id}"][2] == p.JOINT_FIXED:
                        ov = load_obj(shape.mesh_path(onames[0]))[0][:20]
                        assert np.abs(_world_vertices(body, bullet, oi, ov)[0] - ov).max() < 1e-6
            p.resetJointState(body, info[0], 0.0, physicsClientId=bullet)
        # the refrigerator's door: the predicted hinge opens outwards (+z is the front)
        if oid == "10849":
            door = moving[0]
            c = g.obb_center[tree.link_nodes[door.id][0]]
            o, d = np.asarray(door.joint.origin), np.asarray(door.joint.direction)
            r = (c - o) - np.dot(c - o, d) * d
            away = c - g.obb_center[np.flatnonzero(g.parent == g.parent[tree.link_nodes[door.id][0]])].mean(0)
            assert np.dot(np.cross(d, r), away) > 0
    finally:
        p.removeBody(body, physicsClientId=bullet)


@pytest.mark.exactdata
def test_evaluation_and_cli(real):
    from kinmo.evaluate.pre_segmented import METRICS, run_evaluation

    report, paths = run_evaluation([real["run"]], real["cache"], out=real["root"] / "eval",
                                   all_shapes=True, device="cpu", progress=False)
    assert report.models == ["GNN_fine"]
    mean = report.table[("GNN_fine", "mean")]
    assert mean["n_shapes"] == len(OBJECTS)
    for key, _, higher in METRICS:
        v = mean[key]
        if higher:
            assert np.isnan(v) or 0.0 <= v <= 1.0
        else:
            assert np.isnan(v) or v >= 0.0
    md = paths["markdown"].read_text()
    assert "| **mean** |" in md and "GNN_fine" in md and "8.93" in md
    assert paths["csv"].read_text().startswith("model,category,n_shapes,n_joints,edge_acc")

    runner = CliRunner()
    run2 = real["root"] / "cli-run"
    r = runner.invoke(app, ["train", "gnn", "--data", str(real["cache"]), "--out", str(run2),
                            "--types", "coarse", "--epochs", "1", "--quiet", "--device", "cpu"])
    assert r.exit_code == 0, r.output
    assert json.loads((run2 / "config.json").read_text())["model"]["types"] == "coarse"
    r = runner.invoke(app, ["eval", "pre-segmented", "--model", str(real["run"]), "--model", str(run2),
                            "--data", str(real["cache"]), "--all", "--quiet", "--device", "cpu",
                            "--out", str(real["root"] / "eval2"), "--render"])
    assert r.exit_code == 0, r.output
    assert "GNN_coarse" in (real["root"] / "eval2" / "table1.md").read_text()
    assert len(list((real["root"] / "eval2" / "renders" / "GNN_coarse").glob("*.png"))) == len(OBJECTS)
    r = runner.invoke(app, ["predict", str(real["data"] / "100028"), "--model", str(run2),
                            "--out", str(real["root"] / "cli-out"), "--cache", str(real["cache"]),
                            "--quiet", "--device", "cpu"])
    assert r.exit_code == 0, r.output
    assert (real["root"] / "cli-out" / "100028" / "mobility.urdf").is_file()
    r = runner.invoke(app, ["train", "gnn", "--data", str(real["root"] / "missing"), "--out",
                            str(real["root"] / "x"), "--quiet"])
    assert r.exit_code == 1 and "does not" in r.output and "kinmo prepare" in r.output


@pytest.mark.exactdata
def test_outputs_never_overwrite_the_inputs(real, tmp_path):
    """Finding 2 of the hostile-input issue: `kinmo predict DIR -o DIR` replaced the ground
    truth (mobility_v2.json, semantics.txt) of labelled objects. Every form of it is refused
    with one line and exit code 2, and nothing is written."""
    import shutil

    data = tmp_path / "data"
    shutil.copytree(real["data"] / "100028", data / "100028")  # a copy: the shared data is never at risk
    before = {p: p.read_bytes() for p in data.rglob("*") if p.is_file()}
    runner = CliRunner()
    for out in (data, data / "100028", data / "100028" / "textured_objs"):
        r = runner.invoke(app, ["predict", str(data), "--model", str(real["run"]), "--out", str(out),
                                "--quiet", "--device", "cpu"])
        assert r.exit_code == 2, (out, r.output)
        assert "outputs never overwrite inputs" in r.output and len(r.output.strip().splitlines()) <= 2
    r = runner.invoke(app, ["predict", str(data / "100028"), "--model", str(real["run"]), "--out",
                            str(data), "--quiet", "--device", "cpu"])  # OUT/<id> is the input
    assert r.exit_code == 2 and "would overwrite" in r.output, r.output
    assert {p: p.read_bytes() for p in data.rglob("*") if p.is_file()} == before
    assert not (data / "predictions.csv").exists() and not (tmp_path / "predictions.csv").exists()
    # an output folder beside the input is fine
    r = runner.invoke(app, ["predict", str(data), "--model", str(real["run"]), "--out",
                            str(tmp_path / "pred"), "--quiet", "--device", "cpu"])
    assert r.exit_code == 0, r.output
    assert {p: p.read_bytes() for p in data.rglob("*") if p.is_file()} == before


def test_edges_json_is_streamed_with_the_same_document(tmp_path):
    """Issue 21 finding 4: edges.json is written row by row (a flat 500-part asset has
    249,500 sibling edges), and reads back as the document of edges_json."""
    from kinmo.data.model import FINE_TYPES as names
    from kinmo.predict import edges_json, write_edges_json
    from motion_cabinet import cabinet_graph

    g = cabinet_graph(n_points=8)
    edges = oracle_prediction(g)
    pred = ShapePrediction(g, edges, build_mobility_tree(g, edges), tuple(names))
    path = write_edges_json(pred, tmp_path / "edges.json")
    doc = json.loads(path.read_text())
    assert doc == json.loads(json.dumps(edges_json(pred)))
    assert len(doc["edges"]) == len(g.sibling_edges) > 2
    assert [p.name for p in tmp_path.iterdir()] == ["edges.json"]  # no temporary left


@pytest.mark.exactdata
def test_a_prediction_that_fails_while_written_leaves_no_half_object(real, tmp_path, monkeypatch):
    """Issue 21 finding 12: each object is written into a temporary sibling and renamed into
    place whole; a failure half-way leaves nothing of it."""
    import kinmo.predict as predict
    from kinmo.errors import KinmoDataError

    def fail(pred, path):
        raise KinmoDataError(path, "disk full")

    monkeypatch.setattr(predict, "write_edges_json", fail)  # after mobility_v2.json and the URDF
    rows = predict_dataset(real["data"] / "100028", real["run"], tmp_path / "o", device="cpu", progress=False)
    assert rows[0].status == "failed" and "disk full" in rows[0].error
    assert sorted(p.name for p in (tmp_path / "o").iterdir()) == ["predictions.csv"]


def _tree_bytes(root: Path) -> dict[str, bytes]:
    return {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()}


@pytest.mark.exactdata
def test_two_workers_write_the_bytes_one_process_writes(real, tmp_path):
    """``kinmo predict DIR -j 2`` (issue 24, item 4): the shapes are shared out to two spawned
    workers, each with the caller's predictor; every file equals the in-process run's, the
    part-graph cache is used by the workers too, and the rows keep the folders' order."""
    one = predict_dataset(real["data"], real["run"], tmp_path / "j1", cache=real["cache"],
                          device="cpu", progress=False, workers=1)
    two = predict_dataset(real["data"], real["run"], tmp_path / "j2", cache=real["cache"],
                          device="cpu", progress=False, workers=2)
    assert [r.id for r in two] == [r.id for r in one] == sorted(OBJECTS)
    assert [r.status for r in two] == ["ok"] * len(OBJECTS)
    a, b = _tree_bytes(tmp_path / "j1"), _tree_bytes(tmp_path / "j2")
    assert sorted(a) == sorted(b) and len(a) > 6 * len(OBJECTS)
    differing = [k for k in a if a[k] != b[k]]
    assert differing == []


@pytest.mark.exactdata
def test_the_cli_takes_workers(real, tmp_path):
    r = CliRunner().invoke(app, ["predict", str(real["data"]), "-m", str(real["run"]), "-o",
                                 str(tmp_path / "o"), "--cache", str(real["cache"]), "-q", "-j", "2"])
    assert r.exit_code == 0, r.output
    assert f"predicted {len(OBJECTS)} shape(s)" in r.output
    written = sorted(p.name for p in (tmp_path / "o").iterdir() if not p.name.startswith("."))
    assert written == sorted(OBJECTS + ["predictions.csv"])  # .lock is the command's lock
