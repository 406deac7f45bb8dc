"""Readers of PartNet / PartNet-Mobility folders: real data and every kind of bad input."""

from __future__ import annotations

import json
import shutil
from collections import Counter
from pathlib import Path

import numpy as np
import pytest

from kinmo.data.model import JointType, ShapeFormat
from kinmo.data.readers import detect_format, find_shapes, read_hierarchy, read_shape
from kinmo.errors import KinmoDataError


# ------------------------------------------------------------------------------ real data


def test_every_real_object_parses(mobility_root: Path, data_facts: dict[str, int]) -> None:
    folders = find_shapes(mobility_root)
    assert len(folders) == data_facts["mobility_objects"]
    assert folders == sorted(folders)
    joints: Counter = Counter()
    rotating = 0
    n_leaves = []
    categories = set()
    moving = 0
    for f in folders:
        s = read_shape(f)
        assert s.format is ShapeFormat.PARTNET_MOBILITY
        assert s.mesh_dir == f / "textured_objs"
        assert s.id == f.name
        categories.add(s.category)
        h = s.hierarchy
        assert h.order[0] == h.root and sorted(h.order) == sorted(h.nodes)
        n_leaves.append(len(h.leaves(h.root)))
        for lk in s.links:
            joints[lk.joint.type.value] += 1
            if lk.joint.is_moving:
                moving += 1
                assert np.isclose(np.linalg.norm(lk.joint.direction), 1.0)
                if lk.joint.limit is not None:
                    assert lk.joint.limit[0] <= lk.joint.limit[1]
            else:
                assert lk.joint.direction is None
            rotating += lk.joint.rotates
    # The joint kinds the data's README lists, and only hinges and sliders move.
    assert set(joints) == {"slider", "hinge", "free", "heavy", "static", "junk"}
    assert moving == joints["slider"] + joints["hinge"]
    assert rotating == data_facts["rotating_sliders"]
    assert (min(n_leaves), max(n_leaves)) == (data_facts["min_leaves"], data_facts["max_leaves"])
    assert len(categories) == data_facts["mobility_categories"]


def test_every_real_partnet_shape_parses(partnet_root: Path, data_facts: dict[str, int]) -> None:
    folders = find_shapes(partnet_root)
    assert len(folders) == data_facts["partnet_shapes"]
    cats = set()
    for f in folders:
        s = read_shape(f)
        assert s.format is ShapeFormat.PARTNET and s.links is None
        assert s.mesh_dir == f / "objs"
        cats.add(s.category)
        for nid in s.hierarchy.order:
            for name in s.hierarchy.nodes[nid].objs:
                assert s.mesh_path(name).is_file()
    assert len(cats) == data_facts["partnet_categories"]


def test_find_shapes_nested_and_single(
    shared_data: Path, mobility_root: Path, data_facts: dict[str, int]
) -> None:
    both = find_shapes(shared_data)
    assert len(both) == data_facts["mobility_objects"] + data_facts["partnet_shapes"]
    one = both[0]  # any shape folder
    assert find_shapes(one) == [one]
    with pytest.raises(KinmoDataError, match="not a folder"):
        find_shapes(shared_data / "no-such-folder")


def test_non_unit_axes_are_normalised(mobility_root: Path, data_facts: dict[str, int]) -> None:
    n_axes = n_non_unit = 0
    for f in find_shapes(mobility_root):
        raw = {r["id"]: r for r in json.loads((f / "mobility_v2.json").read_text())}
        for lk in read_shape(f).links:
            axis = raw[lk.id]["jointData"].get("axis")
            if axis is None:
                continue
            d = np.asarray(axis["direction"], float)
            n_axes += 1
            n_non_unit += abs(np.linalg.norm(d) - 1.0) > 1e-12
            if lk.joint.is_moving:
                assert np.isclose(np.linalg.norm(lk.joint.direction), 1.0, atol=1e-15)
                assert np.allclose(lk.joint.direction, d / np.linalg.norm(d))
    # The data's README: N of the M axis directions are not of unit length (some of them the
    # zero placeholders of heavy/junk links, which carry no axis once read).
    assert (n_axes, n_non_unit) == (data_facts["axes"], data_facts["non_unit_axes"])


def test_merged_hierarchy_option(partnet_root: Path, mobility_root: Path) -> None:
    # A PartNet shape whose merged file has other node ids than result.json.
    for f in find_shapes(partnet_root):
        if (f / "result_after_merging.json").is_file():
            a = read_shape(f).hierarchy
            b = read_shape(f, hierarchy="merged").hierarchy
            if set(a.nodes) != set(b.nodes):
                assert set(b.nodes) == set(read_hierarchy(f / "result_after_merging.json").nodes)
                break
    else:
        raise AssertionError("no PartNet shape with a different merged hierarchy")
    # PartNet-Mobility keeps result.json, whose ids mobility_v2.json refers to.
    for f in find_shapes(mobility_root):
        if (f / "result_after_merging.json").is_file():
            s = read_shape(f, hierarchy="merged")
            assert set(s.hierarchy.nodes) == set(read_hierarchy(f / "result.json").nodes)
    with pytest.raises(ValueError):
        read_shape(f, hierarchy="other")  # type: ignore[arg-type]


def test_fallback_to_merged_when_result_absent(partnet_root: Path, tmp_path: Path) -> None:
    src = next(f for f in find_shapes(partnet_root) if (f / "result_after_merging.json").is_file())
    dst = tmp_path / src.name
    shutil.copytree(src, dst)
    (dst / "result.json").unlink()
    s = read_shape(dst)
    assert set(s.hierarchy.nodes) == set(read_hierarchy(src / "result_after_merging.json").nodes)


# ----------------------------------------------------------------------------- synthetic


def test_cabinet_fields(cabinet: Path) -> None:
    s = read_shape(cabinet)
    assert detect_format(cabinet) is ShapeFormat.PARTNET_MOBILITY
    assert s.category == "StorageFurniture"
    assert s.hierarchy.order == [0, 1, 2, 3, 4, 5, 6, 7]
    assert s.hierarchy.nodes[5].objs == ("drawer_front", "drawer_box")
    links = {lk.id: lk for lk in s.links}
    door = links[0].joint
    assert door.type is JointType.HINGE
    assert np.allclose(door.direction, [0, 1, 0]) and np.allclose(door.origin, [0, 0.3, 0.51])
    assert door.limit == (0.0, 90.0)
    assert links[2].joint.limit is None  # noLimit
    assert links[1].joint.limit == (0.0, 0.3) and not links[1].joint.rotates
    assert links[3].joint.type is JointType.HEAVY and links[3].joint.origin is None
    assert links[0].parts == (2,)


def test_missing_meta_gives_unknown_category(cabinet: Path) -> None:
    (cabinet / "meta.json").unlink()
    assert read_shape(cabinet).category == "unknown"


def test_rotating_slider_is_cylindrical(cabinet: Path) -> None:
    links = json.loads((cabinet / "mobility_v2.json").read_text())
    links[1]["jointData"]["limit"].update(rotates=True, noRotationLimit=False, rotationLimit=180)
    (cabinet / "mobility_v2.json").write_text(json.dumps(links))
    j = {lk.id: lk for lk in read_shape(cabinet).links}[1].joint
    assert j.rotates and j.rotation_limit == 180.0


def test_partnet_format(tmp_path: Path, cabinet: Path) -> None:
    p = tmp_path / "partnet_shape"
    p.mkdir()
    shutil.copytree(cabinet / "textured_objs", p / "objs")
    shutil.copy(cabinet / "result.json", p / "result.json")
    s = read_shape(p)
    assert s.format is ShapeFormat.PARTNET and s.links is None and s.category == "unknown"


def _edit_json(path: Path, fn) -> None:
    path.write_text(json.dumps(fn(json.loads(path.read_text()))))


def _link(doc: list, lid: int) -> dict:
    return next(r for r in doc if r["id"] == lid)


BAD_INPUTS = {
    # name: (mutation of the cabinet folder, file named in the error, text in the problem)
    "malformed_json": (
        lambda c: (c / "result.json").write_text('[{"id": 0,\n "children": [}]'),
        "result.json", "malformed JSON at line 2 column",
    ),
    "empty_hierarchy": (
        lambda c: (c / "result.json").write_text("[]"), "result.json", "empty hierarchy",
    ),
    "duplicate_node_id": (
        lambda c: _edit_json(c / "result.json", lambda d: (
            d[0]["children"][1]["children"][1].update(id=1), d)[1]),
        "result.json", "duplicate node id 1",
    ),
    "leaf_without_objs": (
        lambda c: _edit_json(c / "result.json", lambda d: (
            d[0]["children"][0].pop("objs"), d)[1]),
        "result.json", "leaf node 1",
    ),
    "missing_mesh": (
        lambda c: (c / "textured_objs" / "knob.obj").unlink(), "textured_objs/knob.obj",
        "mesh file is missing",
    ),
    "unknown_joint_type": (
        lambda c: _edit_json(c / "mobility_v2.json", lambda d: (
            _link(d, 1).update(joint="prismatic"), d)[1]),
        "mobility_v2.json", "unknown joint type 'prismatic'",
    ),
    "zero_length_axis": (
        lambda c: _edit_json(c / "mobility_v2.json", lambda d: (
            _link(d, 0)["jointData"]["axis"].update(direction=[0, 0, 0]), d)[1]),
        "mobility_v2.json", "zero-length axis",
    ),
    "unknown_part_id": (
        lambda c: _edit_json(c / "mobility_v2.json", lambda d: (
            _link(d, 1)["parts"].append({"id": 42}), d)[1]),
        "mobility_v2.json", "node id 42",
    ),
    "leaf_in_two_links": (
        lambda c: _edit_json(c / "mobility_v2.json", lambda d: (
            _link(d, 1)["parts"].append({"id": 3}), d)[1]),
        "mobility_v2.json", "belongs to links",
    ),
    "unknown_parent_link": (
        lambda c: _edit_json(c / "mobility_v2.json", lambda d: (
            _link(d, 1).update(parent=9), d)[1]),
        "mobility_v2.json", "unknown parent link 9",
    ),
    "malformed_mobility": (
        lambda c: (c / "mobility_v2.json").write_text("[{"), "mobility_v2.json",
        "malformed JSON at line 1 column 3",
    ),
    "malformed_meta": (
        lambda c: (c / "meta.json").write_text("{'model_cat': 1}"), "meta.json",
        "malformed JSON",
    ),
    "no_mesh_folder": (
        lambda c: shutil.rmtree(c / "textured_objs"), "textured_objs", "folder is missing",
    ),
}


@pytest.mark.parametrize("case", sorted(BAD_INPUTS))
def test_bad_input_names_the_file(case: str, cabinet: Path) -> None:
    mutate, file, problem = BAD_INPUTS[case]
    mutate(cabinet)
    with pytest.raises(KinmoDataError) as info:
        read_shape(cabinet)
    err = info.value
    assert err.path == str(cabinet / file)
    assert problem in err.problem
    assert "\n" not in str(err)


def test_junk_links_with_zero_axes_are_accepted(cabinet: Path) -> None:
    _edit_json(cabinet / "mobility_v2.json", lambda d: d + [
        {"id": 9, "parent": -1, "joint": "junk", "name": "outlier", "parts": [],
         "jointData": {"axis": {"origin": [0, 0, 0], "direction": [0, 0, 0]},
                       "limit": {"a": 0, "b": 0, "noLimit": False}}}])
    links = read_shape(cabinet).links
    assert links[-1].joint.type is JointType.JUNK and links[-1].joint.direction is None
