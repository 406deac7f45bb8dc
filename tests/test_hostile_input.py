"""Hostile inputs (issue 21, findings 4-12): each finding reproduced as a test.

Findings 1-2 (names as paths, outputs over inputs) are in ``tests/data/test_names.py`` and
``tests/test_io.py``; finding 3 (stale caches) with the cache readers.
"""

from __future__ import annotations

import json

import pytest
from conftest import write_cabinet
from typer.testing import CliRunner

from kinmo.cli import app

runner = CliRunner()


# ---- finding 6: printed names are literal text ------------------------------------------------

def test_literal_keeps_markup_brackets_and_emoji_codes():
    from kinmo.progress import console, literal

    c = console(record=True, width=200)
    for name in ("brk[old]/", "[/]", "a[red]b[/]", ":x:", "a\x01b"):
        c.print(f"[red]name[/] {literal(name)}")
    text = c.export_text()
    assert "brk[old]/" in text and "[/]" in text and "a[red]b[/]" in text
    assert ":x:" in text and "\u274c" not in text
    assert "a\\x01b" in text and "\x01" not in text


def test_prepare_prints_folder_names_with_markup_literally(tmp_path):
    data = tmp_path / "brk[" / "]:x:"
    write_cabinet(data / "a[red]")
    out = tmp_path / "out[" / "]"
    res = runner.invoke(app, ["prepare", str(data), "-o", str(out)])
    assert res.exit_code == 0, res.output
    flat = "".join(res.output.split())
    assert f"->{out}/manifest.csv".replace(" ", "") in flat
    assert "\u274c" not in res.output
    assert (out / "a[red].npz").is_file()


# ---- finding 8: option values checked up front; diverged training saves nothing ---------------

@pytest.mark.parametrize("args,needle", [
    (["--device", "foo"], "--device foo"),
    (["--device", "cuda:99"], "--device cuda:99"),
    (["--hinge-max", "nan"], "--hinge-max nan"),
    (["--ranker", "/etc/passwd"], "not a ranker file"),
])
def test_predict_refuses_bad_option_values_in_one_line(tiny_gnn, tmp_path, args, needle):
    res = runner.invoke(app, ["predict", str(tiny_gnn["data"]), "-m", str(tiny_gnn["run"]),
                              "-o", str(tmp_path / "out"), "-q", *args])
    assert res.exit_code == 2, res.output
    lines = [ln for ln in res.output.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("error:") and needle in lines[0], res.output
    assert "Traceback" not in res.output and not (tmp_path / "out").exists()


@pytest.mark.parametrize("lr", ["nan", "inf", "1e30", "0", "-1"])
def test_train_gnn_refuses_bad_learning_rates(tiny_gnn, tmp_path, lr):
    res = runner.invoke(app, ["train", "gnn", "-d", str(tiny_gnn["cache"]), "-o", str(tmp_path / "r"),
                              "-q", "--lr", lr])
    assert res.exit_code == 2, res.output
    assert res.output.startswith("error: --lr") and len(res.output.strip().splitlines()) == 1
    assert not (tmp_path / "r").exists()


def test_diverged_training_stops_and_saves_no_model(tiny_gnn, tmp_path):
    from kinmo.errors import KinmoTrainingError
    from kinmo.train.config import preset
    from kinmo.train.gnn import train_gnn
    from kinmo.train.split import Split

    cfg = preset("tiny", n_points=32, threads=1, epochs=3, batch_size=2, lr=1e30)
    with pytest.raises(KinmoTrainingError, match="diverged"):
        train_gnn(tiny_gnn["cache"], tmp_path / "run", cfg, split=Split(["c1", "c2"], []),
                  progress=False)
    assert not list(tmp_path.rglob("*.pt"))


# ---- finding 7 and the input rules: glTF node cycles, external URIs, URDF paths and entities --

def _gltf(path, nodes, uri=None, scenes=None):
    """A .gltf with one box mesh (12 triangles, embedded buffer) and the given node list."""
    import base64

    import numpy as np

    v = np.array([(x, y, z) for x in (0, 1) for y in (0, 1) for z in (0, 1)], np.float32)
    f = np.array([(0, 1, 3), (0, 3, 2), (4, 6, 7), (4, 7, 5), (0, 4, 5), (0, 5, 1),
                  (2, 3, 7), (2, 7, 6), (0, 2, 6), (0, 6, 4), (1, 5, 7), (1, 7, 3)], np.uint16)
    blob = v.tobytes() + f.tobytes()
    buf = {"byteLength": len(blob),
           "uri": uri or "data:application/octet-stream;base64," + base64.b64encode(blob).decode()}
    doc = {
        "asset": {"version": "2.0"},
        "buffers": [buf],
        "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": v.nbytes},
                        {"buffer": 0, "byteOffset": v.nbytes, "byteLength": f.nbytes}],
        "accessors": [{"bufferView": 0, "componentType": 5126, "count": 8, "type": "VEC3",
                       "min": [0, 0, 0], "max": [1, 1, 1]},
                      {"bufferView": 1, "componentType": 5123, "count": 36, "type": "SCALAR"}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
        "nodes": nodes,
        "scenes": scenes or [{"nodes": [0]}], "scene": 0,
    }
    path.write_text(json.dumps(doc))
    return path


def test_gltf_node_cycle_is_one_clear_error(tmp_path):
    from kinmo.errors import KinmoDataError
    from kinmo.assets import read_parts

    nodes = [{"mesh": 0, "children": [1]}, {"mesh": 0, "children": [2]},
             {"mesh": 0, "children": [0]}]
    f = _gltf(tmp_path / "cycle.gltf", nodes)
    with pytest.raises(KinmoDataError, match="cycle"):
        read_parts(f)
    res = runner.invoke(app, ["predict", str(f), "-m", str(tmp_path / "nomodel"), "-o",
                              str(tmp_path / "out"), "-q"])
    assert res.exit_code != 0 and "Traceback" not in res.output


def test_gltf_external_uri_outside_the_folder_is_refused(tmp_path):
    from kinmo.errors import KinmoDataError
    from kinmo.assets import read_parts

    nodes = [{"mesh": 0}, {"mesh": 0, "translation": [2, 0, 0]}]
    f = _gltf(tmp_path / "a.gltf", nodes, uri="../../etc/passwd",
              scenes=[{"nodes": [0, 1]}])
    with pytest.raises(KinmoDataError, match="uri '../../etc/passwd' refused"):
        read_parts(f)


def test_gltf_of_plain_parts_still_reads(tmp_path):
    from kinmo.assets import read_parts

    nodes = [{"mesh": 0, "children": [1]}, {"mesh": 0, "translation": [2, 0, 0]}]
    assert len(read_parts(_gltf(tmp_path / "ok.gltf", nodes))) == 2


def _urdf(folder, filename, doctype=""):
    from conftest import write_box_obj

    folder.mkdir(parents=True, exist_ok=True)
    write_box_obj(folder / "a.obj", (0, 0, 0), (1, 1, 1))
    (folder / "sub").mkdir(exist_ok=True)
    write_box_obj(folder / "sub" / "b.obj", (1, 0, 0), (2, 1, 1))
    text = f"""{doctype}<robot name="r">
  <link name="a"><visual><geometry><mesh filename="a.obj"/></geometry></visual></link>
  <link name="b"><visual><geometry><mesh filename="{filename}"/></geometry></visual></link>
  <joint name="j" type="revolute"><parent link="a"/><child link="b"/></joint>
</robot>"""
    (folder / "m.urdf").write_text(text)
    return folder / "m.urdf"


@pytest.mark.parametrize("filename", ["ABS", "../outside.obj", "sub/../../outside.obj",
                                      "package://../outside.obj", "package://sub/../../outside.obj",
                                      "package://foo/../../etc/passwd", "package://a\\b/x.obj",
                                      "file://ABS", "file://../outside.obj"])
def test_urdf_mesh_paths_outside_its_folder_are_refused(tmp_path, filename):
    from conftest import write_box_obj

    from kinmo.errors import KinmoDataError
    from kinmo.assets import read_parts

    write_box_obj(tmp_path / "outside.obj", (0, 0, 0), (1, 1, 1))
    filename = filename.replace("ABS", str(tmp_path / "outside.obj"))
    with pytest.raises(KinmoDataError, match="refused"):
        read_parts(_urdf(tmp_path / "asset", filename))


def test_urdf_relative_mesh_inside_its_folder_reads(tmp_path):
    from kinmo.assets import read_parts

    assert [p[0] for p in read_parts(_urdf(tmp_path / "asset", "package://sub/b.obj"))] == ["a", "b"]


def test_urdf_with_entities_is_refused(tmp_path):
    from kinmo.errors import KinmoDataError
    from kinmo.assets import read_parts

    bomb = ('<?xml version="1.0"?><!DOCTYPE r [<!ENTITY a "aaaaaaaaaa">'
            '<!ENTITY b "&a;&a;&a;&a;&a;&a;&a;&a;&a;&a;">]>\n')
    with pytest.raises(KinmoDataError, match="entity"):
        read_parts(_urdf(tmp_path / "asset", "sub/b.obj", doctype=bomb))


# ---- finding 10: control characters and markup in names of XML / HTML / Markdown writers ------

def _renamed_cabinet(tmp_path, name):
    from kinmo.data.readers import read_shape

    folder = write_cabinet(tmp_path / "cab")
    tree = json.loads((folder / "result.json").read_text())
    tree[0]["children"][1]["name"] = name  # the door
    tree[0]["children"][1]["text"] = name
    (folder / "result.json").write_text(json.dumps(tree))
    links = json.loads((folder / "mobility_v2.json").read_text())
    links[0]["name"] = name
    (folder / "mobility_v2.json").write_text(json.dumps(links))
    return read_shape(folder)


@pytest.mark.parametrize("fmt", ["urdf", "mjcf"])
def test_control_characters_in_names_keep_xml_well_formed(tmp_path, fmt):
    import xml.etree.ElementTree as ET

    from kinmo.export import ExportContext
    from kinmo.export.mjcf import mjcf_string
    from kinmo.urdf import urdf_string

    shape = _renamed_cabinet(tmp_path, "door\u0001\u001b[31m<x>&")
    if fmt == "urdf":
        text = urdf_string(shape, name="obj\u0002")
    else:
        ctx = ExportContext(shape, list(shape.links), tmp_path, "obj\u0002")
        text = mjcf_string(ctx, {lid: f"link_{lid}.obj" for lid in ctx.meshes})
    ET.fromstring(text.split("?>", 1)[-1])  # well-formed
    assert "\u0001" not in text and "\u0002" not in text and "\u001b" not in text


def test_viewer_json_cannot_end_or_remode_its_script_block():
    from kinmo.view import script_json

    blob = script_json({"name": "<!--<script></script>&"})
    assert "<" not in blob and ">" not in blob and "&" not in blob
    assert json.loads(blob) == {"name": "<!--<script></script>&"}


def test_view_page_of_a_hostile_part_name_keeps_its_sliders(tmp_path):
    from kinmo.view import view_folder

    shape = _renamed_cabinet(tmp_path, "<!--<script>")
    page = view_folder(shape.path)
    html_text = page.read_text()
    scripts = html_text.split("<script>")[1:]
    # every script block ends where kinmo ended it: no name opened a comment or a script
    assert all("<!--" not in s.split("</script>")[0] for s in scripts[2:])
    assert "kinmoView(" in html_text and html_text.rstrip().endswith("</html>")


def test_report_markdown_cells_escape_names():
    from kinmo.report.document import Document, Section, Table
    from kinmo.report.markdown import render_markdown

    doc = Document(title="t", meta=[], sections=[Section(id="s", title="s", blocks=[
        Table(columns=["shape"], rows=[["<img src=x onerror=alert(1)>|\u0001"]])])])
    md = render_markdown(doc)
    assert "<img src=x" not in md and "\u0001" not in md and "\\|" in md


# ---- findings 11 and 12: self-contained objects, one writer per OUT, objects appear whole ------

def test_exported_object_is_self_contained_and_loads_after_a_move(tmp_path):
    import shutil

    import pybullet as pb

    src = write_cabinet(tmp_path / "src" / "cab")
    out = tmp_path / "out"
    res = runner.invoke(app, ["export", str(src), "-f", "urdf", "-o", str(out)])
    assert res.exit_code == 0, res.output
    urdf = (out / "mobility.urdf").read_text()
    assert "../" not in urdf and str(tmp_path) not in urdf
    shutil.rmtree(tmp_path / "src")  # the source is gone ...
    moved = shutil.move(str(out), str(tmp_path / "elsewhere"))  # ... and the object moved
    assert not list(tmp_path.glob(".out.partial-*"))
    cid = pb.connect(pb.DIRECT)
    try:
        body = pb.loadURDF(str(tmp_path / "elsewhere" / "mobility.urdf"), physicsClientId=cid)
        assert pb.getNumJoints(body, physicsClientId=cid) >= 3
    finally:
        pb.disconnect(cid)
    assert moved


def test_export_refuses_an_out_another_run_is_writing(tmp_path):
    from kinmo.io import folder_lock

    src = write_cabinet(tmp_path / "src" / "cab")
    out = tmp_path / "out"
    out.mkdir()
    with folder_lock(out, "kinmo predict"):
        res = runner.invoke(app, ["export", str(src), "-f", "mjcf", "-o", str(out)])
    assert res.exit_code == 1 and "is writing this folder" in res.output
    assert not (out / "mobility.xml").exists()


def test_export_of_a_missing_source_creates_no_output_folder(tmp_path):
    res = runner.invoke(app, ["export", str(tmp_path / "missing"), "-f", "mjcf", "-o", str(tmp_path / "out")])
    assert res.exit_code == 2 and "does not exist" in res.output
    assert not (tmp_path / "out").exists()  # no OUT with a stray .lock


def test_staged_folder_appears_whole_or_not_at_all(tmp_path):
    from kinmo.io import staged_folder

    dst = tmp_path / "obj"
    with pytest.raises(RuntimeError):
        with staged_folder(dst) as tmp:
            (tmp / "collision").mkdir()
            raise RuntimeError("killed")
    assert not dst.exists() and not list(tmp_path.iterdir())
    with staged_folder(dst) as tmp:
        (tmp / "a.txt").write_text("1")
        assert not dst.exists()
    assert (dst / "a.txt").read_text() == "1"
    (dst / "keep.txt").write_text("k")
    with staged_folder(dst) as tmp:
        (tmp / "a.txt").write_text("2")
    assert (dst / "a.txt").read_text() == "2" and (dst / "keep.txt").is_file()
    assert [p.name for p in tmp_path.iterdir()] == ["obj"]


# ---- finding 9: parts a simulator cannot load ----------------------------------------------

def _with_flat_knob(tmp_path, lines):
    from kinmo.data.readers import read_shape

    folder = write_cabinet(tmp_path / "cab")
    (folder / "textured_objs" / "knob.obj").write_text("\n".join(lines) + "\n")
    return read_shape(folder)


@pytest.mark.parametrize("lines", [
    ["v 0.2 0.6 0.6", "v 0.3 0.6 0.6", "v 0.2 0.7 0.6", "f 1 2 3"],  # one triangle
    ["v 0.2 0.6 0.6", "v 0.3 0.6 0.6", "v 0.3 0.7 0.6", "v 0.2 0.7 0.6", "f 1 2 3", "f 1 3 4"],
])
def test_flat_parts_export_to_a_model_mujoco_loads(tmp_path, lines):
    import mujoco

    from kinmo.export import export

    shape = _with_flat_knob(tmp_path, lines)
    files = export(shape, tmp_path / "out", ["mjcf"])["mjcf"]
    model = mujoco.MjModel.from_xml_path(str(files[0]))
    assert model.nbody >= 4


def test_zero_area_part_is_refused_by_export_as_by_prepare(tmp_path):
    from kinmo.errors import KinmoDataError
    from kinmo.export.kinematics import link_meshes

    shape = _with_flat_knob(tmp_path, ["v 0.2 0.6 0.6", "v 0.3 0.6 0.6", "v 0.4 0.6 0.6",
                                       "f 1 2 3"])
    with pytest.raises(KinmoDataError, match="zero surface area"):
        link_meshes(shape)
    res = runner.invoke(app, ["prepare", str(shape.path), "-o", str(tmp_path / "c")])
    assert res.exit_code == 1 and "zero area" in " ".join(res.output.split())


# ---- finding 5: the convex decomposition of a many-link export shows progress ----------------

def test_export_of_many_links_shows_vhacd_progress(tmp_path, monkeypatch):
    import kinmo.export.urdf as export_urdf

    monkeypatch.setattr(export_urdf, "PIECES_BAR_MIN_LINKS", 2)
    src = write_cabinet(tmp_path / "src" / "cab")
    monkeypatch.setenv("KINMO_VHACD_CACHE", str(tmp_path / "cache"))
    res = runner.invoke(app, ["export", str(src), "-f", "urdf", "-o", str(tmp_path / "out"),
                              "--collision", "vhacd"])
    assert res.exit_code == 0, res.output
    assert "collision (vhacd)" in res.output and "5/5" in res.output


def test_predict_quiet_shows_no_vhacd_bar(tmp_path, monkeypatch, tiny_gnn):
    import kinmo.export.urdf as export_urdf

    monkeypatch.setattr(export_urdf, "PIECES_BAR_MIN_LINKS", 1)
    src = write_cabinet(tmp_path / "src" / "cab")
    res = runner.invoke(app, ["predict", str(src), "-m", str(tiny_gnn["run"]), "-o", str(tmp_path / "out"),
                              "-q", "--device", "cpu"])
    assert res.exit_code == 0, res.output
    assert (tmp_path / "out" / "cab" / "mobility.urdf").is_file() and "collision (" not in res.output
