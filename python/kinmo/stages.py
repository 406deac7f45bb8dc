"""The machinery of kinmo's per-shape stages: ``kinmo prepare``, ``kinmo render`` and
``kinmo pseudo-label``.

Each of these stages applies one pure, picklable function to every shape folder of a dataset
and writes one output per shape. What they share lives here; what stays in each stage is the
work on one shape, what its row holds, and how it decides that a shape is up to date.

- **Jobs** (:func:`shape_jobs`): the shape folders under a dataset root
  (:func:`kinmo.data.readers.find_shapes`), each with its output key (:func:`cache_key`: the
  folder's path relative to the root, ``/`` replaced by ``__``).
- **Fingerprints**: :func:`source_fingerprint` of a shape folder (names, sizes and
  modification times of its files), :func:`file_fingerprint` of one input file (a
  checkpoint), :func:`digest` of several such strings and :func:`json_digest` of a
  JSON-ready value (a configuration). An output records the fingerprints of its inputs and
  configuration; :func:`matches` compares what it recorded with what the run expects.
- **Resume**: :meth:`ShapeStage.resume` records the result of every job that is up to date
  (the stage's own test, reading the output itself rather than the manifest, so an
  interrupted run resumes correctly) and returns the jobs left to run; ``force`` skips it.
- **Worker failures**: a shape whose worker raised or died (killed for memory) becomes a
  failed row through the stage's ``on_error`` and the run goes on; :func:`worker_error` is
  its one-line reason, ``"<source>: worker process failed: <Type>: <message>"``.
- **Manifest** (:func:`write_manifest`, :func:`read_manifest`): ``manifest.csv`` (one row
  per item, the columns of the stage's :class:`StageRow` subclass, written with
  ``surrogateescape`` so non-UTF-8 folder names keep their bytes) and ``manifest.json``:

  .. code-block:: json

     {"kinmo_version": "...", <the stage's header: versions, root, config, sizes>,
      "complete": false, "counts": {"ok": 0, "skipped": 0, "failed": 0},
      "<rows>": [<one dict per row, the CSV's columns>]}

  ``complete`` is written ``false`` before the first shape, rewritten at most every
  :data:`MANIFEST_INTERVAL_S` seconds while shapes complete, and set ``true`` at the end
  when every job has a result; both files are written atomically (:mod:`kinmo.io`).
- **The run** (:class:`ShapeStage`): the output folder's lock (one run at a time,
  :func:`kinmo.io.folder_lock`), removal of an interrupted run's leftovers, the rich
  progress bar with its counters (:class:`kinmo.progress.CountingBar`), the summary counts,
  the periodic and final saves, stopping at the first failure (``--strict``), and the map
  over the executor seam (:func:`kinmo.executor.map_unordered`: the local ``spawn`` pool or
  Ray).
- **Diagnostics**: resumed shapes, failed shapes and worker failures are logged on the
  ``kinmo.stages`` logger (:mod:`logging`; ``kinmo -v`` shows them, see
  :mod:`kinmo.progress`).

Length: over 500 lines, about 40 % of them docstrings; the code is one topic (what the
three stages share) and splitting it would only scatter the manifest contract over two files.
"""

from __future__ import annotations

import csv
import dataclasses
import hashlib
import io
import json
import logging
import os
import shutil
import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any, ClassVar, Generic, TypeVar

from kinmo import __version__
from kinmo.data.readers import find_shapes
from kinmo.errors import KinmoDataError
from kinmo.executor import map_unordered
from kinmo.io import folder_lock, write_json, write_text
from kinmo.progress import CountingBar

__all__ = [
    "MANIFEST_INTERVAL_S",
    "STATUSES",
    "ShapeStage",
    "StageRow",
    "cache_key",
    "digest",
    "file_fingerprint",
    "json_digest",
    "manifest_csv",
    "matches",
    "one_line",
    "read_manifest",
    "shape_jobs",
    "source_fingerprint",
    "worker_error",
    "write_manifest",
]

logger = logging.getLogger(__name__)

#: Minimum seconds between two manifest rewrites during a run.
MANIFEST_INTERVAL_S = 2.0
#: Row statuses counted in ``manifest.json`` (``counts``).
STATUSES: tuple[str, ...] = ("ok", "skipped", "failed")

R = TypeVar("R")
J = TypeVar("J")
RowT = TypeVar("RowT", bound="StageRow")


def one_line(text: object) -> str:
    """``str(text)`` with every whitespace run (newlines included) made one space."""
    return " ".join(str(text).split())


# ------------------------------------------------------------------------------ fingerprints


def source_fingerprint(folder: str | Path) -> str:
    """Fingerprint of a shape folder's files: relative paths, sizes, modification times.

    Parameters
    ----------
    folder : str or Path

    Returns
    -------
    str
        16 hex digits (SHA-256 prefix). Changes when any file is added, removed, resized or
        touched.

    Raises
    ------
    KinmoDataError
        The folder cannot be listed.
    """
    folder = Path(folder)
    entries: list[str] = []

    def walk(d: Path, rel: str) -> None:
        with os.scandir(d) as it:
            for e in it:
                name = f"{rel}{e.name}"
                if e.is_dir(follow_symlinks=False):
                    walk(Path(e.path), name + "/")
                else:
                    try:
                        st = e.stat()
                        entries.append(f"{name}\0{st.st_size}\0{st.st_mtime_ns}")
                    except OSError:
                        entries.append(f"{name}\0?")

    try:
        walk(folder, "")
    except OSError as e:
        raise KinmoDataError(folder, f"cannot list the folder: {e.strerror or e}") from None
    # surrogateescape: a file name that is not UTF-8 counts by its bytes, never fails
    h = hashlib.sha256("\n".join(sorted(entries)).encode("utf-8", "surrogateescape"))
    return h.hexdigest()[:16]


def file_fingerprint(path: str | Path) -> str:
    """``"<resolved path>:<size>:<mtime ns>"`` of one input file (e.g. a checkpoint).

    Raises
    ------
    OSError
        The file cannot be read (``stat``).
    """
    path = Path(path)
    st = path.stat()
    return f"{path.resolve()}:{st.st_size}:{st.st_mtime_ns}"


def digest(*parts: str) -> str:
    """16 hex digits of SHA-256 over ``parts`` joined by ``|``."""
    return hashlib.sha256("|".join(parts).encode()).hexdigest()[:16]


def json_digest(value: Any) -> str:
    """16 hex digits of SHA-256 over ``json.dumps(value, sort_keys=True)``."""
    return hashlib.sha256(json.dumps(value, sort_keys=True).encode()).hexdigest()[:16]


def matches(recorded: Mapping[str, Any], expected: Mapping[str, Any]) -> bool:
    """True when ``recorded`` (an output's metadata) holds every item of ``expected``."""
    return all(recorded.get(k) == v for k, v in expected.items())


# ------------------------------------------------------------------------------------ jobs


def cache_key(folder: str | Path, root: str | Path) -> str:
    """Output key of a shape folder: its path relative to ``root``, ``/`` made ``__``.

    Just the folder name for the usual flat layout ``root/<id>/``, and when ``root`` is the
    shape folder itself or does not contain it; nested layouts such as
    ``root/<category>/<id>/`` never collide.
    """
    folder, root = Path(folder), Path(root)
    try:
        rel = folder.relative_to(root)
    except ValueError:
        rel = Path(folder.name)
    if rel == Path("."):
        rel = Path(folder.name)
    return "__".join(rel.parts)


def shape_jobs(root: str | Path, required: bool = True) -> list[tuple[Path, str]]:
    """The shape folders under ``root`` with their output keys (:func:`cache_key`).

    Parameters
    ----------
    root : str or Path
        A dataset folder (either format, possibly nested) or one shape folder.
    required : bool
        Raise when there is none.

    Returns
    -------
    list of (Path, str)

    Raises
    ------
    KinmoDataError
        ``root`` is not a folder, or (``required``) holds no shape folder.
    """

    root = Path(root)
    folders = find_shapes(root)
    if required and not folders:
        raise KinmoDataError(
            root, "no shape folders found (folders holding result.json or mobility_v2.json)"
        )
    return [(f, cache_key(f, root)) for f in folders]


def worker_error(source: str | Path, e: BaseException) -> str:
    """The one-line reason of an item whose worker raised or died (e.g. killed for memory)."""
    return one_line(f"{source}: worker process failed: {type(e).__name__}: {e}")


# -------------------------------------------------------------------------------- manifest


@dataclasses.dataclass
class StageRow:
    """Base of a stage's manifest row: a dataclass whose fields include ``columns``.

    Subclasses set ``columns`` (the CSV's columns, in order) and declare the fields with
    ``int`` / ``float`` annotations where the CSV holds numbers (an empty cell reads back as
    ``None``, or as the field's default when the annotation does not admit ``None``).
    Every row has a ``status`` (one of :data:`STATUSES`).
    """

    columns: ClassVar[tuple[str, ...]] = ()

    def as_dict(self) -> dict[str, Any]:
        """Dict in ``columns`` order."""
        d = dataclasses.asdict(self)
        return {k: d[k] for k in self.columns}

    @classmethod
    def from_csv(cls: type[RowT], d: Mapping[str, str]) -> RowT:
        """A row from a ``manifest.csv`` line (strings), converted by field annotation.

        Raises
        ------
        ValueError, KeyError
            A column is missing or a number does not parse.
        """
        kw: dict[str, Any] = {}
        for fl in dataclasses.fields(cls):
            if fl.name not in cls.columns:
                continue
            v, ann = d[fl.name], str(fl.type)
            if "int" in ann or "float" in ann:
                num = (int if "int" in ann else float)(v) if v != "" else None
                if num is None and "None" not in ann and fl.default is not dataclasses.MISSING:
                    num = fl.default
                kw[fl.name] = num
            else:
                kw[fl.name] = v
        return cls(**kw)


def manifest_csv(rows: Iterable[StageRow], columns: Sequence[str]) -> str:
    """CSV text of ``rows`` (``None`` written as an empty cell)."""
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=list(columns), lineterminator="\n")
    w.writeheader()
    for r in rows:
        w.writerow({k: "" if v is None else v for k, v in r.as_dict().items()})
    return buf.getvalue()


def write_manifest(
    out: Path, rows: Sequence[StageRow], columns: Sequence[str], header: Mapping[str, Any],
    rows_key: str, complete: bool,
) -> None:
    """Write ``out/manifest.csv`` and ``out/manifest.json`` atomically (module docstring).

    Parameters
    ----------
    out : Path
        The stage's output folder.
    rows : sequence of StageRow
        In the order to write.
    columns : sequence of str
    header : mapping
        The stage's fields of ``manifest.json`` (after ``kinmo_version``).
    rows_key : str
        The key of the rows in ``manifest.json`` (``"shapes"``, ``"frames"``).
    complete : bool
        Every job of the run has its rows.
    """

    # surrogateescape: non-UTF-8 folder names are written back as their bytes (read_manifest
    # reads them the same way); manifest.json escapes them (\udcxx)
    write_text(out / "manifest.csv", manifest_csv(rows, columns), errors="surrogateescape")
    write_json(out / "manifest.json", {
        "kinmo_version": __version__,
        **header,
        "complete": complete,
        "counts": {s: sum(r.status == s for r in rows) for s in STATUSES},  # type: ignore[attr-defined]
        rows_key: [r.as_dict() for r in rows],
    })


def read_manifest(path: str | Path, row_type: type[RowT]) -> list[RowT]:
    """Read ``manifest.csv`` (or an output folder holding one) back into ``row_type`` rows.

    Raises
    ------
    KinmoDataError
        Missing or malformed manifest (other columns than ``row_type.columns``, a number
        that does not parse).
    """
    path = Path(path)
    if path.is_dir():
        path = path / "manifest.csv"
    try:
        with open(path, newline="", encoding="utf-8", errors="surrogateescape") as f:
            reader = csv.DictReader(f)
            if tuple(reader.fieldnames or ()) != row_type.columns:
                raise KinmoDataError(path, f"unexpected columns {reader.fieldnames}")
            return [row_type.from_csv(d) for d in reader]
    except FileNotFoundError:
        raise KinmoDataError(path, "file is missing") from None
    except (ValueError, KeyError, TypeError, csv.Error) as e:
        if isinstance(e, KinmoDataError):
            raise
        raise KinmoDataError(path, f"malformed manifest: {e}") from None


# ------------------------------------------------------------------------------------ run


def _status_rows(result: Any) -> Sequence[Any]:
    return result if isinstance(result, list) else [result]


def _reason(row: Any) -> str:
    return str(getattr(row, "error", "") or getattr(row, "reason", ""))


class ShapeStage(Generic[R]):
    """One run of a per-shape stage over an output folder (module docstring).

    Use as a context manager: entering takes the folder's lock (raising at once if another
    run holds it), removes the leftovers of an interrupted run (``scratch``), starts the
    progress bar and saves once with no results (``complete: false``); leaving saves the
    results (``complete`` when every job has one; not when an error ends a run that has no
    result yet), removes ``scratch`` again and releases the lock, also when the run is
    interrupted.

    Parameters
    ----------
    out : Path
        The output folder (must exist).
    command : str
        The command, for the lock's error (``"kinmo prepare"``).
    n_jobs : int
        Jobs (shapes) of the run.
    save : callable, optional
        ``save(results, complete)`` writes the stage's tables (e.g. a partial of
        :func:`write_manifest`); called on entering (unless ``save_at_start`` is False),
        at most every ``save_every`` seconds as results arrive, and on leaving.
    bar_total : int, optional
        Items of the progress bar (rows: frames for render), ``n_jobs`` by default.
    title, description : str
        Progress bar title and description.
    counters : dict of str to str, optional
        Statuses counted on the bar (name -> rich colour), ``{"failed": "red"}`` by default.
    progress : bool
        Show the bar.
    on_result : callable, optional
        Called with every result as it is recorded (the caller's hook).
    stop_on_failure : bool
        Stop the map at the first result holding a failed row (``--strict``).
    scratch : sequence of str
        Glob patterns (relative to ``out``) of leftovers removed on entering and leaving
        (files unlinked, folders removed).
    save_every : float
        Seconds between periodic saves.
    save_at_start : bool

    Attributes
    ----------
    results : list
        One per finished job, in completion order; a result is a row (an object with a
        ``status``) or a list of rows.
    n_skipped : int
        Jobs found up to date by :meth:`resume`.
    stopped : bool
        The map stopped at a failure.
    """

    def __init__(
        self, out: Path, command: str, n_jobs: int, *,
        save: Callable[[list[R], bool], None] | None = None,
        bar_total: int | None = None, title: str = "", description: str = "",
        counters: dict[str, str] | None = None, progress: bool = True,
        on_result: Callable[[R], None] | None = None, stop_on_failure: bool = False,
        scratch: Sequence[str] = (".*.tmp",), save_every: float = MANIFEST_INTERVAL_S,
        save_at_start: bool = True,
    ) -> None:
        self.out, self.command, self.n_jobs = Path(out), command, n_jobs
        self._save, self._save_every, self._save_at_start = save, save_every, save_at_start
        self._on_result, self._stop_on_failure = on_result, stop_on_failure
        self._scratch = tuple(scratch)
        self.bar = CountingBar(n_jobs if bar_total is None else bar_total, progress, title,
                               description, counters)
        self.results: list[R] = []
        self.n_skipped = 0
        self.stopped = False
        self._last_save = 0.0
        self._lock: Any = None

    # -- context
    def __enter__(self) -> ShapeStage[R]:
        self._lock = folder_lock(self.out, self.command)
        self._lock.__enter__()
        try:
            self._clean()
            if self._save is not None and self._save_at_start:
                self._save([], False)
            self._last_save = time.monotonic()
            self.bar.__enter__()
        except BaseException:
            self._lock.__exit__(None, None, None)
            raise
        return self

    def __exit__(self, *exc: Any) -> None:
        try:
            self.bar.__exit__(*exc)
            if self._save is not None and (self.results or exc[0] is None):
                self._save(list(self.results), self.complete)
            self._clean()
        finally:
            self._lock.__exit__(*exc)

    def _clean(self) -> None:
        n = 0
        for pattern in self._scratch:
            for p in self.out.glob(pattern):
                try:
                    if p.is_dir() and not p.is_symlink():
                        shutil.rmtree(p)
                    else:
                        p.unlink()
                    n += 1
                except OSError:
                    pass
        if n:
            logger.debug("%s: removed %d leftovers of an interrupted run", self.out, n)

    @property
    def complete(self) -> bool:
        """Every job has its result."""
        return len(self.results) == self.n_jobs

    # -- recording
    def record(self, result: R) -> bool:
        """Record one job's result: counters, bar, hook, periodic save.

        Returns
        -------
        bool
            True when the run must stop (``stop_on_failure`` and a row failed).
        """
        self.results.append(result)
        rows = _status_rows(result)
        failed = [r for r in rows if r.status == "failed"]
        for r in failed[:1]:
            logger.info("failed: %s", _reason(r))
        self.bar.advance(len(rows), **{c: sum(r.status == c for r in rows)
                                       for c in self.bar.counts})
        if self._on_result is not None:
            self._on_result(result)
        now = time.monotonic()
        if self._save is not None and now - self._last_save >= self._save_every:
            self._save(list(self.results), False)
            self._last_save = now
        return self._stop_on_failure and bool(failed)

    def resume(self, jobs: Sequence[J], current: Callable[[J], R | None] | None) -> list[J]:
        """Record the result of every up-to-date job; return the others, in order.

        Parameters
        ----------
        jobs : sequence
        current : callable or None
            ``current(job)``: the job's result when its output is up to date, else None.
            None (``--force``): every job runs.
        """
        if current is None:
            return list(jobs)
        todo = []
        for job in jobs:
            res = current(job)
            if res is None:
                todo.append(job)
            else:
                self.record(res)
                self.n_skipped += 1
        if self.n_skipped:
            logger.info("%s: resumed, %d of %d shapes up to date (skipped)", self.out,
                        self.n_skipped, len(jobs))
        return todo

    def map(
        self, fn: Callable[[J], R], jobs: Sequence[J], workers: int,
        on_error: Callable[[J, Exception], R], **kwargs: Any,
    ) -> bool:
        """Run ``fn`` over ``jobs`` on the executor, recording every result.

        Parameters
        ----------
        fn, jobs, workers, on_error
            As :func:`kinmo.executor.map_unordered`; ``on_error`` turns a worker failure
            into the job's result (it is logged as a warning).
        **kwargs
            ``initializer``, ``initargs``, ``max_tasks_per_child``, ``executor``. Each
            worker process first sets the ``kinmo`` loggers to this process's level, with
            a handler to its stderr, then runs ``initializer(*initargs)``.

        Returns
        -------
        bool
            True when the run stopped at a failure (:attr:`stopped`).
        """
        def failed(job: J, e: Exception) -> R:
            res = on_error(job, e)
            logger.warning("%s", _reason(_status_rows(res)[0]))
            return res

        # worker processes log at this process's level (their records go to their stderr)
        level = logging.getLogger("kinmo").getEffectiveLevel()
        kwargs["initargs"] = (level, kwargs.pop("initializer", None),
                              tuple(kwargs.pop("initargs", ())))
        self.stopped = bool(map_unordered(fn, jobs, workers, lambda job, res: self.record(res),
                                          failed, initializer=_init_worker, **kwargs))
        return self.stopped


def _init_worker(level: int, initializer: Callable[..., Any] | None,
                 initargs: tuple[Any, ...]) -> None:
    """In a worker process: the ``kinmo`` loggers at the parent's level, writing to stderr,
    then the stage's own initializer."""
    log = logging.getLogger("kinmo")
    if not log.handlers:
        handler = logging.StreamHandler()
        handler.setFormatter(logging.Formatter("%(levelname)-8s %(message)s"))
        log.addHandler(handler)
    log.setLevel(level)
    if initializer is not None:
        initializer(*initargs)
