"""`kinmo predict FILE` on a user's own part-segmented asset: a real object converted to a GLB
scene, an OBJ with groups, a folder of part meshes and a URDF; and the unsegmented-mesh error."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import torch
import trimesh
from typer.testing import CliRunner

from kinmo.cli import app
from kinmo.data.build import build_graph
from kinmo.data.readers import read_shape
from kinmo.errors import KinmoDataError
from kinmo.export import export
from kinmo.geometry import load_obj
from kinmo.train.config import preset
from kinmo.train.gnn import train_gnn
from kinmo.train.split import Split
from kinmo.assets import read_parts

torch.set_num_threads(1)

# dishwasher: door_frame + handle (door link), surface + frame (body link)
OBJECT = "11700"


def _leaf_meshes(shape) -> list[tuple[str, np.ndarray, np.ndarray]]:
    out = []
    for nid in shape.hierarchy.order:
        node = shape.hierarchy.nodes[nid]
        if not node.is_leaf:
            continue
        vs, fs, n = [], [], 0
        for m in node.objs:
            v, f = load_obj(shape.mesh_path(m))
            vs.append(v)
            fs.append(f + n)
            n += len(v)
        out.append((node.name, np.concatenate(vs), np.concatenate(fs)))
    return out


@pytest.fixture(scope="module")
def inputs(mobility_root: Path, tmp_path_factory):
    """The object as each input kind, plus a tiny GNN run to predict with."""
    root = tmp_path_factory.mktemp("user")
    shape = read_shape(mobility_root / OBJECT)
    leaves = _leaf_meshes(shape)
    scene = trimesh.Scene()
    for name, v, f in leaves:
        scene.add_geometry(trimesh.Trimesh(v, f, process=False), node_name=name, geom_name=name)
    glb = root / "dishwasher.glb"
    glb.write_bytes(scene.export(file_type="glb"))
    obj = _write_obj_groups(root / "dishwasher.obj", leaves)
    folder = root / "parts"
    folder.mkdir()
    for name, v, f in leaves:
        trimesh.Trimesh(v, f, process=False).export(folder / f"{name}.obj")
    urdf_dir = root / "asset"
    export(shape, urdf_dir, ["urdf"])
    single = root / "blob.obj"
    trimesh.Trimesh(leaves[0][1], leaves[0][2], process=False).export(single)
    # a tiny motion GNN (the pipeline is under test, not its accuracy)
    cache = root / "cache"
    cache.mkdir()
    ids = [OBJECT, "3596"]
    for oid in ids:
        build_graph(read_shape(mobility_root / oid), n_points=32).save(cache / f"{oid}.npz")
    cfg = preset("quick", n_points=32, threads=1, epochs=2, batch_size=2)
    cfg = cfg.model_copy(update={"model": cfg.model.model_copy(update=dict(
        point_widths=[16], geo_dim=16, node_dim=24, edge_dim=24, semantic_dim=4, gnn_layers=2))})
    train_gnn(cache, root / "run", cfg, split=Split(ids, []), progress=False)
    return {"root": root, "shape": shape, "leaves": leaves, "glb": glb, "obj": obj,
            "folder": folder, "urdf": urdf_dir / "mobility.urdf", "single": single,
            "run": root / "run"}


@pytest.mark.exactdata
@pytest.mark.parametrize("kind,n_parts", [("glb", 4), ("obj", 4), ("folder", 4), ("urdf", 2)])
def test_parts_keep_the_geometry(inputs, kind, n_parts):
    parts = read_parts(inputs[kind])
    assert len(parts) == n_parts
    allv = np.concatenate([v for _, v, _ in parts])
    ref = np.concatenate([v for _, v, _ in inputs["leaves"]])
    np.testing.assert_allclose(allv.min(0), ref.min(0), atol=1e-6)
    np.testing.assert_allclose(allv.max(0), ref.max(0), atol=1e-6)
    assert sum(len(f) for _, _, f in parts) == sum(len(f) for _, _, f in inputs["leaves"])
    if kind != "urdf":
        assert sorted(n for n, _, _ in parts) == sorted(n for n, _, _ in inputs["leaves"])


@pytest.mark.exactdata
@pytest.mark.parametrize("kind", ["glb", "obj", "folder", "urdf"])
def test_predict_on_own_asset_writes_a_partnet_mobility_folder(inputs, kind, tmp_path):
    out = tmp_path / "out"
    r = CliRunner().invoke(app, ["predict", str(inputs[kind]), "--model", str(inputs["run"]),
                                 "--out", str(out), "--format", "urdf", "--format", "gltf",
                                 "--device", "cpu", "--quiet"])
    assert r.exit_code == 0, r.output
    stem = {"glb": "dishwasher", "obj": "dishwasher", "folder": "parts", "urdf": "mobility"}[kind]
    final = out / stem
    shape = read_shape(final)  # a complete PartNet-Mobility folder
    assert shape.links and len(shape.hierarchy.leaves(shape.hierarchy.root)) == \
        (2 if kind == "urdf" else 4)
    assert {l.id for l in shape.links} and all(
        l.parent == -1 or l.parent in {k.id for k in shape.links} for l in shape.links)
    for name in ("mobility_v2.json", "edges.json", "mobility.urdf", "mobility.glb"):
        assert (final / name).is_file(), name
    assert not (out / ".staging").exists()
    import pybullet as p

    cid = p.connect(p.DIRECT)
    try:
        body = p.loadURDF(str(final / "mobility.urdf"), useFixedBase=True, physicsClientId=cid)
        assert p.getNumJoints(body, physicsClientId=cid) >= len(shape.links)
    finally:
        p.disconnect(cid)


@pytest.mark.exactdata
def test_unsegmented_mesh_gets_a_clear_error(inputs, tmp_path):
    with pytest.raises(KinmoDataError, match="unsegmented.*kinmo needs the object split"):
        read_parts(inputs["single"])
    r = CliRunner().invoke(app, ["predict", str(inputs["single"]), "--model", str(inputs["run"]),
                                 "--out", str(tmp_path / "o"), "--quiet"])
    assert r.exit_code == 1
    assert "unsegmented" in r.output and "one 'o'/'g' group per part" in " ".join(r.output.split())


def _write_obj_groups(path: Path, leaves) -> Path:
    lines, n = [], 0
    for name, v, f in leaves:
        lines.append(f"o {name}")
        lines += [f"v {x!r} {y!r} {z!r}" for x, y, z in v.tolist()]
        lines += [f"f {a + 1 + n} {b + 1 + n} {c + 1 + n}" for a, b, c in f.tolist()]
        n += len(v)
    path.write_text("\n".join(lines) + "\n")
    return path


# y-up (x, y, z) -> z-up (x, -z, y): the inverse of kinmo.data.frames' z-up -> y-up turn
_TO_Z_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])


@pytest.mark.exactdata
def test_a_z_up_asset_in_centimetres_gets_the_joints_of_the_y_up_one_in_its_own_frame(inputs, tmp_path):
    """Issue 22 part 4: the same object turned z-up, in centimetres and moved off the origin,
    predicted with --up z, gets the y-up prediction's joints mapped into its own frame."""
    (tmp_path / "y").mkdir()
    (tmp_path / "z").mkdir()
    y_obj = _write_obj_groups(tmp_path / "y" / "dishwasher.obj", inputs["leaves"])
    offset = np.array([50.0, -20.0, 300.0])
    z_leaves = [(n, 100.0 * v @ _TO_Z_UP.T + offset, f) for n, v, f in inputs["leaves"]]
    z_obj = _write_obj_groups(tmp_path / "z" / "dishwasher.obj", z_leaves)
    outs = {}
    for key, src, extra in (("y", y_obj, []), ("z", z_obj, ["--up", "z"])):
        outs[key] = tmp_path / f"out_{key}"
        r = CliRunner().invoke(app, ["predict", str(src), "--model", str(inputs["run"]), "--out",
                                     str(outs[key]), "--device", "cpu", "--quiet", *extra])
        assert r.exit_code == 0, r.output
    sy, sz = read_shape(outs["y"] / "dishwasher"), read_shape(outs["z"] / "dishwasher")
    # the meshes are written as given: in centimetres, z-up, off the origin
    written = np.concatenate([load_obj(sz.mesh_path(f"part_{k}"))[0] for k in range(len(z_leaves))])
    given = np.concatenate([v for _, v, _ in z_leaves])
    assert len(written) == len(given)
    np.testing.assert_allclose(written.min(0), given.min(0), atol=1e-4)
    np.testing.assert_allclose(written.max(0), given.max(0), atol=1e-4)
    frame = json.loads((outs["z"] / "dishwasher" / "frame.json").read_text())
    assert frame["up"] == "z" and frame["scale"] == pytest.approx(sy_scale(inputs) / 100.0, rel=1e-6)
    moving_y = [l for l in sy.links if l.joint.direction is not None]
    moving_z = {l.id: l for l in sz.links if l.joint.direction is not None}
    assert moving_y and len(moving_y) == len(moving_z)
    for ly in moving_y:
        lz = moving_z[ly.id]
        assert lz.joint.type == ly.joint.type
        dy = _TO_Z_UP @ (ly.joint.direction / np.linalg.norm(ly.joint.direction))
        dz = lz.joint.direction / np.linalg.norm(lz.joint.direction)
        assert abs(float(dy @ dz)) > 0.999
        # the axis lines coincide (in centimetres)
        oy = 100.0 * _TO_Z_UP @ ly.joint.origin + offset
        d = np.cross(oy - lz.joint.origin, dz)
        assert np.linalg.norm(d) < 0.5, (oy, lz.joint.origin)
        if ly.joint.type.name == "SLIDER" and ly.joint.limit is not None:
            assert lz.joint.limit[1] == pytest.approx(100.0 * ly.joint.limit[1], rel=1e-3)
    assert (outs["z"] / "dishwasher" / "view.html").is_file()


def _z_up_urdf_and_mjcf(folder: Path, leaves, scale: float) -> dict[str, Path]:
    """The object turned z-up and scaled, as a URDF (a link per leaf, fixed joints) and an MJCF
    model (the first leaf in the world body, a body per other leaf with a hinge kinmo must
    ignore), both naming the same OBJ meshes."""
    from xml.sax.saxutils import quoteattr

    (folder / "meshes").mkdir(parents=True)
    names = []
    for k, (name, v, f) in enumerate(leaves):
        trimesh.Trimesh(scale * v @ _TO_Z_UP.T, f, process=False).export(folder / "meshes" / f"p{k}.obj")
        names.append(quoteattr(f"{name}_{k}"))
    links = "".join(f'<link name={n}><visual><geometry><mesh filename="meshes/p{k}.obj"/></geometry>'
                    "</visual></link>" for k, n in enumerate(names))
    joints = "".join(f'<joint name="j{k}" type="fixed"><parent link={names[0]}/><child link={n}/></joint>'
                     for k, n in enumerate(names[1:], 1))
    (folder / "dishwasher.urdf").write_text(f'<robot name="d">{links}{joints}</robot>')
    assets = "".join(f'<mesh name="p{k}" file="meshes/p{k}.obj" inertia="shell"/>' for k in range(len(names)))
    bodies = "".join(f'<body name={n}><joint type="hinge"/><geom type="mesh" mesh="p{k}"/></body>'
                     for k, n in enumerate(names[1:], 1))
    (folder / "dishwasher.xml").write_text(
        f'<mujoco><asset>{assets}</asset><worldbody><geom type="mesh" mesh="p0"/>{bodies}'
        "</worldbody></mujoco>")
    return {"urdf": folder / "dishwasher.urdf", "mjcf": folder / "dishwasher.xml"}


@pytest.mark.exactdata
@pytest.mark.parametrize("kind", ["urdf", "mjcf"])
def test_urdf_and_mjcf_input_in_other_units_get_the_same_joints_scaled(inputs, tmp_path, kind):
    """Issue 36: the z-up URDF / MJCF object at x0.01 and x100 gets the joints of x1, scaled
    (both formats are z-up by default: no --up)."""
    shapes = {}
    for scale in (1.0, 0.01, 100.0):
        src = _z_up_urdf_and_mjcf(tmp_path / f"in_{scale}", inputs["leaves"], scale)[kind]
        out = tmp_path / f"out_{scale}"
        r = CliRunner().invoke(app, ["predict", str(src), "--model", str(inputs["run"]), "--out",
                                     str(out), "--device", "cpu", "--quiet", "-f", "mobility_v2"])
        assert r.exit_code == 0, r.output
        shapes[scale] = read_shape(out / "dishwasher")
        frame = json.loads((out / "dishwasher" / "frame.json").read_text())
        assert frame["up"] == "z"
    ref = {link.id: link for link in shapes[1.0].links if link.joint.direction is not None}
    assert ref and len(shapes[1.0].hierarchy.leaves(shapes[1.0].hierarchy.root)) == 4
    for scale in (0.01, 100.0):
        moving = {link.id: link for link in shapes[scale].links if link.joint.direction is not None}
        assert sorted(moving) == sorted(ref)
        for i, link in moving.items():
            assert link.joint.type == ref[i].joint.type
            d0 = ref[i].joint.direction / np.linalg.norm(ref[i].joint.direction)
            d = link.joint.direction / np.linalg.norm(link.joint.direction)
            assert abs(float(d0 @ d)) > 0.999
            off = np.cross(scale * ref[i].joint.origin - link.joint.origin, d)  # the axis lines coincide
            assert np.linalg.norm(off) < 1e-3 * scale, (scale, ref[i].joint.origin, link.joint.origin)
            if link.joint.type.name == "SLIDER" and link.joint.limit is not None:
                assert link.joint.limit[1] == pytest.approx(scale * ref[i].joint.limit[1], rel=1e-3)


def sy_scale(inputs) -> float:
    """kinmo's scale of the y-up asset: 2 / its bounding-box diagonal."""
    allv = np.concatenate([v for _, v, _ in inputs["leaves"]])
    return 2.0 / float(np.linalg.norm(allv.max(0) - allv.min(0)))


@pytest.mark.exactdata
def test_up_axis_defaults_follow_the_format(inputs, tmp_path):
    from kinmo.assets import asset_up

    assert asset_up(inputs["glb"]) == "y" and asset_up(inputs["obj"]) == "y"
    assert asset_up(inputs["folder"]) == "y"
    assert asset_up(inputs["urdf"]) == "y"  # written by kinmo: <mobility_v2> joints, y-up
    ros = tmp_path / "robot.urdf"
    ros.write_text('<robot name="r"><link name="a"/><link name="b"/>'
                   '<joint name="j" type="fixed"><parent link="a"/><child link="b"/></joint></robot>')
    assert asset_up(ros) == "z"


@pytest.mark.exactdata
def test_up_is_refused_for_a_dataset_folder_and_for_other_axes(inputs, mobility_root, tmp_path):
    r = CliRunner().invoke(app, ["predict", str(mobility_root / OBJECT), "--model", str(inputs["run"]),
                                 "--out", str(tmp_path / "o"), "--up", "z", "--quiet"])
    assert r.exit_code == 2 and "--up is for your own asset" in r.output
    r = CliRunner().invoke(app, ["predict", str(inputs["glb"]), "--model", str(inputs["run"]),
                                 "--out", str(tmp_path / "o2"), "--up", "x", "--quiet"])
    assert r.exit_code == 2 and "must be y or z" in r.output


@pytest.mark.exactdata
def test_turns_reach_the_predictor_and_a_bad_one_is_refused(inputs, tmp_path):
    """``kinmo predict --turns`` (issue 36): ``always`` predicts the asset as the average of its
    four quarter turns, ``never`` in one pass, and the default one pass for an asset whose part
    names the model knows (this GLB keeps PartNet's leaf names)."""
    import json

    def probs(*extra):
        out = tmp_path / "_".join(("o",) + extra)
        r = CliRunner().invoke(app, ["predict", str(inputs["glb"]), "--model", str(inputs["run"]),
                                     "--out", str(out), "--format", "mobility_v2", "--device", "cpu",
                                     "--quiet", *extra])
        assert r.exit_code == 0, r.output
        edges = json.loads((out / "dishwasher" / "edges.json").read_text())["edges"]
        return [e["probs"] for e in edges]

    never, always = probs("--turns", "never"), probs("--turns", "always")
    assert never != always
    assert probs() == never
    r = CliRunner().invoke(app, ["predict", str(inputs["glb"]), "--model", str(inputs["run"]),
                                 "--out", str(tmp_path / "bad"), "--turns", "sometimes", "--quiet"])
    assert r.exit_code == 2 and "--turns sometimes: must be one of unnamed, always, never" in r.output


@pytest.mark.exactdata
def test_an_asset_that_stands_on_another_axis_is_warned_about(inputs, mobility_root, tmp_path, caplog):
    from kinmo.inference.predictor import Predictor
    from kinmo.user_input import predict_user_input

    laptop = _leaf_meshes(read_shape(mobility_root / "11248"))  # lies on its base
    turned = _write_obj_groups(tmp_path / "laptop.obj", [(n, v @ _TO_Z_UP.T, f) for n, v, f in laptop])
    predictor = Predictor.from_parts(inputs["run"], device="cpu")
    with caplog.at_level("WARNING", logger="kinmo.user_input"):
        predict_user_input(turned, predictor, tmp_path / "o", formats=["mobility_v2"], progress=False)
    assert any("read as y-up" in r.getMessage() and "--up z" in r.getMessage() for r in caplog.records)
    caplog.clear()
    with caplog.at_level("WARNING", logger="kinmo.user_input"):
        predict_user_input(turned, predictor, tmp_path / "o2", formats=["mobility_v2"], progress=False, up="z")
    assert not any("read as" in r.getMessage() for r in caplog.records)


def _write_glb(path: Path, leaves) -> Path:
    scene = trimesh.Scene()
    for name, v, f in leaves:
        scene.add_geometry(trimesh.Trimesh(v, f, process=False), node_name=name, geom_name=name)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(scene.export(file_type="glb"))
    return path


def test_names_known_needs_half_the_part_names_in_the_vocabulary():
    from kinmo.features import SemanticVocab
    from kinmo.user_input import names_known

    vocab = SemanticVocab(["door", "handle", "cabinet"])
    assert names_known(["door_1", "Handle", "x", "y"], vocab)  # 2 of 4, numbers dropped
    assert not names_known(["cabinet5", "cabinet5_drawer_top", "handle_cab5_m", "x"], vocab)
    assert not names_known(["part_0", "part_1"], vocab) and not names_known([], vocab)


@pytest.mark.exactdata
def test_names_the_model_does_not_know_are_read_as_unnamed_and_kept_in_the_outputs(inputs, tmp_path):
    """Issue 36: an asset whose part names are mostly unknown to the model (one PartNet name of
    four) is predicted exactly as the same asset with generic names, and its outputs still
    carry the user's names; one whose names are known is not."""
    from kinmo.inference.predictor import Predictor
    from kinmo.user_input import predict_user_input

    leaves = inputs["leaves"]
    own = [(n if k == 0 else f"cab5_link_{'abc'[k - 1]}", v, f) for k, (n, v, f) in enumerate(leaves)]
    generic = [(f"part_{k}", v, f) for k, (_, v, f) in enumerate(leaves)]
    predictor = Predictor.from_parts(inputs["run"], device="cpu")

    def predict(kind, parts):
        out = tmp_path / kind
        predict_user_input(_write_glb(tmp_path / f"in_{kind}" / "asset.glb", parts), predictor, out,
                           formats=["mobility_v2"], progress=False)
        final = out / "asset"
        edges = json.loads((final / "edges.json").read_text())["edges"]
        return [e["probs"] for e in edges], read_shape(final)

    p_own, shape = predict("own", own)
    p_generic, _ = predict("generic", generic)
    p_known, _ = predict("known", leaves)
    assert p_own == p_generic
    assert p_known != p_generic
    names = [shape.hierarchy.nodes[i].name for i in shape.hierarchy.leaves(shape.hierarchy.root)]
    assert sorted(names) == sorted(n for n, _, _ in own)
    link_names = {l.name for l in shape.links}
    assert not any(n.startswith("part_") for n in link_names), link_names


@pytest.mark.exactdata
def test_predict_user_input_takes_a_run_folder_and_loads_it_once(inputs, tmp_path, monkeypatch):
    """``run`` may be a run folder (as ``kinmo.predict.predict_dataset`` takes): the predictor
    is loaded once, for the names rule and the prediction alike."""
    from kinmo.inference.predictor import Predictor
    from kinmo.user_input import predict_user_input

    loads = []
    real = Predictor.from_parts.__func__

    def counting(cls, *a, **kw):
        loads.append(a[0])
        return real(cls, *a, **kw)

    monkeypatch.setattr(Predictor, "from_parts", classmethod(counting))
    rows = predict_user_input(inputs["glb"], inputs["run"], tmp_path / "o", formats=["mobility_v2"],
                              progress=False, device="cpu")
    assert [r.status for r in rows] == ["ok"] and len(loads) == 1
    assert (tmp_path / "o" / "dishwasher" / "mobility_v2.json").is_file()
