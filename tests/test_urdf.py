"""URDF export: loads in PyBullet, joints move the meshes exactly as mobility_v2.json says."""

from __future__ import annotations

import json
import math
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pybullet as p
import pytest
from scipy.spatial.transform import Rotation

from kinmo.data.model import Joint, JointType, Link
from kinmo.data.readers import read_shape
from kinmo.errors import KinmoDataError
from kinmo.geometry import load_obj
from kinmo.urdf import hinge_limits_rad, urdf_joints, urdf_string, write_urdf

# refrigerator (hinge, limits [0, -180]), table with a drawer (slider), laptop (hinge
# [90, -18]), bottle (cylindrical: slider + rotates), box (limits annotated in another turn,
# [-495, -225], non-unit axes), toaster (unlimited hinge + slider), storage furniture (4 doors)
OBJECTS = ["10849", "20453", "10306", "3596", "100162", "103482", "46108"]


@pytest.fixture(scope="module")
def bullet():
    cid = p.connect(p.DIRECT)
    yield cid
    p.disconnect(cid)


def _raw_moving(root: Path, oid: str) -> dict[int, dict]:
    raw = json.loads((root / oid / "mobility_v2.json").read_text())
    return {l["id"]: l for l in raw if l["joint"] in ("hinge", "slider")}


def _joints_by_name(body: int, cid: int) -> dict[str, tuple]:
    return {p.getJointInfo(body, i, physicsClientId=cid)[1].decode(): p.getJointInfo(body, i, physicsClientId=cid)
            for i in range(p.getNumJoints(body, physicsClientId=cid))}


def _link_vertices(shape, link_id: int) -> np.ndarray:
    link = next(l for l in shape.links if l.id == link_id)
    names = [m for pid in link.parts for m in shape.hierarchy.mesh_names(pid)]
    return np.concatenate([load_obj(shape.mesh_path(n))[0] for n in names])


def _world_vertices(body: int, cid: int, link_index: int, verts: np.ndarray) -> list[np.ndarray]:
    """The link's mesh vertices in the world, from PyBullet's link frame and visual frames."""
    st = p.getLinkState(body, link_index, computeForwardKinematics=True, physicsClientId=cid)
    R = np.array(p.getMatrixFromQuaternion(st[5])).reshape(3, 3)
    out = []
    for vis in p.getVisualShapeData(body, physicsClientId=cid):
        if vis[1] != link_index:
            continue
        Rv = np.array(p.getMatrixFromQuaternion(vis[6])).reshape(3, 3)
        local = verts @ Rv.T + np.array(vis[5])
        out.append(local @ R.T + np.array(st[4]))
    return out


@pytest.mark.exactdata
@pytest.mark.parametrize("oid", OBJECTS)
def test_joints_move_meshes_like_mobility(mobility_root: Path, tmp_path: Path, bullet: int, oid: str) -> None:
    shape = read_shape(mobility_root / oid)
    path = write_urdf(shape, tmp_path / "mobility.urdf")
    body = p.loadURDF(str(path), useFixedBase=True, physicsClientId=bullet)
    try:
        joints = _joints_by_name(body, bullet)
        raw = _raw_moving(mobility_root, oid)
        # one movable URDF link (PyBullet child link) per moving mobility link
        movable = {info[12].decode().removesuffix("_helper") for info in joints.values()
                   if info[2] != p.JOINT_FIXED}
        assert movable == {f"link_{i}" for i in raw}
        n_cyl = sum(bool(l["jointData"]["limit"].get("rotates")) for l in raw.values())
        assert sum(info[2] != p.JOINT_FIXED for info in joints.values()) == len(raw) + n_cyl
        link_idx = {info[12].decode(): i for i, info in enumerate(
            p.getJointInfo(body, k, physicsClientId=bullet) for k in range(p.getNumJoints(body, physicsClientId=bullet)))}

        for lid, lk in raw.items():
            o = np.asarray(lk["jointData"]["axis"]["origin"], float)
            d = np.asarray(lk["jointData"]["axis"]["direction"], float)
            d /= np.linalg.norm(d)
            verts = _link_vertices(shape, lid)[::7][:200]
            rotates = lk["joint"] == "hinge" or lk["jointData"]["limit"].get("rotates", False)
            slides = lk["joint"] == "slider"
            for theta, t in ((0.7, 0.05), (-1.3, -0.11), (0.0, 0.0)):
                theta, t = (theta if rotates else 0.0), (t if slides else 0.0)
                if lk["joint"] == "hinge":
                    p.resetJointState(body, joints[f"joint_{lid}"][0], theta, physicsClientId=bullet)
                else:
                    p.resetJointState(body, joints[f"joint_{lid}"][0], t, physicsClientId=bullet)
                    if rotates:
                        p.resetJointState(body, joints[f"joint_{lid}_rotation"][0], theta,
                                          physicsClientId=bullet)
                R = Rotation.from_rotvec(theta * d).as_matrix()
                expected = (verts - o) @ R.T + o + t * d
                got = _world_vertices(body, bullet, link_idx[f"link_{lid}"], verts)
                assert got, f"link_{lid} has no visual"
                for g in got:  # every visual (mesh) of the link sits in the same frame
                    assert np.abs(g - expected).max() < 1e-5, (oid, lid, theta, t)
        # fixed links do not move at all
        for name, info in joints.items():
            child = info[12].decode()
            if info[2] == p.JOINT_FIXED and info[16] == -1:  # attached to the base
                lid = int(child[5:])
                verts = _link_vertices(shape, lid)[:50]
                assert np.abs(_world_vertices(body, bullet, info[0], verts)[0] - verts).max() < 1e-6
    finally:
        p.removeBody(body, physicsClientId=bullet)


@pytest.mark.exactdata
@pytest.mark.parametrize("oid", OBJECTS)
def test_limits_and_types(mobility_root: Path, tmp_path: Path, bullet: int, oid: str) -> None:
    shape = read_shape(mobility_root / oid)
    body = p.loadURDF(str(write_urdf(shape, tmp_path / "m.urdf")), useFixedBase=True,
                      physicsClientId=bullet)
    try:
        joints = _joints_by_name(body, bullet)
        for lid, lk in _raw_moving(mobility_root, oid).items():
            lim = lk["jointData"]["limit"]
            info = joints[f"joint_{lid}"]
            lo, hi = sorted((lim["a"], lim["b"]))
            if lk["joint"] == "slider":
                assert info[2] == p.JOINT_PRISMATIC
                assert (info[8], info[9]) == pytest.approx((lo, hi), abs=1e-12)
                if lim.get("rotates"):
                    rot = joints[f"joint_{lid}_rotation"]
                    assert rot[2] == p.JOINT_REVOLUTE
                    assert (rot[8], rot[9]) == pytest.approx((0.0, math.radians(lim["rotationLimit"])))
            elif lim["noLimit"]:
                assert info[2] == p.JOINT_REVOLUTE and info[8] > info[9]  # continuous: no limit
            else:
                assert info[2] == p.JOINT_REVOLUTE
                # the same range, possibly shifted by whole turns towards the rest pose 0
                assert info[9] - info[8] == pytest.approx(math.radians(hi - lo))
                turns = (info[8] - math.radians(lo)) / (2 * math.pi)
                assert turns == pytest.approx(round(turns), abs=1e-9)
                if lo <= 0 <= hi:
                    assert round(turns) == 0
    finally:
        p.removeBody(body, physicsClientId=bullet)


@pytest.mark.exactdata
def test_mesh_paths_relative_to_object_folder(mobility_root: Path) -> None:
    shape = read_shape(mobility_root / "10849")
    root = ET.fromstring(urdf_string(shape))
    files = [m.get("filename") for m in root.iter("mesh")]
    assert files and all(f.startswith("textured_objs/") for f in files)
    assert all((shape.path / f).is_file() for f in files)
    # every leaf mesh appears once as visual and once as collision
    leaves = sorted(f"textured_objs/{m}.obj" for l in shape.links for pid in l.parts
                    for m in shape.hierarchy.mesh_names(pid))
    assert sorted(files) == sorted(leaves * 2)
    links = [l.get("name") for l in root.iter("link")]
    assert links[0] == "base" and sorted(links[1:]) == sorted(f"link_{l.id}" for l in shape.links)
    door = next(l for l in root.iter("link") if l.get("name") == "link_0")
    o = shape.links[0].joint.origin
    xyz = [float(v) for v in door.find("visual/origin").get("xyz").split()]
    assert xyz == pytest.approx(-o)


def test_hinge_limits_rad() -> None:
    r = math.radians
    assert hinge_limits_rad(0, -180) == pytest.approx((r(-180), 0.0))
    assert hinge_limits_rad(-495, -225) == pytest.approx((r(-135), r(135)))
    assert hinge_limits_rad(178, 69.84) == pytest.approx((r(69.84), r(178)))
    assert hinge_limits_rad(-488.88, -221.76) == pytest.approx((r(-128.88), r(138.24)))
    assert hinge_limits_rad(400, 500) == pytest.approx((r(40), r(140)))
    assert hinge_limits_rad(-360, 0) is None  # a full turn: continuous


@pytest.mark.exactdata
def test_bad_links(mobility_root: Path) -> None:
    shape = read_shape(mobility_root / "10849")
    shape.links = None
    with pytest.raises(KinmoDataError, match="no kinematic links"):
        urdf_string(shape)
    cyc = [Link(0, 1, "a", (), Joint(JointType.STATIC)), Link(1, 0, "b", (), Joint(JointType.STATIC))]
    with pytest.raises(KinmoDataError, match="cycle"):
        urdf_joints(cyc)
    bad = [Link(0, -1, "a", (), Joint(JointType.FREE)),
           Link(1, 0, "b", (), Joint(JointType.HINGE, np.zeros(3), np.zeros(3)))]
    with pytest.raises(KinmoDataError, match="zero axis"):
        urdf_joints(bad)
    missing = [Link(0, -1, "a", (999,), Joint(JointType.FREE))]
    with pytest.raises(KinmoDataError, match="part 999"):
        urdf_string(read_shape(mobility_root / "10849"), missing)


def test_nested_joints_compose(cabinet: Path, tmp_path: Path, bullet: int) -> None:
    """A knob hinged on a door hinged on the body: the knob follows both rotations."""
    shape = read_shape(cabinet)
    body = p.loadURDF(str(write_urdf(shape, tmp_path / "c.urdf")), useFixedBase=True,
                      physicsClientId=bullet)
    try:
        joints = _joints_by_name(body, bullet)
        raw = _raw_moving(cabinet, "")
        door, knob = raw[0]["jointData"]["axis"], raw[2]["jointData"]["axis"]
        a1, a2 = 0.9, -2.0
        p.resetJointState(body, joints["joint_0"][0], a1, physicsClientId=bullet)
        p.resetJointState(body, joints["joint_2"][0], a2, physicsClientId=bullet)

        def motion(ax, a):
            d = np.asarray(ax["direction"], float)
            R = Rotation.from_rotvec(a * d / np.linalg.norm(d)).as_matrix()
            o = np.asarray(ax["origin"], float)
            return lambda x: (x - o) @ R.T + o

        verts = _link_vertices(shape, 2)
        expected = motion(door, a1)(motion(knob, a2)(verts))
        got = _world_vertices(body, bullet, joints["joint_2"][0], verts)
        assert got and all(np.abs(g - expected).max() < 1e-5 for g in got)
        # the static base stays put, the door's knob axis moved with the door
        base = _link_vertices(shape, 4)
        assert np.abs(_world_vertices(body, bullet, joints["joint_4"][0], base)[0] - base).max() < 1e-9
    finally:
        p.removeBody(body, physicsClientId=bullet)
