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


def _write_two_links(folder: Path, body: list[str], child: str, direction, travel: float) -> Path:
    """A PartNet-Mobility folder of ``textured_objs/*.obj`` already written: link 0 the body
    (one leaf per name of ``body``, root), link 1 the leaf ``child`` sliding along
    ``direction`` from 0 to ``travel``."""
    leaves = [{"id": k + 2, "name": n, "text": n, "objs": [n]} for k, n in enumerate(body)]
    tree = [{"id": 0, "name": "object", "text": "object", "children": [
        {"id": 1, "name": "body", "text": "body", "children": leaves},
        {"id": 99, "name": child, "text": child, "objs": [child]}]}]
    links = [
        {"id": 0, "parent": -1, "joint": "heavy", "name": "body", "parts": [{"id": 1}], "jointData": {}},
        {"id": 1, "parent": 0, "joint": "slider", "name": child, "parts": [{"id": 99}],
         "jointData": {"axis": {"origin": [0, 0, 0], "direction": list(direction)},
                       "limit": {"a": 0, "b": travel, "noLimit": False, "rotates": False}}},
    ]
    (folder / "result.json").write_text(json.dumps(tree))
    (folder / "mobility_v2.json").write_text(json.dumps(links))
    (folder / "meta.json").write_text(json.dumps({"model_cat": "StorageFurniture"}))
    return folder


def write_hollow_cabinet(folder: Path, one_leaf: bool = False) -> Path:
    """A PartNet-Mobility folder: link 0 the body (5 panel leaves, or with ``one_leaf`` one
    leaf of the 5 panels 1 mm smaller on every side, disconnected, root), link 1 a drawer
    inside it (slider along +z, 0 .. 0.8)."""
    objs = folder / "textured_objs"
    objs.mkdir(parents=True)
    write_box_obj(objs / "drawer.obj", *DRAWER)
    for name, (lo, hi) in PANELS.items():
        write_box_obj(objs / f"{name}.obj", lo, hi)
    if not one_leaf:
        return _write_two_links(folder, list(PANELS), "drawer", (0, 0, 1), 0.8)
    boards = [trimesh.creation.box(bounds=(np.add(lo, 1e-3), np.subtract(hi, 1e-3)))
              for lo, hi in PANELS.values()]
    trimesh.util.concatenate(boards).export(objs / "frame.obj")
    return _write_two_links(folder, ["frame"], "drawer", (0, 0, 1), 0.8)


#: A U-shaped block, one connected leaf: 3 wide, 3 high, 1 deep, a slot x in [1, 2] from y = 1
#: up; its profile (counter-clockwise, with the cap's corners at (1, 0) and (2, 0)).
U_PROFILE = [(0, 0), (1, 0), (2, 0), (3, 0), (3, 3), (2, 3), (2, 1), (1, 1), (1, 3), (0, 3)]
#: The cap's quads (profile indices): left post, bridge, right post.
U_CAPS = [(0, 1, 7, 8), (1, 2, 6, 7), (2, 3, 4, 5)]
#: A cube that fits the slot (0.1 clearance each side), above it; it slides down by 2.
SLOT_CUBE = ((1.1, 3.2, 0.1), (1.9, 4.0, 0.9))


def u_mesh() -> tuple[np.ndarray, np.ndarray]:
    """The U block of :data:`U_PROFILE` extruded along z from 0 to 1: (vertices (20, 3),
    faces (36, 3)), outward, connected (shared vertices)."""
    n = len(U_PROFILE)
    v = np.array([(x, y, z) for z in (0.0, 1.0) for x, y in U_PROFILE], dtype=float)
    faces = []
    for a, b, c, d in U_CAPS:  # back cap (z = 0) faces -z, front cap +z
        faces += [(a, c, b), (a, d, c), (a + n, b + n, c + n), (a + n, c + n, d + n)]
    for i in range(n):
        j = (i + 1) % n
        faces += [(i, j, j + n), (i, j + n, i + n)]
    return v, np.array(faces, dtype=np.int64)


def write_slot_object(folder: Path) -> Path:
    """A PartNet-Mobility folder: link 0 the U block (one leaf), link 1 a cube sliding down
    into its slot (along -y, 0 .. 2)."""
    objs = folder / "textured_objs"
    objs.mkdir(parents=True)
    trimesh.Trimesh(*u_mesh(), process=False).export(objs / "u.obj")
    write_box_obj(objs / "cube.obj", *SLOT_CUBE)
    return _write_two_links(folder, ["u"], "cube", (0, -1, 0), 2.0)


def _deepest_penetration(urdf: Path, travel: float = 0.8) -> float:
    """Deepest child-body penetration in PyBullet while the (only) slider moves from 0 to
    ``travel``."""
    import pybullet as p

    cid = p.connect(p.DIRECT)
    try:
        body = p.loadURDF(str(urdf), useFixedBase=True, physicsClientId=cid)
        j = next(i for i in range(p.getNumJoints(body, physicsClientId=cid))
                 if p.getJointInfo(body, i, physicsClientId=cid)[2] == p.JOINT_PRISMATIC)
        child = j  # the drawer's link index is its joint's
        parent = p.getJointInfo(body, j, physicsClientId=cid)[16]
        deepest = 0.0
        for t in np.linspace(0.0, travel, 9):
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

    with pytest.raises(KinmoUsageError, match="unknown collision method 'nope'; known: hull, parts, vhacd, coacd"):
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


def _covered(pieces, points: np.ndarray, tol: float = 1e-9) -> bool:
    """Every point inside or on some convex piece."""
    def inside(v, f, x):
        a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
        n = np.cross(b - a, c - a)
        n /= np.linalg.norm(n, axis=1, keepdims=True)
        return (np.einsum("ij,ij->i", n, x - a) <= tol).all()

    return all(any(inside(v, f, x) for v, f in pieces) for x in points)


def test_parts_splits_a_concave_leaf_and_leaves_its_slot_free():
    v, f = u_mesh()
    mesh = LinkMesh(0, v, f, (len(f),))
    slot = np.array([1.5, 2.0, 0.5])
    (hull,) = col.leaf_hulls(mesh)
    assert _inside(*hull, slot)  # the leaf's hull fills the slot
    pieces = col.concave_parts(mesh)
    assert len(pieces) > 1
    for pv, pf in pieces:
        assert trimesh.Trimesh(pv, pf, process=False).is_convex
    assert not any(_inside(pv, pf, slot) for pv, pf in pieces)
    assert _covered(pieces, v)  # every face lies in a piece: the U's surface is kept
    again = col.concave_parts(mesh)  # deterministic
    assert all(np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1])
               for a, b in zip(pieces, again, strict=True))


def test_default_collision_lets_a_cube_slide_into_a_slot(tmp_path, monkeypatch):
    assert col.DEFAULT_COLLISION == "parts"
    src = write_slot_object(tmp_path / "u")
    files = export(read_shape(src), tmp_path / "parts", ["urdf"])["urdf"]
    assert len(files) - 1 > 2
    assert _deepest_penetration(files[0], 2.0) < 0.05
    files = export(read_shape(src), tmp_path / "hull", ["urdf"], collision="hull")["urdf"]
    assert _deepest_penetration(files[0], 2.0) > 0.5  # the U's hull blocks the slot


def test_parts_keeps_convex_leaves_one_hull_each():
    ball = trimesh.creation.icosphere(subdivisions=2)
    box = trimesh.creation.box(extents=(1.0, 2.0, 0.5))
    box.apply_translation((3.0, 0.0, 0.0))
    v = np.concatenate([ball.vertices, box.vertices])
    f = np.concatenate([ball.faces, box.faces + len(ball.vertices)]).astype(np.int64)
    mesh = LinkMesh(0, v, f, (len(ball.faces), len(box.faces)))
    got, want = col.concave_parts(mesh), col.leaf_hulls(mesh)
    assert len(got) == 2
    for (a, af), (b, bf) in zip(got, want, strict=True):
        assert np.array_equal(a, b) and np.array_equal(af, bf)


def test_parts_splits_a_frame_leaf_into_its_boards(tmp_path):
    src = write_hollow_cabinet(tmp_path / "cab", one_leaf=True)
    shape = read_shape(src)
    body = link_meshes(shape)[0]
    assert body.leaf_faces == (60,)
    assert len(col.concave_parts(body)) == 5  # its 5 connected components
    files = export(shape, tmp_path / "parts", ["urdf"])["urdf"]
    assert _deepest_penetration(files[0]) < 1e-3
    files = export(shape, tmp_path / "hull", ["urdf"], collision="hull")["urdf"]
    assert _deepest_penetration(files[0]) > 0.1


def test_cli_default_collision_is_the_registry_default():
    import inspect

    from kinmo.cli.export import export_cmd
    from kinmo.cli.predict import predict_cmd
    from kinmo.cli.pseudo_label import pseudo_label_cmd

    for cmd in (export_cmd, predict_cmd, pseudo_label_cmd):
        option = inspect.signature(cmd).parameters["collision"].default
        assert option.default == col.DEFAULT_COLLISION, cmd.__name__
