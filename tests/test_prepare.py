"""``kinmo prepare``: manifest rows for bad input, strict mode, resume, the CLI."""

from __future__ import annotations

import csv
import json
import os
import shutil
from pathlib import Path

import numpy as np
import pytest
from conftest import write_cabinet
from typer.testing import CliRunner

from kinmo.cli import app
from kinmo.data.graph import PartGraph
from kinmo.errors import KinmoError
from kinmo.prepare import (
    MANIFEST_COLUMNS,
    PrepareConfig,
    cache_key,
    prepare_dataset,
    prepare_one,
    read_manifest,
    source_fingerprint,
)

CFG = PrepareConfig(n_points=32)


def _edit(path: Path, fn) -> None:
    path.write_text(json.dumps(fn(json.loads(path.read_text()))))


def _set_axis(d: list) -> list:
    d[0]["jointData"]["axis"]["direction"] = [0, 0, 0]
    return d


def _set_joint(d: list) -> list:
    d[1]["joint"] = "telescopic"
    return d


def _nan_vertex(c: Path) -> None:
    obj = c / "textured_objs" / "knob.obj"
    lines = obj.read_text().splitlines()
    lines[3] = "v 0.2 nan 0.55"
    obj.write_text("\n".join(lines) + "\n")


#: Broken variants of the cabinet: name -> (mutation, file the error must name, problem text).
BROKEN = {
    "b_malformed_json": (lambda c: (c / "result.json").write_text('[{"id": 0,'),
                         "result.json", "malformed JSON at line 1"),
    "c_missing_mesh": (lambda c: (c / "textured_objs" / "door.obj").unlink(),
                       "textured_objs/door.obj", "mesh file is missing"),
    "d_nan_vertex": (_nan_vertex, "textured_objs/knob.obj", "non-finite"),
    "e_empty_hierarchy": (lambda c: (c / "result.json").write_text("[]"),
                          "result.json", "empty hierarchy"),
    "f_unknown_joint": (lambda c: _edit(c / "mobility_v2.json", _set_joint),
                        "mobility_v2.json", "unknown joint type 'telescopic'"),
    "g_zero_axis": (lambda c: _edit(c / "mobility_v2.json", _set_axis),
                    "mobility_v2.json", "zero-length axis"),
}


@pytest.fixture
def dataset(tmp_path: Path) -> Path:
    root = tmp_path / "data"
    write_cabinet(root / "a_good")
    for name, (mutate, _, _) in BROKEN.items():
        mutate(write_cabinet(root / name))
    write_cabinet(root / "z_good")
    return root


def _rows(out: Path) -> dict[str, dict]:
    with open(out / "manifest.csv", newline="") as f:
        r = csv.DictReader(f)
        assert tuple(r.fieldnames) == MANIFEST_COLUMNS
        return {row["id"]: row for row in r}


def test_bad_input_gives_rows_and_the_run_goes_on(dataset: Path, tmp_path: Path) -> None:
    out = tmp_path / "cache"
    res = prepare_dataset(dataset, out, CFG, workers=2, progress=False)
    assert res.n_shapes == 8 and not res.ok and not res.stopped
    rows = _rows(out)
    assert set(rows) == {"a_good", "z_good", *BROKEN}
    for name, (_, file, problem) in BROKEN.items():
        row = rows[name]
        assert row["status"] == "failed", name
        assert row["error"].startswith(str(dataset / name / file) + ":"), row["error"]
        assert problem in row["error"], row["error"]
        assert "\n" not in row["error"]
        assert row["format"] == "partnet-mobility"
        assert not (out / f"{name}.npz").exists()
    for good in ("a_good", "z_good"):
        row = rows[good]
        assert row["status"] == "ok" and row["error"] == ""
        assert (row["category"], row["format"]) == ("StorageFurniture", "partnet-mobility")
        assert (row["n_nodes"], row["n_leaves"], row["n_sibling_edges"],
                row["n_moving_joints"]) == ("8", "6", "22", "3")
        assert row["fingerprint"] == source_fingerprint(dataset / good)
        g = PartGraph.load(out / f"{good}.npz")
        assert g.points.shape == (8, 32, 3) and g.meta["config"] == CFG.as_dict()
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["complete"] and manifest["counts"] == {"ok": 2, "skipped": 0, "failed": 6}
    assert [r["id"] for r in manifest["shapes"]] == sorted(rows)
    assert [r.id for r in read_manifest(out)] == sorted(rows)
    assert not list(out.glob(".*.tmp"))


def test_strict_stops_at_the_first_failure(dataset: Path, tmp_path: Path) -> None:
    out = tmp_path / "cache"
    res = prepare_dataset(dataset, out, CFG, workers=1, strict=True, progress=False)
    assert res.stopped and not res.ok
    assert [(r.id, r.status) for r in res.rows] == [("a_good", "ok"), ("b_malformed_json", "failed")]
    assert set(_rows(out)) == {"a_good", "b_malformed_json"}
    assert json.loads((out / "manifest.json").read_text())["complete"] is False


def test_resume(tmp_path: Path) -> None:
    root = tmp_path / "data"
    for name in ("s1", "s2", "s3"):
        write_cabinet(root / name)
    (root / "s3" / "result.json").write_text("[")  # fails every time
    out = tmp_path / "cache"
    first = prepare_dataset(root, out, CFG, workers=1, progress=False)
    assert [r.status for r in first.rows] == ["ok", "ok", "failed"]
    stamp = (out / "s1.npz").stat().st_mtime_ns

    # Second run: up-to-date shapes are skipped (file untouched), the failed one is retried.
    second = prepare_dataset(root, out, CFG, workers=1, progress=False)
    assert [r.status for r in second.rows] == ["skipped", "skipped", "failed"]
    assert (out / "s1.npz").stat().st_mtime_ns == stamp
    rows = _rows(out)
    assert rows["s1"]["n_nodes"] == "8" and rows["s1"]["status"] == "skipped"

    # Interrupted-run leftovers: a stray temporary file, a manifest row without cache file.
    (out / ".s1.npz.abc123.tmp").write_bytes(b"partial")
    (out / "s2.npz").unlink()
    # A touched source file changes the fingerprint; a new config redoes everything.
    obj = root / "s1" / "textured_objs" / "knob.obj"
    os.utime(obj, ns=(obj.stat().st_atime_ns, obj.stat().st_mtime_ns + 10**9))
    third = prepare_dataset(root, out, CFG, workers=1, progress=False)
    assert [r.status for r in third.rows] == ["ok", "ok", "failed"]
    assert not list(out.glob(".*.tmp"))
    fourth = prepare_dataset(root, out, PrepareConfig(n_points=16), workers=1, progress=False)
    assert [r.status for r in fourth.rows] == ["ok", "ok", "failed"]
    assert PartGraph.load(out / "s1.npz").points.shape[1] == 16
    # A stale cache version or a corrupt cache file is rebuilt.
    (out / "s1.npz").write_bytes(b"not a zip")
    fifth = prepare_dataset(root, out, PrepareConfig(n_points=16), workers=1, progress=False)
    assert [r.status for r in fifth.rows] == ["ok", "skipped", "failed"]
    # --force rebuilds up-to-date shapes
    sixth = prepare_dataset(root, out, PrepareConfig(n_points=16), workers=1, force=True,
                            progress=False)
    assert [r.status for r in sixth.rows] == ["ok", "ok", "failed"]


def test_prepare_one_never_raises(tmp_path: Path) -> None:
    row = prepare_one(tmp_path / "nowhere", tmp_path / "out", CFG)
    assert row.status == "failed" and str(tmp_path / "nowhere") in row.error
    shape = write_cabinet(tmp_path / "one")
    row = prepare_one(shape, tmp_path / "out", CFG)
    assert row.status == "ok" and (tmp_path / "out" / "one.npz").is_file()
    assert prepare_one(shape, tmp_path / "out", CFG).status == "skipped"


def test_cache_keys_and_single_shape_root(tmp_path: Path) -> None:
    root = tmp_path / "nested"
    assert cache_key(root / "Chair" / "179", root) == "Chair__179"
    assert cache_key(root / "179", root) == "179"
    assert cache_key(root, root) == "nested"
    shape = write_cabinet(root / "Cabinet" / "12")
    write_cabinet(root / "Table" / "12")
    res = prepare_dataset(root, tmp_path / "out", CFG, workers=1, progress=False)
    assert [r.id for r in res.rows] == ["Cabinet__12", "Table__12"] and res.ok
    res = prepare_dataset(shape, tmp_path / "one", CFG, workers=1, progress=False)
    assert [r.id for r in res.rows] == ["12"] and (tmp_path / "one" / "12.npz").is_file()


def test_one_run_per_cache(tmp_path: Path) -> None:
    import fcntl

    write_cabinet(tmp_path / "data" / "s")
    out = tmp_path / "cache"
    out.mkdir()
    with open(out / ".lock", "a+") as fh:
        fcntl.flock(fh, fcntl.LOCK_EX | fcntl.LOCK_NB)
        with pytest.raises(KinmoError, match="another kinmo prepare"):
            prepare_dataset(tmp_path / "data", out, CFG, workers=1, progress=False)


@pytest.mark.exactdata
def test_real_shapes_both_formats(mobility_root: Path, partnet_root: Path, tmp_path: Path) -> None:
    root = tmp_path / "mix"
    root.mkdir()
    for src in (mobility_root / "10849", mobility_root / "20453", partnet_root / "179"):
        (root / src.name).symlink_to(src, target_is_directory=True)
    res = prepare_dataset(root, tmp_path / "out", CFG, workers=1, progress=False)
    assert res.ok and [r.status for r in res.rows] == ["ok"] * 3
    fmt = {r.id: r.format for r in res.rows}
    assert fmt == {"10849": "partnet-mobility", "20453": "partnet-mobility", "179": "partnet"}
    assert PartGraph.load(tmp_path / "out" / "179.npz").edge_fine is None
    assert PartGraph.load(tmp_path / "out" / "10849.npz").edge_fine is not None


# ----------------------------------------------------------------------------------- CLI


def test_cli(dataset: Path, tmp_path: Path) -> None:
    runner = CliRunner()
    out = tmp_path / "cli"
    r = runner.invoke(app, ["prepare", str(dataset), "--out", str(out), "-j", "1", "-q",
                            "--n-points", "24", "--seed", "5"])
    assert r.exit_code == 1, r.output
    assert "8 shapes" in r.output and "2 built" in r.output and "6 failed" in r.output
    for name in BROKEN:
        assert name in r.output
    g = PartGraph.load(out / "a_good.npz")
    assert g.points.shape[1] == 24 and g.meta["seed"] == 5
    # second run: all good shapes up to date, still exit 1 for the failures
    r = runner.invoke(app, ["prepare", str(dataset), "--out", str(out), "-j", "1", "-q",
                            "--n-points", "24", "--seed", "5"])
    assert r.exit_code == 1 and "2 up to date" in r.output
    # --strict stops at the first failure
    r = runner.invoke(app, ["prepare", str(dataset), "--out", str(tmp_path / "s"), "-j", "1",
                            "-q", "--strict", "--n-points", "24"])
    assert r.exit_code == 1 and "--strict" in r.output
    assert len(_rows(tmp_path / "s")) == 2
    # only good shapes: exit 0
    for name in BROKEN:
        shutil.rmtree(dataset / name)
    r = runner.invoke(app, ["prepare", str(dataset), "--out", str(tmp_path / "ok"), "-j", "1",
                            "-q", "--n-points", "24"])
    assert r.exit_code == 0, r.output
    # bad root or parameters
    r = runner.invoke(app, ["prepare", str(tmp_path / "missing"), "--out", str(out)])
    assert r.exit_code == 2 and "not a folder" in r.output
    r = runner.invoke(app, ["prepare", str(dataset), "--contact-tolerance", "0.5"])
    assert r.exit_code == 2
    # an absurd point count is refused up front, before any shape is tried (issue 14)
    r = runner.invoke(app, ["prepare", str(dataset), "--out", str(tmp_path / "huge"),
                            "--n-points", "10000000000000"])
    assert r.exit_code == 2 and "--n-points" in r.output
    assert not (tmp_path / "huge").exists()


def test_default_cache_dir(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    write_cabinet(tmp_path / "mydata" / "s")
    monkeypatch.chdir(tmp_path)
    res = prepare_dataset(tmp_path / "mydata", None, CFG, workers=1, progress=False)
    assert res.out == Path("cache") / "mydata"
    assert (tmp_path / "cache" / "mydata" / "s.npz").is_file()
    assert np.isfinite(PartGraph.load(tmp_path / "cache" / "mydata" / "s.npz").points).all()
