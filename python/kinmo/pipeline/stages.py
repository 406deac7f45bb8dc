"""The stage runner of ``kinmo train all``: resumable stages (a ``.done`` file holding the
stage's configuration), their timings, and the run's result (``pipeline_result.json``)."""

from __future__ import annotations

import json
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from pydantic import BaseModel, Field

from kinmo.io import write_text
from kinmo.progress import literal

__all__ = ["PipelineResult", "StageTiming", "mark_done", "stage_done"]


class StageTiming(BaseModel):
    """Time one stage took.

    Attributes
    ----------
    wall_s : float
        Wall-clock seconds.
    cpu_s : float
        CPU seconds (user + system) of this process and of the worker processes that ended
        during the stage.
    ran : bool
        False when the stage was up to date (skipped).
    parallel : bool
        Trained in the pool of ``kinmo train all -j N`` beside other stages: its wall time
        overlaps theirs, and its times are the worker's own (wall and CPU of that process).
        The pool's own row counts the wall and CPU of all of them, so :meth:`PipelineResult.total`
        leaves these rows out.
    """

    wall_s: float
    cpu_s: float
    ran: bool = True
    parallel: bool = False


class PipelineResult(BaseModel):
    """Where the stages wrote their results, and how long each took (``pipeline_result.json``,
    read first by ``kinmo report``).

    Attributes
    ----------
    out : Path
        The run folder as given (the stage paths start with it).
    stages : dict of str to list of str
        Stage (``split``, ``prepare``, ``gnn``, ``axis``, ``ranker``, ``table1``, ``pseudo``,
        ``ancsh``, ``table2``; prefixed ``synth-extra: `` for the run with generated shapes)
        → the files or folders it wrote.
    split : Path or None
        The train/test split every model of the run used (``out/split.json``).
    selector : str or None
        The candidate selector of the ``OBB_*`` rows and the pseudo-labels (``learned`` or
        ``paper``; None without refinement).
    ancsh_synth : dict or None
        ``--ancsh-synth N``: ``{"objects": N, "as": "mix" | "pretrain", "without": {"<category>
        <structure>": why}}``, the trained pairs that got no generated objects; None without.
    """

    out: Path
    split: Path | None = None
    selector: str | None = None
    stages: dict[str, list[str]] = Field(default_factory=dict)
    categories: list[str] = Field(default_factory=list)
    skipped_categories: dict[str, str] = Field(default_factory=dict)
    structures: dict[str, list[str]] = Field(default_factory=dict)
    report: Path | None = None
    timings: dict[str, StageTiming] = Field(default_factory=dict)
    synth_extra: Path | None = None
    ancsh_synth: dict[str, Any] | None = None

    def total(self) -> StageTiming:
        """The sum over the stages (rows of a pool, :attr:`StageTiming.parallel`, are counted
        by the pool's row)."""
        own = [t for t in self.timings.values() if not t.parallel]
        return StageTiming(wall_s=sum(t.wall_s for t in own), cpu_s=sum(t.cpu_s for t in own),
                           ran=any(t.ran for t in self.timings.values()))


def _cpu_seconds() -> float:
    """User + system CPU seconds of this process and its finished children."""
    import resource

    own, kids = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + kids.ru_utime + kids.ru_stime


class _Clock:
    """Times the stages of a run into ``timings`` and prints one line per stage."""

    def __init__(self, timings: dict[str, StageTiming], log: Callable[[str], None]) -> None:
        self.timings, self.log = timings, log

    def run(self, name: str, fn: Callable[[], Any]) -> Any:
        """Call ``fn``, record its wall and CPU time as stage ``name``, print them."""
        import time

        w0, c0 = time.perf_counter(), _cpu_seconds()
        value = fn()
        t = StageTiming(wall_s=round(time.perf_counter() - w0, 2), cpu_s=round(_cpu_seconds() - c0, 2))
        self.timings[name] = t
        self.log(f"[green]{name}[/]: {t.wall_s:.1f} s wall, {t.cpu_s:.1f} s CPU")
        return value

    def record(self, name: str, timing: StageTiming) -> None:
        """Record a stage timed elsewhere (in a worker of a pool), print it."""
        self.timings[name] = timing
        where = " (in parallel)" if timing.parallel else ""
        self.log(f"[green]{name}[/]: {timing.wall_s:.1f} s wall, {timing.cpu_s:.1f} s CPU{where}")

    def skipped(self, name: str) -> None:
        """Record stage ``name`` as up to date (not run)."""
        self.timings[name] = StageTiming(wall_s=0.0, cpu_s=0.0, ran=False)


def _stage(folder: Path, key: dict[str, Any], run: Callable[[], Any], log: Callable[[str], None], name: str,
           clock: _Clock | None = None, marker_name: str = ".done", after: Sequence[Path] = ()) -> bool:
    """Run ``run`` unless ``folder/<marker_name>`` holds ``key`` and is newer than the markers
    of the stages in ``after`` (:func:`stage_done`); returns True if it ran.

    With a ``clock``, the stage's time is recorded under ``name``. A stage writing one file
    into a folder shared with others (the split) gets its own ``marker_name``.
    """
    if stage_done(folder, key, marker_name, after):
        log(f"[dim]{name}: up to date ({literal(folder)})[/]")
        if clock is not None:
            clock.skipped(name)
        return False
    log(f"[bold cyan]{name}[/] -> {literal(folder)}")
    if clock is not None:
        clock.run(name, run)
    else:
        run()
    mark_done(folder, key, marker_name)
    return True




def _key_text(key: dict[str, Any]) -> str:
    return json.dumps(key, sort_keys=True, default=str)


def stage_done(folder: Path, key: dict[str, Any], marker_name: str = ".done",
               after: Sequence[Path] = ()) -> bool:
    """True when the stage of ``folder`` ran with ``key`` (its marker holds it) and after every
    stage it reads from.

    Parameters
    ----------
    folder : Path
    key : dict
    marker_name : str
    after : sequence of Path
        Folders of the stages whose outputs this one reads (models it evaluates, runs it
        starts from). A key names them by path, so it cannot see them trained again; as
        ``make`` does, the stage is stale when one of their ``.done`` markers is newer than
        its own. A folder without a marker (a model given from outside a run) is not checked.
    """
    marker = folder / marker_name
    if not (marker.is_file() and marker.read_text() == _key_text(key)):
        return False
    own = marker.stat().st_mtime_ns
    for up in after:
        m = Path(up) / ".done"
        if m.is_file() and m.stat().st_mtime_ns > own:
            return False
    return True


def mark_done(folder: Path, key: dict[str, Any], marker_name: str = ".done") -> None:
    """Write the marker of a stage that ran with ``key`` (a stage run outside :func:`_stage`)."""
    folder.mkdir(parents=True, exist_ok=True)
    write_text(folder / marker_name, _key_text(key))
