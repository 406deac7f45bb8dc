"""The registry of input formats (issue 36): which reader takes which path, what every
reader shares (limits, the unsegmented-input error, up axes), and a format added later."""

from __future__ import annotations

import numpy as np
import pytest

from assets.builders import box_mjcf, box_urdf, write_mesh
from conftest import write_cabinet
from kinmo.assets import READERS, Reader, ReadOptions, asset_up, is_user_input, read_parts, reader_for
from kinmo.errors import KinmoDataError


@pytest.fixture
def inputs(tmp_path):
    write_mesh(tmp_path / "parts" / "a.obj")
    write_mesh(tmp_path / "parts" / "b.stl", offset=(2, 0, 0))
    (tmp_path / "robot.xml").write_text(box_urdf(tmp_path / "cab.urdf").read_text())
    return {"glb": write_mesh(tmp_path / "a.glb"), "folder": tmp_path / "parts",
            "urdf": tmp_path / "cab.urdf", "urdf_xml": tmp_path / "robot.xml",
            "mjcf": box_mjcf(tmp_path / "cab.xml"), "dataset": write_cabinet(tmp_path / "data" / "c1"),
            "missing": tmp_path / "nothing.glb"}


def test_every_format_has_one_reader_in_registration_order(inputs):
    assert is_user_input(inputs["glb"])  # loads the registry
    assert list(READERS) == ["mesh", "folder", "urdf", "mjcf"]
    assert all(isinstance(r, Reader) and r.description for r in READERS.values())
    taken = {k: getattr(reader_for(p), "name", None) for k, p in inputs.items()}
    assert taken == {"glb": "mesh", "folder": "folder", "urdf": "urdf", "urdf_xml": "urdf",
                     "mjcf": "mjcf", "dataset": None, "missing": None}
    assert not is_user_input(inputs["dataset"]) and not is_user_input(inputs["dataset"].parent)


def test_the_order_does_not_depend_on_which_format_module_is_imported_first():
    """Importing a format module directly (``kinmo.evaluate.foreign`` imports
    ``kinmo.assets.mjcf``) registers it first; the registry still keeps kinmo's order, with a
    format registered later after kinmo's."""
    import subprocess
    import sys

    code = ("import kinmo.assets.mjcf, kinmo.assets.urdf\n"
            "from kinmo.assets import READERS, register, reader_for\n"
            "register('toy', 'a toy', lambda p: False, lambda p: 'y')(lambda p, o: [])\n"
            "reader_for('x.glb')\n"
            "print(','.join(READERS))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "mesh,folder,urdf,mjcf,toy"


def test_up_axes_follow_each_format(inputs):
    ups = {k: asset_up(inputs[k]) for k in ("glb", "folder", "urdf", "urdf_xml", "mjcf")}
    assert ups == {"glb": "y", "folder": "y", "urdf": "z", "urdf_xml": "z", "mjcf": "z"}


def test_the_same_cabinet_reads_alike_as_urdf_and_mjcf(inputs):
    urdf, mjcf = read_parts(inputs["urdf"]), read_parts(inputs["mjcf"])
    assert len(urdf) == len(mjcf) == 4
    for (_, vu, _), (_, vm, _) in zip(urdf, mjcf):
        np.testing.assert_allclose([vu.min(0), vu.max(0)], [vm.min(0), vm.max(0)], atol=1e-6)


def test_what_no_reader_takes_is_one_line_saying_what_kinmo_reads(inputs, tmp_path):
    with pytest.raises(KinmoDataError, match="nothing.glb: no such file or folder"):
        read_parts(inputs["missing"])
    (tmp_path / "notes.txt").write_text("hello")
    with pytest.raises(KinmoDataError, match=r"unknown input kind '.txt'.*or an MJCF model"):
        read_parts(tmp_path / "notes.txt")


def test_one_part_is_refused_as_unsegmented_whatever_the_format(tmp_path):
    one = tmp_path / "one.urdf"
    one.write_text('<robot name="r"><link name="a"><visual><geometry><box size="1 1 1"/>'
                   "</geometry></visual></link><link name=\"empty\"/></robot>")
    with pytest.raises(KinmoDataError, match=r"found 1 part\(s\): an unsegmented mesh; kinmo needs"):
        read_parts(one)


def test_the_parts_limit_holds_for_every_reader(inputs, monkeypatch):
    monkeypatch.setenv("KINMO_MAX_PARTS", "3")
    for kind in ("urdf", "mjcf"):
        with pytest.raises(KinmoDataError, match="exceeds the limit of 3"):
            read_parts(inputs[kind])


def test_a_format_registered_later_is_read_with_the_options(tmp_path, monkeypatch):
    seen = []

    def read(path, options):
        seen.append(options)
        box = (np.eye(3), np.array([[0, 1, 2]]))
        return [("a", *box), ("b", *box)]

    monkeypatch.setitem(READERS, "toy", Reader("toy", "a toy", lambda p: p.suffix == ".toy", read,
                                               lambda p: "z"))
    (tmp_path / "x.toy").write_text("")
    opts = ReadOptions((tmp_path,))
    assert [n for n, _, _ in read_parts(tmp_path / "x.toy", opts)] == ["a", "b"]
    assert seen == [opts] and asset_up(tmp_path / "x.toy") == "z"
