"""Fuzz test of hostile inputs (issue 21): random ``result.json`` / ``mobility_v2.json`` / OBJ /
glTF inputs with hostile names, cycles, huge counts and degenerate geometry.

Checked for every example: the readers raise nothing but :class:`~kinmo.errors.KinmoError`
(one line naming the file), nothing is written outside the output folder, and the limits
refuse huge counts before allocating. Derandomized (a fixed seed per test) so CI is stable;
about 10 s in all.
"""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

import pytest
from conftest import write_box_obj
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from kinmo.errors import KinmoError

SETTINGS = settings(max_examples=25, deadline=None, derandomize=True, database=None,
                    suppress_health_check=list(HealthCheck))

HOSTILE = st.sampled_from([
    "../../../probe/victim", "/etc/passwd", "..", ".", "a/b", "a\\b", "C:evil", "x\x00y",
    "[/]", "brk[old]", ":x:", "<!--<script>", "\u0001", "\u202e", "", " ", "a" * 300, "ok",
    "part\nname", "%2e%2e%2f",
])
NAMES = st.one_of(HOSTILE, st.text(alphabet="ab_-. 0[]:/\u00e9\u0001", min_size=0, max_size=8))


def _files(root: Path) -> set[Path]:
    return {p for p in root.rglob("*")}


@st.composite
def trees(draw):
    """A PartNet ``result.json`` tree: hostile names, duplicate ids, deep or wide, sometimes
    a node listing itself as its child (a cycle by id)."""
    n = draw(st.integers(1, 12))
    nodes = []
    for i in range(n):
        nodes.append({"id": draw(st.integers(0, n)) if draw(st.integers(0, 39)) == 0 else i,
                      "name": draw(NAMES), "text": draw(NAMES)})
    for i, node in enumerate(nodes[1:], 1):
        parent = nodes[draw(st.integers(0, i - 1))]
        parent.setdefault("children", []).append(node)
    for node in nodes:
        if "children" not in node:
            node["objs"] = draw(st.lists(st.one_of(st.just("box"), st.just("box"), st.just("box"),
                                                   st.just("box"), st.just("box"), NAMES),
                                         min_size=0 if draw(st.integers(0, 9)) == 0 else 1,
                                         max_size=3))
    if draw(st.integers(0, 9)) == 0:
        nodes[0].setdefault("children", []).append({"id": nodes[0]["id"], "objs": ["box"]})
    return [nodes[0]]


@st.composite
def mobility(draw, n_ids: int):
    links = []
    for i in range(draw(st.integers(0, 5))):
        links.append({
            "id": draw(st.integers(-1, 6)), "parent": draw(st.integers(-2, 6)),
            "joint": draw(st.sampled_from(["hinge", "slider", "heavy", "static", "free", "x"])),
            "name": draw(NAMES),
            "parts": [{"id": draw(st.integers(0, n_ids + 1))}],
            "jointData": draw(st.sampled_from([
                {}, {"axis": {"origin": [0, 0, 0], "direction": [0, 0, 0]}},
                {"axis": {"origin": [0, 0, 0], "direction": [0, 1, 0]},
                 "limit": {"a": 0, "b": 90, "noLimit": False}},
                {"axis": {"origin": ["nan", 0], "direction": [1e308, 1e308, 1e308]}},
            ])),
        })
    return links


@given(data=st.data())
@SETTINGS
def test_random_partnet_folders_fail_cleanly_and_write_only_into_out(tmp_path_factory, data):
    from kinmo.data.build import build_graph
    from kinmo.data.readers import read_shape

    base = tmp_path_factory.mktemp("fuzz")
    (base / "probe").mkdir()
    write_box_obj(base / "probe" / "victim.obj", (0, 0, 0), (1, 1, 1))
    folder = base / "data" / "shape"
    labelled = data.draw(st.booleans())
    meshes = folder / ("textured_objs" if labelled else "objs")
    meshes.mkdir(parents=True)
    write_box_obj(meshes / "box.obj", (0, 0, 0), (1, 1, 1))
    degenerate = data.draw(st.sampled_from(["", "v 0 0 0\nf 1 1 1\n", "v nan 0 0\n", None, None,
                                            None]))
    if degenerate is not None:
        (meshes / "ok.obj").write_text(degenerate)
    tree = data.draw(trees())
    (folder / "result.json").write_text(json.dumps(tree))
    if labelled:
        (folder / "mobility_v2.json").write_text(json.dumps(data.draw(mobility(12))))
    before = _files(base)
    victim = (base / "probe" / "victim.obj").read_bytes()
    out = base / "out"
    try:
        shape = read_shape(folder)
        graph = build_graph(shape, n_points=8)
        graph.save(out / "shape.npz")
        if shape.links:
            from kinmo.export import export

            export(shape, out / "obj", ["mobility_v2", "semantics"])
        outcome = "ok"
    except KinmoError as e:
        assert "\n" not in str(e).strip()
        outcome = type(e).__name__
        MESSAGES.append(str(e))
    OUTCOMES.append(outcome)
    after = _files(base)
    assert {p for p in after - before if out not in p.parents and p != out} == set()
    assert (base / "probe" / "victim.obj").read_bytes() == victim
    shutil.rmtree(base)


OUTCOMES: list[str] = []
MESSAGES: list[str] = []


def test_fuzz_reached_the_graph_builder():
    """The random folders are not all refused at the door: some built a graph (runs after
    the fuzz test above, in file order)."""
    assert "ok" in OUTCOMES and len(set(OUTCOMES)) >= 2, "\n".join(m.split("shape/")[-1] for m in MESSAGES)


@st.composite
def gltf_docs(draw):
    n = draw(st.integers(0, 8))
    nodes = []
    for _ in range(n):
        node: dict = {"name": draw(NAMES)}
        if draw(st.booleans()):
            node["mesh"] = draw(st.integers(-1, 2))
        if n and draw(st.booleans()):
            node["children"] = draw(st.lists(st.integers(-1, n), max_size=3))
        nodes.append(node)
    huge = draw(st.sampled_from([36, 3 * 10**9, -3, 2**63]))
    uri = draw(st.one_of(st.none(), HOSTILE))
    buf = {"byteLength": 12} | ({"uri": uri} if uri is not None else {})
    return {"asset": {"version": "2.0"}, "nodes": nodes, "buffers": [buf],
            "accessors": [{"count": huge, "type": "SCALAR", "componentType": 5125}],
            "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 0}]}],
            "scenes": [{"nodes": list(range(min(n, 2)))}], "scene": 0}


@given(doc=gltf_docs(), glb=st.booleans())
@SETTINGS
def test_random_gltf_scenes_fail_cleanly(tmp_path_factory, doc, glb):
    import struct

    from kinmo.assets import read_parts

    base = tmp_path_factory.mktemp("gltf")
    raw = json.dumps(doc).encode()
    raw += b" " * (-len(raw) % 4)
    if glb:
        path = base / "a.glb"
        path.write_bytes(struct.pack("<4sIIII", b"glTF", 2, 20 + len(raw), len(raw), 0x4E4F534A) + raw)
    else:
        path = base / "a.gltf"
        path.write_bytes(raw)
    before = _files(base)
    try:
        parts = read_parts(path)
        assert len(parts) >= 2
    except KinmoError as e:
        assert "\n" not in str(e).strip()
    assert _files(base) == before
    shutil.rmtree(base)


def test_huge_part_counts_are_refused_before_allocating(tmp_path, monkeypatch):
    """A result.json with a huge flat leaf list: refused by the parts limit, not by memory."""
    from kinmo.data.build import build_graph
    from kinmo.data.readers import read_shape

    monkeypatch.delenv("KINMO_MAX_PARTS", raising=False)
    folder = tmp_path / "shape"
    (folder / "objs").mkdir(parents=True)
    write_box_obj(folder / "objs" / "box.obj", (0, 0, 0), (1, 1, 1))
    n = 2001
    tree = [{"id": 0, "name": "root", "children": [
        {"id": i + 1, "name": "p", "objs": ["box"]} for i in range(n)]}]
    (folder / "result.json").write_text(json.dumps(tree))
    with pytest.raises(KinmoError, match="parts per shape exceeds the limit"):
        build_graph(read_shape(folder), n_points=8)
    assert os.listdir(tmp_path) == ["shape"]


# ---- issue 36: file references inside URDF and MJCF input -----------------------------------

REFS = st.one_of(HOSTILE, st.sampled_from([
    "meshes/a.obj", "./meshes/a.obj", "meshes//a.obj", "../meshes/a.obj", "../../../probe/victim.obj",
    "meshes/../../../probe/victim.obj", "meshes/victim.obj", "pkg/meshes/a.obj", "pkg/../probe/victim.obj",
]))


def _victim_layout(base: Path) -> Path:
    """``base/ws/pkg`` (a ROS package holding meshes/a.obj, and a link meshes/victim.obj to
    ``base/probe/victim.obj``, a box far away): returns the package folder."""
    pkg = base / "ws" / "pkg"
    (pkg / "meshes").mkdir(parents=True)
    (pkg / "package.xml").write_text("<package><name>pkg</name></package>")
    write_box_obj(pkg / "meshes" / "a.obj", (0, 0, 0), (1, 1, 1))
    (base / "probe").mkdir()
    write_box_obj(base / "probe" / "victim.obj", (100, 100, 100), (101, 101, 101))
    (pkg / "meshes" / "victim.obj").symlink_to(base / "probe" / "victim.obj")
    return pkg


def _only_inside(base: Path, read) -> None:
    """``read()`` either fails in one line or reads the box inside the package, never the victim."""
    import numpy as np

    before = _files(base)
    try:
        parts = read()
        assert float(np.concatenate([v for _, v, _ in parts]).max()) <= 1.0 + 1e-9
    except KinmoError as e:
        assert "\n" not in str(e).strip()
    assert _files(base) == before
    shutil.rmtree(base)


@given(prefix=st.sampled_from(["", "package://", "package://pkg/", "file://", "package://ws/"]), ref=REFS)
@SETTINGS
def test_random_urdf_mesh_references_stay_inside_their_root(tmp_path_factory, prefix, ref):
    from kinmo.assets import read_parts

    base = tmp_path_factory.mktemp("urdf")
    pkg = _victim_layout(base)
    (pkg / "r.urdf").write_text(
        '<robot name="r"><link name="a"><visual><geometry><box size="1 1 1"/></geometry></visual>'
        '<visual><origin xyz="0.5 0.5 0.5"/><geometry><box size="1 1 1"/></geometry></visual></link>'
        f'<link name="b"><visual><geometry><mesh filename="{_xml_attr(prefix + ref)}"/></geometry>'
        "</visual></link></robot>")
    _only_inside(base, lambda: read_parts(pkg / "r.urdf"))


@given(ref=REFS, meshdir=st.one_of(st.none(), st.sampled_from(["", ".", "meshes", "..", "/tmp"]), HOSTILE))
@SETTINGS
def test_random_mjcf_file_references_stay_inside_the_model_folder(tmp_path_factory, ref, meshdir):
    from kinmo.assets import read_parts

    base = tmp_path_factory.mktemp("mjcf")
    pkg = _victim_layout(base)
    compiler = "" if meshdir is None else f'<compiler meshdir="{_xml_attr(meshdir)}"/>'
    (pkg / "m.xml").write_text(
        f'<mujoco>{compiler}<asset><mesh name="m" file="{_xml_attr(ref)}"/></asset><worldbody>'
        '<geom type="box" size="0.5 0.5 0.5" pos="0.5 0.5 0.5"/><body><geom type="mesh" mesh="m"/>'
        "</body></worldbody></mujoco>")
    _only_inside(base, lambda: read_parts(pkg / "m.xml"))


def _xml_attr(text: str) -> str:
    """``text`` as an XML attribute value (characters XML cannot hold as character references
    are left for the parser to refuse)."""
    from xml.sax.saxutils import quoteattr

    return quoteattr(text)[1:-1]
