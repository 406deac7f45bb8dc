"""MJCF input (issue 36): bodies are parts at the default pose, joints ignored, meshes and
primitives are the geometry, and every file reference is checked before MuJoCo opens it."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from assets.builders import CABINET, bounds, box_mjcf, write_mesh
from kinmo.assets import asset_up, is_user_input, read_parts
from kinmo.errors import KinmoDataError


def _parts(xml, text: str) -> dict[str, np.ndarray]:
    """The model ``text`` written at ``xml``, read: part name -> vertices."""
    xml.write_text(text)
    return {n: v for n, v, _ in read_parts(xml)}


def test_a_model_of_boxes_reads_one_part_per_body_and_the_world(tmp_path):
    parts = read_parts(box_mjcf(tmp_path / "cab.xml"))
    assert [n for n, _, _ in parts] == ["world", "door", "drawer", "handle"]
    names = {"world": "body"}
    for name, v, f in parts:  # the plane is skipped: the world part is the body's box only
        c, s = CABINET[names.get(name, name)]
        np.testing.assert_allclose(v.min(0), np.subtract(c, np.divide(s, 2)), atol=1e-6)
        np.testing.assert_allclose(v.max(0), np.add(c, np.divide(s, 2)), atol=1e-6)
        assert v.dtype == np.float64 and f.dtype == np.int64
    assert asset_up(tmp_path / "cab.xml") == "z" and is_user_input(tmp_path / "cab.xml")


def test_meshes_are_placed_by_the_body_pose_and_scale_despite_mujoco_recentring(tmp_path):
    write_mesh(tmp_path / "meshes" / "door.stl", extents=(1, 2, 3), offset=(5, 0, 0))
    parts = _parts(tmp_path / "m.xml",
        '<mujoco><compiler meshdir="meshes" angle="degree"/><asset><mesh name="d" file="door.stl" '
        'scale="2 2 2"/></asset><worldbody><geom type="sphere" size="0.5"/>'
        '<body name="door" pos="1 0 0" euler="0 0 90"><joint type="hinge"/><geom type="mesh" mesh="d"/>'
        '<body name="knob"><geom type="capsule" fromto="0 0 0 0 0 1" size="0.05"/></body>'
        "</body></worldbody></mujoco>")
    assert list(parts) == ["world", "door", "knob"]
    # the box (centre (10, 0, 0), extents (2, 4, 6) once scaled) turned 90 degrees about z, moved by +x
    np.testing.assert_allclose(parts["door"].min(0), [-1, 9, -3], atol=1e-5)
    np.testing.assert_allclose(parts["door"].max(0), [3, 11, 3], atol=1e-5)
    np.testing.assert_allclose(parts["knob"][:, 2].min(), -0.05, atol=1e-6)
    np.testing.assert_allclose(parts["knob"][:, 2].max(), 1.05, atol=1e-6)


def test_joint_values_are_ignored_the_default_pose_is_read(tmp_path):
    xml = box_mjcf(tmp_path / "cab.xml")
    text = xml.read_text().replace('<joint type="hinge" axis="0 0 1"/>', '<joint type="hinge" axis="0 0 1" ref="30"/>')
    xml.write_text(text)
    np.testing.assert_allclose(bounds(read_parts(xml)), bounds(read_parts(box_mjcf(tmp_path / "b.xml"))))


def test_visual_geoms_stand_for_their_body_when_it_has_any(tmp_path):
    xml = tmp_path / "v.xml"
    xml.write_text(
        '<mujoco><worldbody><geom type="box" size="1 1 1"/><body name="lid" pos="0 0 2">'
        '<geom type="box" size="5 5 0.1"/>'  # collision proxy, larger: dropped
        '<geom type="ellipsoid" size="1 2 0.5" contype="0" conaffinity="0"/></body></worldbody></mujoco>')
    lid = read_parts(xml)[1][1]
    np.testing.assert_allclose(np.abs(lid - [0, 0, 2]).max(0), [1, 2, 0.5], atol=0.05)


def test_moving_bodies_without_mass_load(tmp_path):
    # object files completed by their framework (LIBERO's, robosuite adds the inertials): a
    # hinged body whose only geom is massless, and a slide body of visual geoms without
    # density, which MuJoCo alone refuses ("mass and inertia of moving bodies ...")
    parts = _parts(tmp_path / "m.xml",
        '<mujoco><worldbody><geom type="box" size="1 1 1"/>'
        '<body name="door" pos="0 1.2 0"><joint type="hinge" axis="0 0 1"/>'
        '<geom type="box" size="1 0.1 1" mass="0"/></body>'
        '<body name="drawer" pos="0 0 1.5"><joint type="slide" axis="0 1 0"/>'
        '<geom type="box" size="0.5 0.5 0.2" density="0" contype="0" conaffinity="0"/></body>'
        "</worldbody></mujoco>")
    assert list(parts) == ["world", "door", "drawer"]
    np.testing.assert_allclose(parts["door"].min(0), [-1, 1.1, -1], atol=1e-6)
    np.testing.assert_allclose(parts["drawer"].max(0), [0.5, 0.5, 1.7], atol=1e-6)


def test_an_xml_file_of_another_kind_is_not_an_asset(tmp_path):
    other = tmp_path / "scene.xml"
    other.write_text('<?xml version="1.0"?><!-- a comment --><sdf version="1.6"/>')
    assert not is_user_input(other)
    with pytest.raises(KinmoDataError, match=r"unknown input kind '.xml' \(an .xml file must be MJCF"):
        read_parts(other)


def test_mujoco_errors_are_one_line_naming_the_file(tmp_path):
    xml = tmp_path / "bad.xml"
    xml.write_text('<mujoco><worldbody><geom type="mesh" mesh="nothing"/></worldbody></mujoco>')
    with pytest.raises(KinmoDataError) as e:
        read_parts(xml)
    assert str(e.value).startswith(f"{xml}: MuJoCo cannot load the model:") and "\n" not in str(e.value)


def test_includes_are_followed_and_checked(tmp_path):
    (tmp_path / "parts").mkdir()
    (tmp_path / "parts" / "door.xml").write_text(
        '<mujoco><body name="door" pos="0 0 2"><geom type="box" size="1 1 1"/></body></mujoco>')
    xml = tmp_path / "m.xml"
    xml.write_text('<mujoco><worldbody><geom type="box" size="1 1 1"/><include file="parts/door.xml"/>'
                   "</worldbody></mujoco>")
    assert [n for n, _, _ in read_parts(xml)] == ["world", "door"]


# ---- hostile references: refused before MuJoCo opens anything --------------------------------

def _model(tmp_path, asset="", compiler="", extra=""):
    xml = tmp_path / "model" / "m.xml"
    xml.parent.mkdir(exist_ok=True)
    xml.write_text(f'<mujoco><compiler {compiler}/><asset>{asset}</asset><worldbody>'
                   f'<geom type="box" size="1 1 1"/>{extra}<body name="b" pos="0 0 3">'
                   '<geom type="box" size="1 1 1"/></body></worldbody></mujoco>')
    return xml


@pytest.mark.parametrize("kw,problem", [
    ({"asset": '<mesh name="m" file="../secret.stl"/>'}, "<mesh file> '../secret.stl' refused: it climbs out"),
    ({"asset": '<mesh name="m" file="ABS"/>'}, "is an absolute path"),
    ({"compiler": 'meshdir="../"', "asset": '<mesh name="m" file="secret.stl"/>'}, "<compiler meshdir> '../' refused"),
    ({"compiler": 'assetdir="/tmp"'}, "<compiler assetdir> '/tmp' refused: it is an absolute path"),
    ({"compiler": 'meshdir="out"', "asset": '<mesh name="m" file="secret.stl"/>'},
     "<compiler meshdir> 'out' refused: it leads outside through a symbolic link"),
    ({"asset": '<mesh name="m" file="sub/../../secret.stl"/>'}, "'sub/../../secret.stl' refused: it climbs out"),
    ({"asset": '<mesh name="m" file="out/../secret.stl"/>'}, "refused: it leads outside through a symbolic link"),
    ({"asset": '<hfield name="h" file="link.png"/>'}, "leads outside through a symbolic link"),
    ({"extra": '<include file="../other.xml"/>'}, "<include file> '../other.xml' refused"),
    ({"asset": '<mesh name="m" file="a:b.stl"/>'}, "contains ':'"),
])
def test_file_references_leaving_the_model_folder_are_refused(tmp_path, monkeypatch, kw, problem):
    import mujoco

    opened = []
    monkeypatch.setattr(mujoco.MjSpec, "from_file", lambda *a: opened.append(a))
    secret = write_mesh(tmp_path / "secret.stl")
    (tmp_path / "other.xml").write_text("<mujoco/>")
    kw = {k: v.replace("ABS", str(secret)) for k, v in kw.items()}
    xml = _model(tmp_path, **kw)
    (xml.parent / "out").symlink_to(tmp_path, target_is_directory=True)
    (xml.parent / "link.png").symlink_to(secret)
    with pytest.raises(KinmoDataError) as e:
        read_parts(xml)
    msg = str(e.value)
    assert msg.startswith(str(xml)) and problem in msg and "\n" not in msg
    assert "inside the model's folder" in msg and opened == []  # refused before MuJoCo opens it


def test_meshes_up_and_back_into_the_folder_and_textures_outside_it_load(tmp_path):
    """Meta-World names ``../objects/meshes/...`` from ``objects/`` (up, then back inside);
    robosuite names ``../textures/*.png`` beside the model's folder. Textures are never
    opened, so one that does not exist at all loads too."""
    write_mesh(tmp_path / "objects" / "meshes" / "door.stl", offset=(0, 0, 3))
    xml = tmp_path / "objects" / "door.xml"
    xml.write_text(
        '<mujoco><asset><texture name="wood" type="cube" file="../textures/wood.png"/>'
        '<texture name="sky" type="skybox" builtin="gradient" width="8" height="8"/>'
        '<material name="m" texture="wood"/><mesh name="d" file="../objects/meshes/door.stl"/></asset>'
        '<worldbody><geom type="box" size="1 1 1" material="m"/><body name="door"><joint type="hinge"/>'
        '<geom type="mesh" mesh="d" material="m"/></body></worldbody></mujoco>')
    parts = dict((n, v) for n, v, _ in read_parts(xml))
    assert list(parts) == ["world", "door"] and not (tmp_path / "textures").exists()
    np.testing.assert_allclose(parts["door"].min(0), [-0.5, -0.5, 2.5], atol=1e-6)
    # robosuite's cabinet.xml uses materials its arena defines: no geometry is lost without them
    xml.write_text('<mujoco><worldbody><geom type="box" size="1 1 1" material="MatRedWood"/>'
                   '<body name="drawer" pos="0 0 3"><joint type="slide"/><geom type="box" size="1 1 1" '
                   'material="MatCeramic"/><site name="s" material="MatRedWood"/></body></worldbody></mujoco>')
    assert [n for n, _, _ in read_parts(xml)] == ["world", "drawer"]


def test_a_hostile_included_file_is_checked_too(tmp_path):
    xml = _model(tmp_path, extra='<include file="inc/a.xml"/>')
    (xml.parent / "inc").mkdir()
    (xml.parent / "inc" / "a.xml").write_text('<mujoco><include file="../../x.xml"/></mujoco>')
    with pytest.raises(KinmoDataError, match=r"a.xml: <include file> '../../x.xml' refused"):
        read_parts(xml)
    (xml.parent / "inc" / "a.xml").write_text('<!DOCTYPE m [<!ENTITY a "b">]><mujoco/>')
    with pytest.raises(KinmoDataError, match="entity"):
        read_parts(xml)
    (xml.parent / "inc" / "a.xml").write_text('<mujoco><include file="inc/a.xml"/></mujoco>')
    with pytest.raises(KinmoDataError, match="included twice"):
        read_parts(xml)


def test_a_mesh_over_the_triangle_limit_is_refused(tmp_path, monkeypatch):
    trimesh.creation.icosphere(subdivisions=3).export(tmp_path / "ball.stl")  # 1280 faces
    xml = tmp_path / "m.xml"
    xml.write_text('<mujoco><asset><mesh name="m" file="ball.stl"/></asset><worldbody>'
                   '<geom type="mesh" mesh="m"/><body><geom type="box" size="1 1 1"/></body>'
                   "</worldbody></mujoco>")
    assert len(read_parts(xml)) == 2
    monkeypatch.setenv("KINMO_MAX_TRIANGLES", "1000")
    with pytest.raises(KinmoDataError, match="triangles per mesh exceeds the limit"):
        read_parts(xml)
