"""`kinmo predict FILE` on a user's own part-segmented asset: a real object converted to a GLB
scene, an OBJ with groups, a folder of part meshes and a URDF; and the unsegmented-mesh error."""

from __future__ import annotations

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
from kinmo.user_input import read_parts

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
    obj = root / "dishwasher.obj"
    lines, n = [], 0
    for name, v, f in leaves:
        lines.append(f"o {name}")
        lines += [f"v {x!r} {y!r} {z!r}" for x, y, z in v.tolist()]
        lines += [f"f {a + 1 + n} {b + 1 + n} {c + 1 + n}" for a, b, c in f.tolist()]
        n += len(v)
    obj.write_text("\n".join(lines) + "\n")
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


def test_unsegmented_mesh_gets_a_clear_error(inputs, tmp_path):
    with pytest.raises(KinmoDataError, match="unsegmented.*kinmo needs the object split"):
        read_parts(inputs["single"])
    r = CliRunner().invoke(app, ["predict", str(inputs["single"]), "--model", str(inputs["run"]),
                                 "--out", str(tmp_path / "o"), "--quiet"])
    assert r.exit_code == 1
    assert "unsegmented" in r.output and "one 'o'/'g' group per part" in " ".join(r.output.split())
