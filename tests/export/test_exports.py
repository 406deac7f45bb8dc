"""Every export format written for real objects (and predicted-like motions) and loaded back in
its own library, with joint motion checked numerically against mobility_v2.json's transform."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial import ConvexHull
from scipy.spatial.transform import Rotation
import trimesh
from typer.testing import CliRunner

from kinmo.cli import app
from kinmo.data.model import JointType
from kinmo.data.readers import read_shape
from kinmo.export import export, formats
from kinmo.export.kinematics import link_meshes, link_poses, moving_links
from kinmo.export.urdf import read_urdf
from kinmo.geometry import load_obj
from kinmo.urdf import link_frame_origins, urdf_joints

# bottle (cylindrical: slider that rotates), dishwasher (root link 1 "heavy", hinge child 0),
# box (limits annotated a turn away, [-495, -225]), toaster (unlimited hinge + slider)
OBJECTS = ["3596", "11700", "100162", "103482"]


def _predicted_like(shape, seed: int):
    """The object's links with tilted axes (arbitrary directions, as predictions have)."""
    rng = np.random.default_rng(seed)
    out = []
    for l in shape.links:
        if l.joint.is_moving:
            R = Rotation.from_rotvec(rng.normal(size=3) * 0.4).as_matrix()
            l = dataclasses.replace(l, joint=dataclasses.replace(
                l.joint, direction=R @ l.joint.direction))
        out.append(l)
    return out


@pytest.fixture(scope="module")
def exported(mobility_root: Path, tmp_path_factory):
    """{case: (shape, links, out_dir, files)} for every object, real and tilted links."""
    root = tmp_path_factory.mktemp("export")
    cases = {}
    for oid in OBJECTS:
        shape = read_shape(mobility_root / oid)
        for kind, links in (("real", shape.links), ("pred", _predicted_like(shape, int(oid)))):
            out = root / f"{oid}-{kind}"
            files = export(shape, out, formats(), links=links)
            cases[f"{oid}-{kind}"] = (shape, links, out, files)
    return cases


def _expected_frames(links, values):
    """World (R, p) of every link frame at ``values``: T_k applied to the rest frame a_k."""
    rest = link_frame_origins(links)
    poses = link_poses(links, values)
    return {lid: (T[:3, :3], T[:3, :3] @ rest[lid] + T[:3, 3]) for lid, T in poses.items()}


def _values(links, frac: float):
    """A joint value per moving link, at ``frac`` of its URDF range (both DOFs of a PR)."""
    vals = {}
    for j in urdf_joints(links):
        if not j.is_moving:
            continue
        lo, hi = (j.lower, j.upper) if j.lower is not None else (-math.pi, math.pi)
        v = lo + frac * (hi - lo)
        t, r = vals.get(j.link_id, (0.0, 0.0))
        vals[j.link_id] = (v, r) if j.type == "prismatic" else (t, v)
    return vals


@pytest.mark.exactdata
def test_every_format_is_registered_and_written(exported):
    assert formats()[:3] == ["mobility_v2", "semantics", "urdf"]
    assert {"mjcf", "usd", "gltf"} <= set(formats())
    for shape, links, out, files in exported.values():
        assert set(files) == set(formats())
        for written in files.values():
            assert written and all(p.is_file() and p.stat().st_size > 0 for p in written)


@pytest.mark.exactdata
def test_urdf_loads_in_pybullet_with_convex_collision_and_moves_links(exported):
    import pybullet as p

    cid = p.connect(p.DIRECT)
    try:
        for case, (shape, links, out, files) in exported.items():
            body = p.loadURDF(str(out / "mobility.urdf"), useFixedBase=True, physicsClientId=cid)
            info = {p.getJointInfo(body, i, physicsClientId=cid)[12].decode(): i
                    for i in range(p.getNumJoints(body, physicsClientId=cid))}
            # a single-parent tree: every kinmo link is one URDF link (+ a helper per PR joint)
            n_pr = sum(l.joint.rotates for l in moving_links(links))
            assert len(info) == len(links) + n_pr
            # collision: convex pieces (a hull per leaf mesh) for every link with geometry
            for l in links:
                shapes = p.getCollisionShapeData(body, info[f"link_{l.id}"], physicsClientId=cid)
                assert shapes, f"{case}: link {l.id} has no collision shape"
                pieces = sorted((out / "collision").glob(f"link_{l.id}_*.obj"))
                assert pieces and len(shapes) == len(pieces), (case, l.id, len(pieces), len(shapes))
                for piece in pieces:  # each piece is convex: it encloses its own hull's volume
                    v, f = load_obj(piece)
                    vol = abs(trimesh.Trimesh(v, f, process=False).volume)
                    assert vol == pytest.approx(ConvexHull(v).volume, rel=1e-3), (case, piece)
            vals = _values(links, 0.7)
            for j in urdf_joints(links):
                if j.is_moving:
                    t, r = vals[j.link_id]
                    p.resetJointState(body, info[j.child], t if j.type == "prismatic" else r,
                                      physicsClientId=cid)
            want = _expected_frames(links, vals)
            for l in links:
                st = p.getLinkState(body, info[f"link_{l.id}"], computeForwardKinematics=True,
                                    physicsClientId=cid)
                R = np.array(p.getMatrixFromQuaternion(st[5])).reshape(3, 3)
                np.testing.assert_allclose(st[4], want[l.id][1], atol=1e-5, err_msg=case)
                np.testing.assert_allclose(R, want[l.id][0], atol=1e-5, err_msg=case)
            p.removeBody(body, physicsClientId=cid)
    finally:
        p.disconnect(cid)


@pytest.mark.exactdata
def test_urdf_round_trip_is_lossless(exported):
    for case, (shape, links, out, files) in exported.items():
        back = read_urdf(out / "mobility.urdf")
        assert [l.id for l in back] == sorted(l.id for l in links), case
        for a, b in zip(sorted(links, key=lambda l: l.id), back):
            assert (a.parent, a.name, tuple(a.parts)) == (b.parent, b.name, tuple(b.parts)), case
            ja, jb = a.joint, b.joint
            assert (ja.type, ja.rotates, ja.limit, ja.rotation_limit) == \
                   (jb.type, jb.rotates, jb.limit, jb.rotation_limit), (case, a.id)
            if ja.is_moving:
                np.testing.assert_allclose(jb.origin, ja.origin, rtol=0, atol=1e-12)
                np.testing.assert_allclose(jb.direction, ja.direction / np.linalg.norm(ja.direction),
                                           rtol=0, atol=1e-12)
    # the cylindrical joint survives as one slider that rotates
    bottle = read_urdf(exported["3596-real"][2] / "mobility.urdf")
    lid = next(l for l in bottle if l.joint.type is JointType.SLIDER)
    assert lid.joint.rotates and lid.joint.rotation_limit == 180


@pytest.mark.exactdata
def test_mjcf_loads_in_mujoco_and_qpos_moves_bodies_about_the_axes(exported):
    import mujoco

    for case, (shape, links, out, files) in exported.items():
        m = mujoco.MjModel.from_xml_path(str(out / "mobility.xml"))
        d = mujoco.MjData(m)
        for frac in (0.0, 0.35, 1.0):
            vals = _values(links, frac)
            for j in urdf_joints(links):
                if j.is_moving:
                    t, r = vals[j.link_id]
                    jid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, j.name)
                    assert jid >= 0, (case, j.name)
                    d.qpos[m.jnt_qposadr[jid]] = t if j.type == "prismatic" else r
            mujoco.mj_kinematics(m, d)
            want = _expected_frames(links, vals)
            for l in links:
                b = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, f"link_{l.id}")
                np.testing.assert_allclose(d.xpos[b], want[l.id][1], atol=1e-6, err_msg=case)
                np.testing.assert_allclose(d.xmat[b].reshape(3, 3), want[l.id][0], atol=1e-6,
                                           err_msg=case)
        assert m.njnt == sum(1 + l.joint.rotates for l in moving_links(links))
        # collision: the convex pieces (group 3), visuals (group 1) do not collide
        colliding = [g for g in range(m.ngeom) if m.geom_contype[g]]
        assert colliding and all(m.geom_group[g] == 3 for g in colliding)
        assert len(colliding) == len(list((out / "meshes").glob("link_*_collision_*.obj")))


@pytest.mark.exactdata
def test_usd_stage_has_physics_joints_axes_limits_and_meshes(exported):
    from pxr import Gf, Usd, UsdGeom, UsdPhysics

    for case, (shape, links, out, files) in exported.items():
        stage = Usd.Stage.Open(str(out / "mobility.usd"))
        assert UsdGeom.GetStageUpAxis(stage) == "Y"
        top = stage.GetDefaultPrim()
        assert top.HasAPI(UsdPhysics.ArticulationRootAPI)
        meshes = link_meshes(shape, links)
        by_urdf = {j.name: j for j in urdf_joints(links)}
        for l in links:
            body = top.GetChild(f"link_{l.id}")
            assert body.HasAPI(UsdPhysics.RigidBodyAPI), case
            pts = np.array(UsdGeom.Mesh(body.GetChild("mesh")).GetPointsAttr().Get())
            assert len(pts) == len(meshes[l.id].vertices)
            jp = top.GetChild("joints").GetChild(f"joint_{l.id}")
            j = UsdPhysics.Joint(jp)
            parent = [str(t) for t in j.GetBody0Rel().GetTargets()]
            assert parent == ([] if l.parent == -1 else [f"{top.GetPath()}/link_{l.parent}"])
            if l.parent == -1 or not l.joint.is_moving:
                assert jp.IsA(UsdPhysics.FixedJoint), case
                continue
            q = j.GetLocalRot0Attr().Get()
            axis = Gf.Rotation(Gf.Quatd(q)).TransformDir(Gf.Vec3d(1, 0, 0))
            np.testing.assert_allclose(np.array(axis), l.joint.direction / np.linalg.norm(
                l.joint.direction), atol=1e-6)
            uj = by_urdf[f"joint_{l.id}"]
            if l.joint.rotates:  # D6: free transX and rotX within limits, the rest locked
                lims = {dof: UsdPhysics.LimitAPI(jp, dof) for dof in
                        ("transX", "transY", "transZ", "rotX", "rotY", "rotZ")}
                assert lims["transX"].GetLowAttr().Get() == pytest.approx(uj.lower)
                assert lims["rotX"].GetHighAttr().Get() == pytest.approx(l.joint.rotation_limit)
                for dof in ("transY", "transZ", "rotY", "rotZ"):
                    assert lims[dof].GetLowAttr().Get() > lims[dof].GetHighAttr().Get()
            elif l.joint.type is JointType.SLIDER:
                pj = UsdPhysics.PrismaticJoint(jp)
                assert pj and pj.GetAxisAttr().Get() == "X"
                assert pj.GetLowerLimitAttr().Get() == pytest.approx(uj.lower)
                assert pj.GetUpperLimitAttr().Get() == pytest.approx(uj.upper)
            else:
                rj = UsdPhysics.RevoluteJoint(jp)
                assert rj and rj.GetAxisAttr().Get() == "X"
                lo = rj.GetLowerLimitAttr().Get()
                if uj.lower is None:  # UsdPhysics: unlimited is the schema's default, +-inf
                    assert lo == -math.inf and rj.GetUpperLimitAttr().Get() == math.inf
                else:
                    assert lo == pytest.approx(math.degrees(uj.lower), abs=1e-4)
                    assert rj.GetUpperLimitAttr().Get() == pytest.approx(math.degrees(uj.upper),
                                                                         abs=1e-4)


def _node_world(gl, node_index: int, local: dict[int, np.ndarray]) -> np.ndarray:
    parents = {c: i for i, n in enumerate(gl.nodes) for c in (n.children or [])}
    M = np.eye(4)
    i = node_index
    while i is not None:
        M = local[i] @ M
        i = parents.get(i)
    return M


def _trs(t, q) -> np.ndarray:
    M = np.eye(4)
    if q is not None:
        M[:3, :3] = Rotation.from_quat(q).as_matrix()
    if t is not None:
        M[:3, 3] = t
    return M


@pytest.mark.exactdata
def test_gltf_animations_move_link_nodes_as_mobility_says(exported):
    import pygltflib
    import trimesh

    for case, (shape, links, out, files) in exported.items():
        path = out / "mobility.glb"
        scene = trimesh.load(path)  # a second reader: the file is valid glTF
        assert len(scene.geometry) == sum(len(m.faces) > 0 for m in link_meshes(shape, links).values())
        gl = pygltflib.GLTF2().load(str(path))
        name_to_node = {n.name: i for i, n in enumerate(gl.nodes)}
        moving = moving_links(links)
        assert sorted(a.name for a in gl.animations) == sorted(f"joint_{l.id}" for l in moving)
        rest_local = {i: _trs(n.translation, n.rotation) for i, n in enumerate(gl.nodes)}
        for anim in gl.animations:
            lid = int(anim.name.split("_")[1])
            values = np.array(anim.extras["values"])
            channels = {}
            for ch in anim.channels:
                s = anim.samplers[ch.sampler]
                acc = gl.accessors[s.output]
                bv = gl.bufferViews[acc.bufferView]
                width = 4 if ch.target.path == "rotation" else 3
                data = np.frombuffer(gl.binary_blob()[bv.byteOffset:bv.byteOffset + bv.byteLength],
                                     dtype=np.float32).reshape(acc.count, width)
                channels[ch.target.path] = data
            for key in (0, len(values) // 2, len(values) - 1):
                local = dict(rest_local)
                node = name_to_node[f"link_{lid}"]
                t = channels.get("translation", [gl.nodes[node].translation] * len(values))[key]
                q = channels.get("rotation", [None] * len(values))[key]
                local[node] = _trs(t, q)
                got = _node_world(gl, node, local)
                want_R, want_p = _expected_frames(links, {lid: tuple(values[key])})[lid]
                np.testing.assert_allclose(got[:3, 3], want_p, atol=1e-5, err_msg=case)
                np.testing.assert_allclose(got[:3, :3], want_R, atol=1e-5, err_msg=case)


@pytest.mark.exactdata
def test_cli_export_writes_formats_and_rejects_unknown(mobility_root: Path, tmp_path: Path):
    r = CliRunner().invoke(app, ["export", str(mobility_root / "3596"), "--format", "mjcf",
                                 "--format", "gltf", "--out", str(tmp_path / "o")])
    assert r.exit_code == 0, r.output
    assert (tmp_path / "o" / "mobility.xml").is_file() and (tmp_path / "o" / "mobility.glb").is_file()
    r = CliRunner().invoke(app, ["export", str(mobility_root / "3596"), "--format", "step",
                                 "--out", str(tmp_path / "p")])
    assert r.exit_code == 2 and "unknown format" in r.output
    assert not (tmp_path / "p").exists()
    (tmp_path / "file").write_text("x")
    r = CliRunner().invoke(app, ["export", str(mobility_root / "3596"), "--format", "usd",
                                 "--out", str(tmp_path / "file")])
    assert r.exit_code == 1 and "is not a folder" in r.output and "Traceback" not in r.output


@pytest.mark.exactdata
def test_cli_export_of_a_predicted_folder_needs_its_source(mobility_root: Path, tmp_path: Path):
    pred = tmp_path / "pred"  # what `kinmo predict` writes: links, no meshes
    pred.mkdir()
    (pred / "mobility_v2.json").write_bytes((mobility_root / "11700" / "mobility_v2.json").read_bytes())
    r = CliRunner().invoke(app, ["export", str(pred), "-f", "usd", "-o", str(tmp_path / "a")])
    assert r.exit_code == 1 and "--source" in " ".join(r.output.split())
    r = CliRunner().invoke(app, ["export", str(pred), "-f", "usd", "-o", str(tmp_path / "b"),
                                 "--source", str(mobility_root / "11700")])
    assert r.exit_code == 0, r.output
    assert (tmp_path / "b" / "mobility.usd").is_file()
