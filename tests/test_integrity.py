"""Nothing lost, nothing crashes (issue 14, Python side): corrupt and incomplete caches, garbage
meshes, non-UTF-8 names, ``--out`` on a file, damaged checkpoints, the one CLI error handler."""

from __future__ import annotations

import json
import os
import re
import zipfile
from pathlib import Path

import numpy as np
import pytest
import torch
import typer
from conftest import REPO, write_cabinet
from typer.testing import CliRunner

from kinmo.cli import app
from kinmo.cli._errors import cli_errors
from kinmo.data.graph import PartGraph
from kinmo.errors import KinmoDataError, KinmoError
from kinmo.data.cache import check_manifest
from kinmo.prepare import PrepareConfig, prepare_dataset, read_manifest
from kinmo.data.cache import load_cache

CFG = PrepareConfig(n_points=32)


def _one_line_error(output: str, *needles: str) -> None:
    """The CLI output holds exactly one ``error:`` line, containing every needle, and no
    traceback."""
    lines = [ln for ln in output.splitlines() if ln.startswith("error:")]
    assert len(lines) == 1, output
    for n in needles:
        assert n in lines[0], (n, lines[0])
    assert "Traceback" not in output, output


def _flip_byte(npz: Path, member: str = "points.npy") -> None:
    """Flip one byte inside the data of ``member`` of an (uncompressed) ``.npz``."""
    with zipfile.ZipFile(npz) as z:
        info = z.getinfo(member)
    raw = bytearray(npz.read_bytes())
    # local header: 30 bytes + name + extra; then the .npy header (<= 128 bytes) and the data
    name_len = int.from_bytes(raw[info.header_offset + 26: info.header_offset + 28], "little")
    extra_len = int.from_bytes(raw[info.header_offset + 28: info.header_offset + 30], "little")
    start = info.header_offset + 30 + name_len + extra_len
    pos = start + 128 + (info.file_size - 128) // 2
    raw[pos] ^= 0x40
    npz.write_bytes(bytes(raw))


@pytest.fixture
def two_cabinets(tmp_path: Path) -> tuple[Path, Path]:
    root = tmp_path / "data"
    write_cabinet(root / "s1")
    write_cabinet(root / "s2")
    out = tmp_path / "cache"
    res = prepare_dataset(root, out, CFG, workers=1, progress=False)
    assert res.ok
    return root, out


# ------------------------------------------------------------------------- cache integrity


def test_flipped_byte_is_named_by_readers_and_rebuilt_by_prepare(two_cabinets) -> None:
    root, out = two_cabinets
    npz = out / "s1.npz"
    _flip_byte(npz)
    with pytest.raises(KinmoDataError) as e:
        PartGraph.load(npz)
    assert str(e.value).startswith(f"{npz}: corrupt") and "\n" not in str(e.value)
    with pytest.raises(KinmoDataError, match=re.escape(str(npz))):
        load_cache(out)
    # prepare rebuilds it instead of calling it up to date
    res = prepare_dataset(root, out, CFG, workers=1, progress=False)
    assert {r.id: r.status for r in res.rows} == {"s1": "ok", "s2": "skipped"}
    assert len(load_cache(out)) == 2


def test_checksum_covers_the_arrays(two_cabinets) -> None:
    """An array changed behind the zip's back (valid CRCs) fails the stored checksum."""
    _, out = two_cabinets
    npz = out / "s2.npz"
    with np.load(npz) as z:
        arrays = {k: z[k] for k in z.files}
    assert len(json.loads(str(arrays["meta_json"]))["checksum"]) == 32
    arrays["sibling_distance"] = arrays["sibling_distance"] + 1e-3
    with open(npz, "wb") as f:
        np.savez(f, **arrays)
    with pytest.raises(KinmoDataError, match="checksum mismatch"):
        PartGraph.load(npz)


def test_cli_readers_name_the_corrupt_file(two_cabinets, tmp_path: Path) -> None:
    from kinmo.train.config import preset
    from kinmo.train.gnn import train_gnn
    from kinmo.train.split import Split

    root, out = two_cabinets
    cfg = preset("quick", n_points=32, threads=1, epochs=1, batch_size=2)
    small = cfg.model.model_copy(update=dict(point_widths=[8], geo_dim=8, node_dim=8, edge_dim=8,
                                             semantic_dim=2, gnn_layers=1))
    run = tmp_path / "run"
    train_gnn(out, run, cfg.model_copy(update={"model": small}), split=Split(["s1", "s2"], []),
              progress=False)
    npz = out / "s1.npz"
    _flip_byte(npz)
    runner = CliRunner()
    r = runner.invoke(app, ["train", "gnn", "--data", str(out), "--out", str(tmp_path / "r2"),
                            "--quiet", "--epochs", "1"])
    assert r.exit_code == 1
    _one_line_error(r.output, str(npz), "corrupt")
    r = runner.invoke(app, ["eval", "pre-segmented", "--model", str(run), "--data", str(out),
                            "--all", "--quiet", "--device", "cpu", "--out", str(tmp_path / "ev")])
    assert r.exit_code == 1
    _one_line_error(r.output, str(npz), "corrupt")
    r = runner.invoke(app, ["predict", str(root), "--model", str(run), "--out",
                            str(tmp_path / "pred"), "--cache", str(out), "--quiet",
                            "--device", "cpu"])
    assert r.exit_code == 1 and "Traceback" not in r.output
    assert f"failed s1: {npz}: corrupt" in " ".join(r.output.split())


def test_incomplete_manifest_is_refused_with_counts(tmp_path: Path) -> None:
    root = tmp_path / "data"
    for name in ("s1", "s2", "s3"):
        write_cabinet(root / name)
    out = tmp_path / "cache"

    def interrupt(row) -> None:
        if row.id == "s2":
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        prepare_dataset(root, out, CFG, workers=1, progress=False, on_row=interrupt)
    assert json.loads((out / "manifest.json").read_text())["complete"] is False
    (out / "manifest.csv").write_text((out / "manifest.csv").read_text().splitlines()[0] + "\n")
    for f in (lambda: load_cache(out), lambda: check_manifest(out)):
        with pytest.raises(KinmoDataError) as e:
            f()
        msg = str(e.value)
        assert msg.startswith(f"{out}: incomplete cache: the manifest accounts for 0 of 3 shapes")
        assert "(3 missing, 2 graphs on disk not in it)" in msg
        assert f"`kinmo prepare {root} --out {out}`" in msg
    r = CliRunner().invoke(app, ["train", "gnn", "--data", str(out), "--out",
                                 str(tmp_path / "run"), "--quiet"])
    assert r.exit_code == 1
    _one_line_error(r.output, "incomplete cache", "kinmo prepare")
    assert prepare_dataset(root, out, CFG, workers=1, progress=False).ok  # resumes
    assert [g.shape_id for g in load_cache(out)] == ["s1", "s2", "s3"]


def test_a_run_writes_an_incomplete_manifest_first(tmp_path: Path) -> None:
    """Killed before its first periodic manifest write, a run still leaves ``complete: false``."""
    root = tmp_path / "data"
    write_cabinet(root / "s1")
    out = tmp_path / "cache"
    seen = []

    def look(row) -> None:
        seen.append(json.loads((out / "manifest.json").read_text()))

    prepare_dataset(root, out, CFG, workers=1, progress=False, on_row=look)
    assert seen[0]["complete"] is False and seen[0]["shapes"] == [] and seen[0]["n_shapes"] == 1
    assert json.loads((out / "manifest.json").read_text())["complete"] is True


# ----------------------------------------------------------------------- meshes and names


@pytest.mark.parametrize("content", ["this is not an OBJ file\nat all\n", "", "# only a comment\n"])
def test_garbage_obj_among_a_leafs_meshes_fails_the_shape(tmp_path: Path, content: str) -> None:
    root = tmp_path / "data"
    bad = write_cabinet(root / "bad") / "textured_objs" / "drawer_box.obj"  # drawer: 2 meshes
    bad.write_text(content)
    write_cabinet(root / "good")
    res = prepare_dataset(root, tmp_path / "cache", CFG, workers=1, progress=False)
    rows = {r.id: r for r in res.rows}
    assert rows["good"].status == "ok"
    assert rows["bad"].status == "failed"
    # Text that is not an OBJ is refused by the loader itself (kinmo._core.load_obj);
    # an empty or comment-only OBJ loads as an empty mesh and is refused by prepare.
    want = "not an OBJ file" if content.strip() and not content.startswith("#") else "no faces"
    assert rows["bad"].error.startswith(f"{bad}: ") and want in rows["bad"].error


def test_non_utf8_file_name_inside_a_shape(tmp_path: Path) -> None:
    root = tmp_path / "data"
    s1 = write_cabinet(root / "s1")
    write_cabinet(root / "s2")
    (s1 / os.fsdecode(b"notes-\xff.txt")).write_text("x")
    out = tmp_path / "cache"
    res = prepare_dataset(root, out, CFG, workers=1, progress=False)
    assert res.ok and [r.id for r in read_manifest(out)] == ["s1", "s2"]
    res = prepare_dataset(root, out, CFG, workers=1, progress=False)
    assert res.count("skipped") == 2


def test_non_utf8_shape_folder_name(tmp_path: Path) -> None:
    root = tmp_path / "data"
    name = os.fsdecode(b"cab-\xe9")
    write_cabinet(root / name)
    write_cabinet(root / "s2")
    out = tmp_path / "cache"
    r = CliRunner().invoke(app, ["prepare", str(root), "--out", str(out), "-j", "1", "-q",
                                 "--n-points", "32"])
    assert r.exit_code == 0, r.output
    assert sorted(p.name for p in out.glob("*.npz")) == sorted([f"{name}.npz", "s2.npz"])
    rows = read_manifest(out)
    assert [r.id for r in rows] == sorted([name, "s2"]) and {r.status for r in rows} == {"ok"}
    assert sorted(s["id"] for s in json.loads((out / "manifest.json").read_text())["shapes"]) \
        == sorted([name, "s2"])
    assert sorted(g.shape_id for g in load_cache(out)) == sorted([name, "s2"])
    assert prepare_dataset(root, out, CFG, workers=1, progress=False).count("skipped") == 2


def test_failed_non_utf8_shape_is_a_row_not_a_traceback(tmp_path: Path) -> None:
    """The failed-shape table prints such an id even on a strict UTF-8 terminal."""
    import subprocess
    import sys

    root = tmp_path / "data"
    name = os.fsdecode(b"bad-\xe9")
    (write_cabinet(root / name) / "result.json").write_text("[")
    write_cabinet(root / "good")
    out = tmp_path / "cache"
    r = subprocess.run([sys.executable, "-m", "kinmo", "prepare", str(root), "--out", str(out),
                        "-j", "1", "-q", "--n-points", "32"], capture_output=True, text=True,
                       env={**os.environ, "PYTHONIOENCODING": "utf-8:strict", "COLUMNS": "200"})
    assert r.returncode == 1 and "Traceback" not in r.stderr, r.stderr
    assert "bad-\\udce9" in r.stdout and "malformed JSON" in r.stdout
    rows = {r.id: r for r in read_manifest(out)}
    assert rows[name].status == "failed" and rows["good"].status == "ok"
    assert rows[name].error.startswith(str(root / name / "result.json"))


# ------------------------------------------------------------------------- --out on a file


@pytest.mark.parametrize("argv", [
    ["prepare", "{data}", "--out", "{file}", "-q"],
    ["synth", "{file}", "--n", "1", "-q"],
    ["predict", "{data}", "--model", "{data}", "--out", "{file}", "-q"],
])
def test_out_pointing_at_a_file(tmp_path: Path, argv: list[str]) -> None:
    data = tmp_path / "data"
    write_cabinet(data / "s1")
    file = tmp_path / "taken"
    file.write_text("x")
    r = CliRunner().invoke(app, [a.format(data=data, file=file) for a in argv])
    assert r.exit_code in (1, 2)
    _one_line_error(r.output, str(file), "exists and is not a folder")


# ------------------------------------------------------------------------------- checkpoints


def _loaders():
    from kinmo.ancsh.inference import load_run as load_ancsh
    from kinmo.refine.train import load_axis_model
    from kinmo.train.gnn import load_run as load_gnn

    return {"motion-GNN": load_gnn, "axis-selection": load_axis_model, "ANCSH": load_ancsh}


@pytest.mark.parametrize("damage", ["empty", "garbage", "truncated", "code"])
@pytest.mark.parametrize("what", ["motion-GNN", "axis-selection", "ANCSH"])
def test_damaged_checkpoint_is_one_line_naming_the_file(tmp_path: Path, damage: str, what: str) -> None:
    ckpt = tmp_path / "model.pt"
    if damage == "empty":
        ckpt.write_bytes(b"")
    elif damage == "garbage":
        ckpt.write_bytes(b"\x80\x02garbage" * 50)
    elif damage == "truncated":
        torch.save({"format": "x", "state_dict": {"w": torch.zeros(1000)}}, ckpt)
        ckpt.write_bytes(ckpt.read_bytes()[: ckpt.stat().st_size // 2])
    else:  # a pickled object that is not plain data: refused by weights_only
        torch.save({"format": "x", "path": Path("/tmp")}, ckpt)
    with pytest.raises(KinmoDataError) as e:
        _loaders()[what](tmp_path)
    msg = str(e.value)
    assert msg.startswith(f"{ckpt}: ") and "\n" not in msg and what in msg, msg
    assert "weights_only=False" not in msg
    if damage == "empty":
        assert "empty file" in msg


def test_damaged_checkpoint_in_the_cli(tmp_path: Path) -> None:
    data = tmp_path / "data"
    write_cabinet(data / "s1")
    run = tmp_path / "run"
    run.mkdir()
    (run / "model.pt").write_bytes(b"")
    r = CliRunner().invoke(app, ["predict", str(data), "--model", str(run), "--out",
                                 str(tmp_path / "out"), "-q"])
    assert r.exit_code == 1
    _one_line_error(r.output, str(run / "model.pt"), "empty file")


def test_every_torch_load_is_weights_only() -> None:
    calls = []
    for p in (REPO / "python" / "kinmo").rglob("*.py"):
        text = p.read_text()
        for m in re.finditer(r"torch\.load\(", text):
            end = text.find(")", m.end())
            calls.append((p, text[m.start(): end + 1]))
    assert calls
    for p, call in calls:
        assert "weights_only=True" in call, (p, call)


# --------------------------------------------------------------------------- error handler


def _run_handler(exc: BaseException, code: int = 3, also=()) -> int:
    with pytest.raises(typer.Exit) as e:
        with cli_errors(code, also=also):
            raise exc
    return e.value.exit_code


def test_cli_errors(capsys: pytest.CaptureFixture[str]) -> None:
    assert _run_handler(KinmoError("a.npz: bad\nthing [red]x[/]")) == 3
    assert capsys.readouterr().err == "error: a.npz: bad thing [red]x[/]\n"
    assert _run_handler(KinmoDataError(os.fsdecode(b"f\xff"), "odd")) == 3
    assert capsys.readouterr().err == "error: f\\udcff: odd\n"
    assert _run_handler(FileExistsError(17, "File exists", "/x/out")) == 3
    assert capsys.readouterr().err == "error: /x/out: File exists\n"
    assert _run_handler(ValueError("bad option"), 2, also=(ValueError,)) == 2
    with pytest.raises(ValueError):
        _run_handler(ValueError("a bug"))
    with pytest.raises(OSError):  # no file named: not a user error
        _run_handler(OSError("pipe"))
