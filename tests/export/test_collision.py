"""Collision geometry of exports (:mod:`kinmo.export.collision`, issue 24 item 2)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import trimesh
from typer.testing import CliRunner

from conftest import write_box_obj
from kinmo.cli import app
from kinmo.data.readers import read_shape
from kinmo.errors import KinmoUsageError
from kinmo.export import collision as col
from kinmo.export import export
from kinmo.export.kinematics import LinkMesh, link_meshes

runner = CliRunner()

#: A hollow cabinet (5 panels, one leaf each) and a drawer box that slides out along +z.
PANELS = {
    "left": ((0.0, 0.0, 0.0), (0.02, 1.0, 1.0)),
    "right": ((0.98, 0.0, 0.0), (1.0, 1.0, 1.0)),
    "bottom": ((0.02, 0.0, 0.0), (0.98, 0.02, 1.0)),
    "top": ((0.02, 0.98, 0.0), (0.98, 1.0, 1.0)),
    "back": ((0.02, 0.02, 0.0), (0.98, 0.98, 0.02)),
}
DRAWER = ((0.05, 0.05, 0.05), (0.95, 0.95, 1.0))


def write_hollow_cabinet(folder: Path) -> Path:
    """A PartNet-Mobility folder: link 0 the body (5 panel leaves, root), link 1 a drawer inside
    it (slider along +z, 0 .. 0.8)."""
    (folder / "textured_objs").mkdir(parents=True)
    for name, (lo, hi) in {**PANELS, "drawer": DRAWER}.items():
        write_box_obj(folder / "textured_objs" / f"{name}.obj", lo, hi)
    leaves = [{"id": k + 2, "name": n, "text": n, "objs": [n]} for k, n in enumerate(PANELS)]
    tree = [{"id": 0, "name": "cabinet", "text": "cabinet", "children": [
        {"id": 1, "name": "body", "text": "body", "children": leaves},
        {"id": 9, "name": "drawer", "text": "drawer", "objs": ["drawer"]}]}]
    links = [
        {"id": 0, "parent": -1, "joint": "heavy", "name": "body", "parts": [{"id": 1}], "jointData": {}},
        {"id": 1, "parent": 0, "joint": "slider", "name": "drawer", "parts": [{"id": 9}],
         "jointData": {"axis": {"origin": [0, 0, 0], "direction": [0, 0, 1]},
                       "limit": {"a": 0, "b": 0.8, "noLimit": False, "rotates": False}}},
    ]
    (folder / "result.json").write_text(json.dumps(tree))
    (folder / "mobility_v2.json").write_text(json.dumps(links))
    (folder / "meta.json").write_text(json.dumps({"model_cat": "StorageFurniture"}))
    return folder


def _deepest_penetration(urdf: Path) -> float:
    """Deepest drawer-body penetration in PyBullet while the drawer slides over its range."""
    import pybullet as p

    cid = p.connect(p.DIRECT)
    try:
        body = p.loadURDF(str(urdf), useFixedBase=True, physicsClientId=cid)
        j = next(i for i in range(p.getNumJoints(body, physicsClientId=cid))
                 if p.getJointInfo(body, i, physicsClientId=cid)[2] == p.JOINT_PRISMATIC)
        child = j  # the drawer's link index is its joint's
        parent = p.getJointInfo(body, j, physicsClientId=cid)[16]
        deepest = 0.0
        for t in np.linspace(0.0, 0.8, 9):
            p.resetJointState(body, j, float(t), physicsClientId=cid)
            p.performCollisionDetection(physicsClientId=cid)
            for c in p.getClosestPoints(body, body, 0.0, child, parent, physicsClientId=cid):
                deepest = max(deepest, -c[8])
        return deepest
    finally:
        p.disconnect(cid)


def _inside(v: np.ndarray, f: np.ndarray, x: np.ndarray) -> bool:
    """``x`` inside the closed convex mesh (v, f) with outward faces."""
    a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
    return bool((np.einsum("ij,ij->i", np.cross(b - a, c - a), x - a) < 0).all())


def test_hull_gives_one_convex_piece_per_leaf_mesh(tmp_path):
    shape = read_shape(write_hollow_cabinet(tmp_path / "cab"))
    mesh = link_meshes(shape)[0]
    assert mesh.leaf_faces == (12,) * 5
    pieces = col.leaf_hulls(mesh)
    assert len(pieces) == 5
    for v, f in pieces:
        m = trimesh.Trimesh(v, f, process=False)
        assert m.is_convex and m.volume > 0  # closed, outward, convex
    # the drawer's space is outside every piece: the body's own hull would fill it
    inside = np.array([0.5, 0.5, 0.5])
    assert not any(_inside(v, f, inside) for v, f in pieces)
    assert _inside(*col._whole_hull(mesh)[0], inside)
    assert _inside(*pieces[0], np.array([0.01, 0.5, 0.5]))  # within the left panel


def test_flat_leaf_becomes_a_slab_and_zero_area_leaf_has_no_piece():
    box = trimesh.creation.box()
    flat_v = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], dtype=float) + 3
    flat_f = np.array([[0, 1, 2], [0, 2, 3]])
    line_v = np.array([[0, 0, 5], [1, 0, 5], [2, 0, 5]], dtype=float)
    v = np.concatenate([box.vertices, flat_v, line_v])
    f = np.concatenate([box.faces, flat_f + 8, [[12, 13, 14]]]).astype(np.int64)
    pieces = col.leaf_hulls(LinkMesh(0, v, f, (12, 2, 1)))
    assert len(pieces) == 2
    slab_v, _ = pieces[1]
    assert len(slab_v) == 8 and np.ptp(slab_v, axis=0).min() > 0  # a thin box, not a plane
    assert np.ptp(slab_v, axis=0).min() < 0.01


def test_default_collision_keeps_a_sliding_drawer_out_of_its_cabinet(tmp_path, monkeypatch):
    src = write_hollow_cabinet(tmp_path / "cab")
    files = export(read_shape(src), tmp_path / "hull", ["urdf"])["urdf"]
    assert len(files) - 1 == 6  # 5 panels + the drawer
    assert _deepest_penetration(files[0]) < 1e-3
    # the same check fails for collision geometry that fills the cabinet (one hull per link)
    monkeypatch.setitem(col.COLLISION_METHODS, "whole", col.CollisionMethod(
        "whole", "one hull per link", col._whole_hull))
    files = export(read_shape(src), tmp_path / "whole", ["urdf"], collision="whole")["urdf"]
    assert _deepest_penetration(files[0]) > 0.1


def test_default_collision_mjcf_loads_and_steps_in_mujoco(tmp_path):
    import mujoco

    src = write_hollow_cabinet(tmp_path / "cab")
    xml = export(read_shape(src), tmp_path / "out", ["mjcf"])["mjcf"][0]
    model = mujoco.MjModel.from_xml_path(str(xml))
    assert sum(model.geom_group == 3) == 6
    data = mujoco.MjData(model)
    model.opt.gravity[:] = 0
    data.qpos[0] = 0.4
    for _ in range(100):
        mujoco.mj_step(model, data)
    assert np.isfinite(data.qpos).all() and abs(data.qvel).max() < 1e-3  # nothing pushes it


def test_cached_methods_are_computed_once(tmp_path, monkeypatch):
    calls = []

    def pieces(mesh):
        calls.append(1)
        return col.leaf_hulls(mesh)

    monkeypatch.setenv("KINMO_VHACD_CACHE", str(tmp_path / "cache"))
    monkeypatch.setitem(col.COLLISION_METHODS, "slow", col.CollisionMethod(
        "slow", "cached", pieces, cached=True, settings="slow/1"))
    mesh = link_meshes(read_shape(write_hollow_cabinet(tmp_path / "cab")))[0]
    a = col.collision_pieces(mesh, tmp_path / "a" / "link_0", "slow")
    b = col.collision_pieces(mesh, tmp_path / "b" / "link_0", "slow")
    assert len(calls) == 1 and len(a) == len(b) == 5
    assert [p.read_text() for p in a] == [p.read_text() for p in b]


def test_unknown_method_and_missing_coacd_are_usage_errors(tmp_path, monkeypatch):
    import importlib.util

    with pytest.raises(KinmoUsageError, match="unknown collision method 'nope'; known: hull, vhacd, coacd"):
        col.check_collision_method("nope")
    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec",
                        lambda name, *a: None if name == "coacd" else real(name, *a))
    with pytest.raises(KinmoUsageError, match="pip install coacd"):
        col.check_collision_method("coacd")
    src = write_hollow_cabinet(tmp_path / "cab")
    res = runner.invoke(app, ["export", str(src), "-f", "urdf", "-o", str(tmp_path / "o"),
                              "--collision", "nope"])
    assert res.exit_code == 2 and not (tmp_path / "o").exists()
    assert "--collision nope: unknown collision method" in " ".join(res.output.split())


def test_export_vhacd_on_request(tmp_path, monkeypatch):
    monkeypatch.setenv("KINMO_VHACD_CACHE", str(tmp_path / "cache"))
    src = write_hollow_cabinet(tmp_path / "cab")
    res = runner.invoke(app, ["export", str(src), "-f", "urdf", "-o", str(tmp_path / "o"),
                              "--collision", "vhacd", "-q"])
    assert res.exit_code == 0, res.output
    pieces = sorted((tmp_path / "o" / "collision").glob("link_*_*.obj"))
    assert pieces and len(list((tmp_path / "cache").glob("*.obj"))) == 2  # one per link
    for p in pieces:
        m = trimesh.load(p, force="mesh")
        assert m.is_convex
