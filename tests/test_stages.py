"""The per-shape stage machinery (:mod:`kinmo.stages`), its logging, and the CLI's verbosity
and error handling."""

from __future__ import annotations

import dataclasses
import json
import logging
from pathlib import Path
from typing import ClassVar

import pytest
from conftest import write_cabinet
from typer.testing import CliRunner

from kinmo.cli import app
from kinmo.errors import KinmoDataError, KinmoError
from kinmo.prepare import PrepareConfig, prepare_dataset
from kinmo.progress import log_level, setup_logging
from kinmo.stages import (
    ShapeStage,
    StageRow,
    cache_key,
    digest,
    json_digest,
    matches,
    read_manifest,
    worker_error,
    write_manifest,
)

CFG = PrepareConfig(n_points=32)


@dataclasses.dataclass
class _Row(StageRow):
    id: str
    status: str
    n: int | None = None
    x: float | None = None
    seconds: float = 0.0
    error: str = ""

    columns: ClassVar[tuple[str, ...]] = ("id", "status", "n", "x", "seconds", "error")


def test_manifest_round_trip_keeps_types_and_non_utf8_names(tmp_path: Path) -> None:
    name = b"caf\xe9".decode("utf-8", "surrogateescape")  # a Latin-1 folder name
    rows = [_Row("a", "ok", 3, 0.5, 1.25), _Row(name, "failed", error="x: broken"),
            _Row("c", "skipped", 0)]
    write_manifest(tmp_path, rows, _Row.columns, {"root": "R", "n_shapes": 3}, "shapes", True)
    back = read_manifest(tmp_path, _Row)
    assert back == rows
    assert back[1].n is None and back[1].seconds == 0.0  # empty cells: None, or the default
    info = json.loads((tmp_path / "manifest.json").read_text())
    assert list(info)[:3] == ["kinmo_version", "root", "n_shapes"]
    assert info["complete"] and info["counts"] == {"ok": 1, "skipped": 1, "failed": 1}
    assert [r["id"] for r in info["shapes"]] == ["a", name, "c"]


def test_read_manifest_names_the_file_and_problem(tmp_path: Path) -> None:
    with pytest.raises(KinmoDataError, match="file is missing"):
        read_manifest(tmp_path, _Row)
    (tmp_path / "manifest.csv").write_text("id,status\na,ok\n")
    with pytest.raises(KinmoDataError, match="unexpected columns"):
        read_manifest(tmp_path, _Row)
    (tmp_path / "manifest.csv").write_text(",".join(_Row.columns) + "\na,ok,three,,,\n")
    with pytest.raises(KinmoDataError, match=r"manifest\.csv.*malformed manifest"):
        read_manifest(tmp_path, _Row)


def test_fingerprints_and_keys() -> None:
    assert len(digest("a")) == 16 and digest("a") != digest("b")
    assert json_digest({"x": 1, "y": 2}) == json_digest({"y": 2, "x": 1})
    assert matches({"v": 1, "c": {"a": 1}, "extra": 0}, {"v": 1, "c": {"a": 1}})
    assert not matches({"v": 1}, {"v": 1, "c": 2})
    assert cache_key("/d/chair/12", "/d") == "chair__12"
    assert cache_key("/d", "/d") == "d" and cache_key("/x/7", "/d") == "7"
    msg = worker_error("/d/7", MemoryError("killed\nfor memory"))
    assert msg == "/d/7: worker process failed: MemoryError: killed for memory"


def _work(j: str) -> _Row:
    """The work of a job in a worker process: ``c`` raises."""
    if j == "c":
        raise RuntimeError("boom")
    return _Row(j, "ok")


def _work_logging(j: str) -> _Row:
    logging.getLogger("kinmo.test_stages").info("worker says %s", j)
    return _Row(j, "ok")


def _stage(tmp_path: Path, saves: list, **kw) -> ShapeStage:
    return ShapeStage(tmp_path, "kinmo test", 3, progress=False,
                      save=lambda rows, complete: saves.append((len(rows), complete)), **kw)


def test_stage_resumes_records_failures_and_saves(tmp_path: Path, caplog) -> None:
    """Up-to-date jobs are recorded without running; a worker failure becomes its row; the
    saves bracket the run (incomplete first, complete last); leftovers are removed."""
    (tmp_path / ".x.npz.tmp").write_text("half")
    saves: list = []
    seen: list = []
    caplog.set_level(logging.INFO, logger="kinmo")
    with _stage(tmp_path, saves, on_result=seen.append) as stage:
        assert not (tmp_path / ".x.npz.tmp").exists()
        todo = stage.resume(["a", "b", "c"], lambda j: _Row(j, "skipped") if j == "a" else None)
        assert todo == ["b", "c"] and stage.n_skipped == 1
        stage.map(_work, todo, 2, lambda j, e: _Row(j, "failed", error=worker_error(j, e)))
    assert saves[0] == (0, False) and saves[-1] == (3, True)
    assert sorted((r.id, r.status) for r in stage.results) == [
        ("a", "skipped"), ("b", "ok"), ("c", "failed")]
    assert len(seen) == 3 and stage.bar.counts == {"failed": 1}
    assert "resumed, 1 of 3 shapes up to date" in caplog.text
    warnings = [r for r in caplog.records if r.levelno == logging.WARNING]
    assert len(warnings) == 1 and "c: worker process failed: RuntimeError: boom" in warnings[0].message


def test_stage_stops_at_a_failure_and_saves_incomplete(tmp_path: Path) -> None:
    saves: list = []
    with _stage(tmp_path, saves, stop_on_failure=True) as stage:
        stage.map(lambda j: _Row(j, "failed" if j == "a" else "ok"), ["a", "b", "c"], 1,
                  lambda j, e: _Row(j, "failed"))
    assert stage.stopped and [r.id for r in stage.results] == ["a"] and saves[-1] == (1, False)


def test_stage_lock_fails_at_once_and_touches_nothing(tmp_path: Path) -> None:
    saves: list = []
    with _stage(tmp_path, saves):
        (tmp_path / ".y.tmp").write_text("theirs")
        with pytest.raises(KinmoError, match="another kinmo test is writing"):
            with _stage(tmp_path, saves):
                pass  # pragma: no cover
        assert (tmp_path / ".y.tmp").exists() and saves == [(0, False)]


def test_prepare_logs_the_resumed_shapes(tmp_path: Path, caplog) -> None:
    write_cabinet(tmp_path / "data" / "s1")
    write_cabinet(tmp_path / "data" / "s2")
    out = tmp_path / "cache"
    assert prepare_dataset(tmp_path / "data", out, CFG, workers=1, progress=False).ok
    caplog.set_level(logging.INFO, logger="kinmo.stages")
    res = prepare_dataset(tmp_path / "data", out, CFG, workers=1, progress=False)
    assert res.count("skipped") == 2
    assert f"{out}: resumed, 2 of 2 shapes up to date (skipped)" in caplog.messages


def test_prepare_logs_a_damaged_cache_file_it_rebuilds(tmp_path: Path, caplog) -> None:
    write_cabinet(tmp_path / "data" / "s1")
    out = tmp_path / "cache"
    assert prepare_dataset(tmp_path / "data", out, CFG, workers=1, progress=False).ok
    (out / "s1.npz").write_bytes(b"not a zip")
    caplog.set_level(logging.INFO, logger="kinmo")
    assert prepare_dataset(tmp_path / "data", out, CFG, workers=1, progress=False).count("ok") == 1
    assert any(m.startswith("rebuilding a damaged cache file: ") and "s1.npz" in m
               for m in caplog.messages), caplog.messages


def test_log_level_from_verbosity_and_environment() -> None:
    assert log_level(0, {}) == logging.WARNING
    assert log_level(1, {}) == logging.INFO and log_level(3, {}) == logging.DEBUG
    assert log_level(0, {"KINMO_LOG": "debug"}) == logging.DEBUG
    assert log_level(0, {"KINMO_LOG": "15"}) == 15
    assert log_level(1, {"KINMO_LOG": "error"}) == logging.INFO  # -v wins
    with pytest.raises(KinmoError, match="KINMO_LOG='loud'"):
        log_level(0, {"KINMO_LOG": "loud"})


@pytest.fixture
def _restore_kinmo_logger():
    log = logging.getLogger("kinmo")
    level, handlers = log.level, list(log.handlers)
    yield log
    log.setLevel(level)
    log.handlers[:] = handlers


def test_verbose_option_sets_the_level_and_shows_diagnostics(tmp_path: Path, _restore_kinmo_logger,
                                                             monkeypatch) -> None:
    log = _restore_kinmo_logger
    monkeypatch.delenv("KINMO_LOG", raising=False)
    write_cabinet(tmp_path / "data" / "s1")
    out = tmp_path / "cache"
    args = ["prepare", str(tmp_path / "data"), "--out", str(out), "-j", "1", "-q",
            "--n-points", "32"]
    r = CliRunner().invoke(app, args)
    assert r.exit_code == 0, r.output
    assert log.level == logging.WARNING and "resumed" not in r.output
    r = CliRunner().invoke(app, ["-v", *args])
    assert r.exit_code == 0, r.output
    assert log.level == logging.INFO
    assert "resumed, 1 of 1 shapes up to date" in " ".join(r.output.split())
    assert sum(getattr(h, "_kinmo", False) for h in log.handlers) == 1  # replaced, not stacked
    monkeypatch.setenv("KINMO_LOG", "nonsense")
    r = CliRunner().invoke(app, args)
    assert r.exit_code == 2 and r.output.count("error:") == 1 and "KINMO_LOG" in r.output


def test_setup_logging_does_not_stack_handlers(_restore_kinmo_logger) -> None:
    log = setup_logging(2, {})
    setup_logging(0, {})
    assert log.level == logging.WARNING
    assert sum(getattr(h, "_kinmo", False) for h in log.handlers) == 1


@pytest.mark.parametrize("argv, needle, code", [
    (["train", "ranker", "--data", "{tmp}/nope", "--out", "{tmp}/o", "--split", "{tmp}/s.json",
      "--types", "fine,medium"], "--types: expected fine and/or coarse", 2),
    (["train", "ranker", "--data", "{tmp}/nope", "--out", "{tmp}/o", "--split", "{tmp}/s.json"],
     "s.json: cannot read split", 1),
    (["render", "{tmp}/nope", "--out", "{tmp}/o", "-q"], "nope", 2),
])
def test_bad_input_is_one_error_line(tmp_path: Path, argv: list[str], needle: str, code: int) -> None:
    r = CliRunner().invoke(app, [a.format(tmp=tmp_path) for a in argv])
    assert r.exit_code == code, r.output
    lines = [ln for ln in r.output.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: ") and needle in lines[0], r.output
    assert "Traceback" not in r.output


def test_refine_options_reach_the_command_as_one_value() -> None:
    """``with_refine_options``: the six options in place of ``refine``, handed over as one."""
    import typer

    from kinmo.cli._refine import REFINE, RefineOptions, with_refine_options

    got = []
    cmd = typer.Typer()

    @cmd.command()
    @with_refine_options
    def run(first: int = typer.Option(1, "--first"), refine: RefineOptions = REFINE,
            last: str = typer.Option("x", "--last")) -> None:
        got.append((first, refine, last))

    r = CliRunner().invoke(cmd, ["--first", "3", "--snap-angle", "20", "--box-frames",
                                 "moving,shape", "--keep-gnn", "--last", "y"])
    assert r.exit_code == 0, r.output
    assert got == [(3, RefineOptions(keep_gnn=True, snap_angle=20.0, box_frames="moving,shape"), "y")]
    assert got[0][1].config().snap_angle_deg == 20.0
    names = [p.name for p in __import__("inspect").signature(run).parameters.values()]
    assert names[0] == "first" and names[-1] == "last" and "snap_angle" in names
    with pytest.raises(TypeError, match="no parameter 'refine'"):
        with_refine_options(lambda x=1: x)


def test_worker_processes_log_at_the_parent_level(tmp_path: Path, capfd, _restore_kinmo_logger) -> None:
    """Diagnostics of the work done in worker processes reach stderr at the parent's level."""
    log = _restore_kinmo_logger
    for level, shown in ((logging.INFO, True), (logging.WARNING, False)):
        log.setLevel(level)
        with _stage(tmp_path, []) as stage:
            stage.map(_work_logging, ["a", "b"], 2, lambda j, e: _Row(j, "failed"))
        assert sorted(r.status for r in stage.results) == ["ok", "ok"]
        err = capfd.readouterr().err
        assert ("worker says a" in err and "worker says b" in err) is shown, err
