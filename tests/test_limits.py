"""Resource limits on untrusted inputs (kinmo.limits, issue 21 finding 4)."""

from __future__ import annotations

import pytest
from conftest import write_cabinet
from typer.testing import CliRunner

from kinmo import limits
from kinmo.cli import app
from kinmo.errors import KinmoDataError, KinmoUsageError


def test_defaults_and_environment(monkeypatch):
    monkeypatch.delenv("KINMO_MAX_PARTS", raising=False)
    assert limits.limit("parts") == 2000
    assert limits.limit("file_bytes") == 1 << 32  # the Rust reader's MAX_OBJ_BYTES
    monkeypatch.setenv("KINMO_MAX_PARTS", "5_000")
    assert limits.limit("parts") == 5000
    monkeypatch.setenv("KINMO_MAX_PARTS", "-3")
    with pytest.raises(KinmoUsageError, match="KINMO_MAX_PARTS"):
        limits.limit("parts")


@pytest.mark.parametrize("spec", ["parts", "parts=0", "parts=x", "bogus=3"])
def test_set_limit_refuses_bad_specs(spec):
    with pytest.raises(KinmoUsageError, match="NAME=N"):
        limits.set_limit(spec)


def test_check_names_file_and_limit(monkeypatch):
    monkeypatch.delenv("KINMO_MAX_EDGES", raising=False)
    limits.check("edges", 300_000, "f.json")
    with pytest.raises(KinmoDataError, match=r"f.json: 300,001 sibling edges per graph exceeds "
                                             r"the limit of 300,000.*--limit edges=N"):
        limits.check("edges", 300_001, "f.json")


def test_prepare_over_a_limit_is_one_line_and_the_option_raises_it(tmp_path, monkeypatch):
    monkeypatch.setenv("KINMO_MAX_PARTS", "2000")  # restored after the test: --limit sets it
    monkeypatch.delenv("KINMO_MAX_PARTS")
    write_cabinet(tmp_path / "data" / "cab")
    runner = CliRunner()
    res = runner.invoke(app, ["--limit", "parts=3", "prepare", str(tmp_path / "data"), "-o",
                              str(tmp_path / "out"), "--strict"], env={"COLUMNS": "400"})
    assert res.exit_code == 1
    assert "6 parts per shape exceeds the limit of 3" in res.output, res.output
    monkeypatch.delenv("KINMO_MAX_PARTS", raising=False)  # --limit set it for this process
    res = runner.invoke(app, ["--limit", "parts=6", "prepare", str(tmp_path / "data"), "-o",
                              str(tmp_path / "out2")])
    assert res.exit_code == 0, res.output


def test_limit_option_refuses_bad_values(tmp_path, monkeypatch):
    monkeypatch.setenv("KINMO_MAX_PARTS", "2000")
    res = CliRunner().invoke(app, ["--limit", "parts=-1", "prepare", str(tmp_path)])
    assert res.exit_code == 2 and "error: --limit parts=-1" in res.output


def test_defaults_accept_the_shared_data_flattened(mobility_root, partnet_root, data_facts, monkeypatch):
    """Every shape of the shared data, flattened to one level, stays under the part and edge
    limits (its largest object, by the data's README: 116 leaves in 2026-11, about 13,000
    directed sibling edges)."""
    from kinmo.data.readers import find_shapes, read_shape

    for name in ("KINMO_MAX_PARTS", "KINMO_MAX_EDGES"):
        monkeypatch.delenv(name, raising=False)
    worst = 0
    for root in (mobility_root, partnet_root):
        for folder in find_shapes(root):
            n = sum(1 for node in read_shape(folder).hierarchy.nodes.values() if node.is_leaf)
            limits.check("parts", n, folder)
            limits.check("edges", n * (n - 1), folder)
            worst = max(worst, n * (n - 1))
    most = data_facts["max_leaves"]
    assert worst >= most * (most - 1)  # the data's largest shape was checked: not vacuous


def test_the_rust_obj_reader_takes_the_file_limit(tmp_path, monkeypatch):
    """One file limit: the Rust OBJ reader is given ``file_bytes`` (no second, fixed cap)."""
    from kinmo.geometry import load_obj, load_objs

    obj = tmp_path / "tri.obj"
    obj.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    n = obj.stat().st_size
    monkeypatch.setenv("KINMO_MAX_FILE_BYTES", str(n))
    assert load_obj(obj)[1].shape == (1, 3)
    monkeypatch.setenv("KINMO_MAX_FILE_BYTES", str(n - 1))
    for read in (lambda: load_obj(obj), lambda: load_objs([obj])):
        with pytest.raises(OSError, match=rf"tri.obj.*too large.*{n - 1}"):
            read()
