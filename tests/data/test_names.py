"""Names read from input files are names, never paths (kinmo.data.names, kinmo.data.readers)."""

from __future__ import annotations

import json
import os
import shutil
import unicodedata
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from kinmo.data.names import check_mesh_name, clean_text, inside, name_problem
from kinmo.data.readers import find_shapes, read_hierarchy, read_shape
from kinmo.errors import KinmoDataError

HOSTILE = ["../../../../probe/victim", "..", ".", "", "a/b", "a\\b", "/etc/passwd", "C:evil",
           "nul\x00byte", "ctl\x01char", "new\nline", "x" * 300, 7, None]


@pytest.mark.parametrize("name", HOSTILE)
def test_hostile_names_are_refused(name):
    assert name_problem(name) is not None
    with pytest.raises(KinmoDataError, match=r"^f\.json: mesh name .* of leaf node 3 .*not a path$"):
        check_mesh_name(name, "f.json", "leaf node 3")


@pytest.mark.parametrize("name", ["original-29", "new-3", "part_0", "tür 2", "a.b", "ü" * 50])
def test_plain_names_are_kept(name):
    assert check_mesh_name(name, "f.json", "leaf node 3") == name


@given(st.text(min_size=1, max_size=60))
def test_an_accepted_name_never_leaves_its_folder(tmp_path_factory, name):
    base = tmp_path_factory.getbasetemp() / "names"
    if name_problem(name) is None:
        assert inside(base / "objs" / f"{name}.obj", base / "objs")
        assert Path(f"{name}.obj").name == f"{name}.obj"  # one path component


def test_inside_resolves_links(tmp_path):
    (tmp_path / "folder").mkdir()
    (tmp_path / "outside.obj").write_text("v 0 0 0\n")
    (tmp_path / "folder" / "link.obj").symlink_to(tmp_path / "outside.obj")
    assert not inside(tmp_path / "folder" / "link.obj", tmp_path / "folder")
    assert inside(tmp_path / "folder" / "missing.obj", tmp_path / "folder")
    (tmp_path / "alias").symlink_to(tmp_path / "folder", target_is_directory=True)
    assert inside(tmp_path / "alias" / "x.obj", tmp_path / "folder")


def _shape(tmp_path: Path, partnet_root: Path) -> Path:
    """A copy of the data's first PartNet shape with a ``result.json`` (any one will do)."""
    src = next(f for f in find_shapes(partnet_root) if (f / "result.json").is_file())
    dst = tmp_path / src.name
    shutil.copytree(src, dst)
    return dst


def _first_leaf(doc: list) -> dict:
    node = doc[0]
    while node.get("children"):
        node = node["children"][0]
    return node


def test_read_hierarchy_names_the_file_and_the_name(tmp_path, partnet_root):
    shape = _shape(tmp_path, partnet_root)
    doc = json.loads((shape / "result.json").read_text())
    _first_leaf(doc)["objs"] = ["../../x"]
    (shape / "result.json").write_text(json.dumps(doc))
    with pytest.raises(KinmoDataError) as e:
        read_hierarchy(shape / "result.json")
    msg = str(e.value)
    assert msg.startswith(str(shape / "result.json")) and "'../../x'" in msg and "\n" not in msg


def test_mesh_links_leaving_the_shape_folder_are_refused(tmp_path, partnet_root):
    shape = _shape(tmp_path, partnet_root)
    outside = tmp_path / "elsewhere.obj"
    mesh = min((shape / "objs").glob("*.obj"))
    shutil.copyfile(mesh, outside)
    mesh.unlink()
    mesh.symlink_to(outside)
    with pytest.raises(KinmoDataError, match="symbolic link that leaves the shape folder"):
        read_shape(shape)
    # a link inside the folder, and a shape folder that is itself a link, are fine
    mesh.unlink()
    os.link(outside, mesh)  # a hard link is a file of the folder
    assert read_shape(shape).hierarchy.nodes
    (tmp_path / "alias").symlink_to(shape, target_is_directory=True)
    assert read_shape(tmp_path / "alias").id == "alias"


@given(st.text(max_size=40) | st.text(st.characters(max_codepoint=127), max_size=40))
def test_clean_text_replaces_exactly_the_control_characters(text):
    # the definition, character by character (the function returns printable ASCII as it is)
    want = "".join(" " if unicodedata.category(c) == "Cc" or c in "\ufffe\uffff" else c
                   for c in text.encode("utf-8", "backslashreplace").decode("utf-8"))
    assert clean_text(text) == want
    assert clean_text("link_3 rotation_door") == "link_3 rotation_door"
    assert clean_text("a\tb\x7fc\x85d") == "a b c d"
