"""bench/foreign_assets.py (issue 36): a repository at its commit becomes self-contained MJCF
folders, one per jointed object, with their meshes copied and the sources recorded."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import numpy as np
import pytest

from kinmo.assets import read_parts
from repo_scripts import load_script


def _script():
    return load_script("bench/foreign_assets.py")


def _commit(root: Path) -> str:
    """``root`` made a git repository with one commit of everything in it; returns the commit."""
    git = ["git", "-C", str(root), "-c", "user.name=t", "-c", "user.email=t@t"]
    subprocess.run(["git", "init", "-q", str(root)], check=True)
    subprocess.run([*git, "add", "-A"], check=True)
    subprocess.run([*git, "commit", "-qm", "fake"], check=True)
    return subprocess.run([*git, "rev-parse", "HEAD"], check=True, capture_output=True, text=True).stdout.strip()


def _build(tmp_path: Path, monkeypatch, source: dict) -> list[dict]:
    """Run the script on a manifest of ``source`` (repositories under ``tmp_path/src``) into
    ``tmp_path/out``; returns the rows of its ``sources.json``."""
    mod = _script()
    manifest = tmp_path / "sources.json"
    manifest.write_text(json.dumps({"sources": [source]}))
    monkeypatch.setattr(mod, "SOURCES", manifest)
    out = tmp_path / "out"
    assert mod.main(["--out", str(out), "--cache", str(tmp_path / "cache"),
                     "--git-base", str(tmp_path / "src" / "{name}")]) == 0
    return json.loads((out / "sources.json").read_text())["objects"]


def _fake_furniture_repo(root: Path) -> str:
    """A furniture_sim-like repository: a cabinet asset file (a mesh, a texture), two body
    variants (one with a hinge door, one without joints). Returns its commit."""
    import trimesh

    cab = root / "cab"
    (cab / "meshes").mkdir(parents=True)
    trimesh.creation.box((0.4, 0.4, 0.02)).export(cab / "meshes" / "door.stl")
    (cab / "cab_asset.xml").write_text(
        '<mujocoinclude><asset><mesh name="door" file="../furniture_sim/cab/meshes/door.stl"/>'
        '<texture name="wood" type="2d" file="../furniture_sim/cab/wood.png"/>'
        '<material name="wood" texture="wood"/></asset></mujocoinclude>')
    (cab / "cab_body0.xml").write_text(
        '<mujocoinclude><body name="carcass"><geom type="box" size="0.2 0.2 0.2"/>'
        '<body name="door" pos="0.21 0 0"><joint name="hinge" type="hinge" axis="0 0 1"/>'
        '<geom type="mesh" mesh="door" material="wood" euler="0 1.5707963 0"/></body></body></mujocoinclude>')
    (cab / "cab_body1.xml").write_text(
        '<mujocoinclude><body name="block"><geom type="box" size="0.2 0.2 0.2"/></body></mujocoinclude>')
    (root / "LICENSE").write_text("Apache License 2.0 (test)\n")
    return _commit(root)


def test_a_repository_at_its_commit_becomes_one_folder_per_jointed_object(tmp_path, monkeypatch):
    commit = _fake_furniture_repo(tmp_path / "src" / "fake")
    rows = _build(tmp_path, monkeypatch, {
        "name": "furniture_sim", "repo": "owner/fake", "commit": commit, "license": "Apache-2.0",
        "license_file": "LICENSE", "kind": "furniture_sim", "root": "", "exclude": []})
    out = tmp_path / "out"
    assert [r["id"] for r in rows] == ["furniture_sim-cab0"]  # the jointless variant is left out
    assert rows[0]["commit"] == commit and rows[0]["joints"] == [{"name": "hinge", "type": "hinge"}]
    assert (out / "LICENSES" / "furniture_sim").read_text().startswith("Apache")
    folder = out / "furniture_sim-cab0"
    copied = sorted(p.name for p in (folder / "assets").iterdir())
    assert any(n.endswith("door.stl") for n in copied) and any(n.endswith("wood.png") for n in copied)
    # self-contained: no path leaves the folder, and kinmo reads the door and the carcass
    assert "../" not in (folder / "model.xml").read_text()
    parts = {n: v for n, v, _ in read_parts(folder / "model.xml")}
    assert set(parts) == {"carcass", "door"}
    assert np.ptp(parts["door"], axis=0)[0] < 0.05  # the door mesh turned as the model says (radians, as furniture_sim compiles)


def test_a_urdf_scene_is_cut_into_one_package_per_jointed_subtree(tmp_path, monkeypatch):
    import trimesh

    root = tmp_path / "src" / "maps"
    pkg = root / "apt"
    (pkg / "meshes").mkdir(parents=True)
    (pkg / "urdf").mkdir()
    (pkg / "package.xml").write_text("<package><name>apt</name><license>MIT</license></package>")
    trimesh.creation.box((0.4, 0.4, 0.02)).export(pkg / "meshes" / "door.obj")
    (pkg / "urdf" / "scene.urdf").write_text("""<robot name="scene">
  <link name="root"/><link name="side"/>
  <link name="cab"><visual><geometry><box size="0.4 0.4 0.4"/></geometry></visual></link>
  <link name="door"><visual><geometry><mesh filename="package://apt/meshes/door.dae"/></geometry></visual>
    <collision><geometry><mesh filename="package://apt/meshes/door.obj"/></geometry></collision></link>
  <link name="shelf"><visual><geometry><box size="0.4 0.4 0.02"/></geometry></visual></link>
  <joint name="j_side" type="fixed"><parent link="root"/><child link="side"/><origin xyz="5 0 0" rpy="0 0 1.5707963267948966"/></joint>
  <joint name="j_cab" type="fixed"><parent link="side"/><child link="cab"/><origin xyz="1 0 0"/></joint>
  <joint name="hinge" type="revolute"><parent link="cab"/><child link="door"/><origin xyz="0.2 0 0"/>
    <axis xyz="0 0 1"/><limit lower="0" upper="1.5" effort="1" velocity="1"/></joint>
  <joint name="j_shelf" type="fixed"><parent link="side"/><child link="shelf"/></joint>
</robot>
""")
    (root / "LICENSE").write_text("MIT\n")
    commit = _commit(root)
    rows = _build(tmp_path, monkeypatch, {
        "name": "apt", "repo": "owner/maps", "commit": commit, "license": "MIT", "license_file": "LICENSE",
        "kind": "urdf_split", "root": "apt", "urdf": "apt/urdf/scene.urdf", "package": "apt",
        "package_dir": "apt", "split": ["side"]})
    out = tmp_path / "out"
    assert [r["id"] for r in rows] == ["apt-cab"]  # the shelf has no joint below it
    assert rows[0]["joints"] == [{"name": "hinge", "type": "revolute"}]
    folder = out / "apt-cab"
    assert (folder / "package.xml").is_file() and (folder / "meshes" / "door.obj").is_file()
    # the .dae visual is dropped for the collision mesh; package:// resolves inside the folder
    assert ".dae" not in (folder / "model.urdf").read_text()
    parts = {n: v for n, v, _ in read_parts(folder / "model.urdf")}
    assert set(parts) == {"cab", "door"}
    assert np.allclose(parts["cab"].mean(0)[:2], [5, 1], atol=1e-6)  # the scene pose kept (up stays up)


def test_a_urdf_without_split_is_one_object(tmp_path, monkeypatch):
    """IsaacGymEnvs' cabinet is a whole URDF: without ``split`` its root link is the object,
    with every joint below it (the fixed handle kept, only the moving joint counted)."""
    root = tmp_path / "src" / "gym"
    pkg = root / "assets" / "cab_model"
    (pkg / "urdf").mkdir(parents=True)
    (pkg / "package.xml").write_text("<package><name>cab_model</name></package>")
    (pkg / "urdf" / "cab.urdf").write_text("""<robot name="cab">
  <link name="body"><visual><geometry><box size="0.4 0.4 0.4"/></geometry></visual></link>
  <link name="drawer"><visual><geometry><box size="0.3 0.3 0.1"/></geometry></visual></link>
  <link name="handle"><visual><geometry><box size="0.02 0.1 0.02"/></geometry></visual></link>
  <joint name="slide" type="prismatic"><parent link="body"/><child link="drawer"/><origin xyz="0.05 0 0"/>
    <axis xyz="1 0 0"/><limit lower="0" upper="0.3" effort="1" velocity="1"/></joint>
  <joint name="fix" type="fixed"><parent link="drawer"/><child link="handle"/><origin xyz="0.16 0 0"/></joint>
</robot>
""")
    (root / "LICENSE.txt").write_text("BSD\n")
    commit = _commit(root)
    rows = _build(tmp_path, monkeypatch, {
        "name": "gym", "repo": "owner/gym", "commit": commit, "license": "BSD-3-Clause",
        "license_file": "LICENSE.txt", "kind": "urdf_split", "root": "assets/cab_model",
        "urdf": "assets/cab_model/urdf/cab.urdf", "package": "cab_model", "package_dir": "assets/cab_model"})
    out = tmp_path / "out"
    assert [r["id"] for r in rows] == ["gym-body"]
    assert rows[0]["joints"] == [{"name": "slide", "type": "prismatic"}]
    parts = {n: v for n, v, _ in read_parts(out / "gym-body" / "model.urdf")}
    assert set(parts) == {"body", "drawer", "handle"}
    assert parts["handle"].mean(0)[0] == pytest.approx(0.21)  # placed through both joints


def test_stand_alone_object_files_with_massless_moving_bodies_are_staged(tmp_path, monkeypatch):
    # LIBERO's layout (the held-out set, kind mjcf_files): one object per file, its meshes
    # in a folder beside it, moving bodies without inertials; a file MuJoCo refuses is skipped
    import trimesh

    root = tmp_path / "src" / "fake" / "objs"
    (root / "box").mkdir(parents=True)
    trimesh.creation.box((0.4, 0.02, 0.4)).export(root / "box" / "door.stl")
    (root / "cab.xml").write_text(
        '<mujoco model="cab"><compiler meshdir="./"/><asset><mesh name="door" file="box/door.stl"/></asset>'
        '<worldbody><body name="carcass"><geom type="box" size="0.2 0.2 0.2"/>'
        '<body name="door" pos="0 0.21 0"><joint name="hinge" type="hinge" axis="0 0 1"/>'
        '<geom type="mesh" mesh="door" contype="0" conaffinity="0" density="0"/></body></body>'
        "</worldbody></mujoco>")
    (root / "bad.xml").write_text('<mujoco model="bad"><worldbody><region/></worldbody></mujoco>')
    (root.parent / "LICENSE").write_text("MIT (test)\n")
    commit = _commit(root.parent)
    rows = _build(tmp_path, monkeypatch, {
        "name": "libero", "repo": "owner/fake", "commit": commit, "license": "MIT", "license_file": "LICENSE",
        "kind": "mjcf_files", "root": "objs", "exclude": []})
    assert [r["id"] for r in rows] == ["libero-cab"] and rows[0]["joints"] == [{"name": "hinge", "type": "hinge"}]
    folder = tmp_path / "out" / "libero-cab"
    assert any(p.name.endswith("door.stl") for p in (folder / "assets").iterdir())
    parts = {n: v for n, v, _ in read_parts(folder / "model.xml")}
    assert set(parts) == {"carcass", "door"}
    np.testing.assert_allclose(np.ptp(parts["door"], axis=0), [0.4, 0.02, 0.4], atol=1e-6)
