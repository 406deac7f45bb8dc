"""bench/foreign_assets.py (issue 36): a repository at its commit becomes self-contained MJCF
folders, one per jointed object, with their meshes copied and the sources recorded."""

from __future__ import annotations

import importlib.util
import json
import subprocess
from pathlib import Path

import numpy as np

from kinmo.assets import read_parts

REPO = Path(__file__).resolve().parent.parent


def _script():
    spec = importlib.util.spec_from_file_location("foreign_assets", REPO / "bench" / "foreign_assets.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


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
    git = ["git", "-C", str(root), "-c", "user.name=t", "-c", "user.email=t@t"]
    subprocess.run(["git", "init", "-q", str(root)], check=True)
    subprocess.run([*git, "add", "-A"], check=True)
    subprocess.run([*git, "commit", "-qm", "fake"], check=True)
    return subprocess.run([*git, "rev-parse", "HEAD"], check=True, capture_output=True, text=True).stdout.strip()


def test_a_repository_at_its_commit_becomes_one_folder_per_jointed_object(tmp_path, monkeypatch):
    mod = _script()
    commit = _fake_furniture_repo(tmp_path / "src" / "fake")
    manifest = tmp_path / "sources.json"
    manifest.write_text(json.dumps({"sources": [{
        "name": "furniture_sim", "repo": "owner/fake", "commit": commit, "license": "Apache-2.0",
        "license_file": "LICENSE", "kind": "furniture_sim", "root": "", "exclude": []}]}))
    monkeypatch.setattr(mod, "SOURCES", manifest)
    out = tmp_path / "out"
    assert mod.main(["--out", str(out), "--cache", str(tmp_path / "cache"),
                     "--git-base", str(tmp_path / "src" / "{name}")]) == 0
    rows = json.loads((out / "sources.json").read_text())["objects"]
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
