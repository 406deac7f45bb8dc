"""``kinmo prepare``: turn dataset folders into a cache of part graphs.

:func:`prepare_dataset` finds every shape folder under a dataset root (PartNet or
PartNet-Mobility, :func:`kinmo.data.readers.find_shapes`), builds each shape's
:class:`~kinmo.data.graph.PartGraph` (:func:`kinmo.data.build.build_graph`) in worker
processes, and writes:

- ``<out>/<key>.npz``: one graph per shape (atomic). ``key`` is the shape folder's path
  relative to the root with ``/`` replaced by ``__`` (just the folder name for the usual
  flat layout ``root/<id>/``; the folder name when the root is itself a shape folder), so
  nested layouts such as ``root/<category>/<id>/`` never collide;
- ``<out>/manifest.csv`` and ``<out>/manifest.json``: one row per shape (columns
  :data:`MANIFEST_COLUMNS`), status ``ok`` (built now), ``skipped`` (cache up to date) or
  ``failed`` (with the one-line reason, naming the file), rewritten atomically as shapes
  complete (at most every :data:`MANIFEST_INTERVAL_S` seconds, and at the end).
  ``manifest.json`` says whether the run finished (``complete``): a run writes
  ``complete: false`` before its first shape, so a run killed at any point leaves an
  incomplete manifest, and readers (:func:`kinmo.data.cache.check_manifest`, used by
  :func:`kinmo.data.cache.load_cache`) refuse it, saying how many shapes are missing and how
  to resume.

Resume: a shape is skipped when its ``.npz`` exists and records the same cache version
(:data:`kinmo.data.graph.CACHE_VERSION`), the same configuration (:class:`PrepareConfig`)
and the same source fingerprint (:func:`source_fingerprint`: names, sizes and modification
times of every file of the shape folder), and is intact (read whole, its arrays' checksum
checked, :meth:`kinmo.data.graph.PartGraph.load`: a damaged file is rebuilt, never called
up to date). The decision reads the ``.npz`` itself, not the manifest, so an interrupted
run (stray ``.tmp`` files, which are removed at start; manifest rows without a cache file)
resumes correctly. One run at a time per cache folder (a lock
file, ``.lock``, enforces it).

Parallelism: :func:`prepare_one` is a pure function of picklable arguments returning a
:class:`ManifestRow`; it reads, builds, saves and reports one shape and never raises for bad
input. :func:`prepare_dataset` runs it over the shapes with the stage machinery of
:mod:`kinmo.stages` (manifest, resume, lock, progress bar, worker-failure rows) on the
executor chosen with ``executor`` (:mod:`kinmo.executor`: a ``spawn`` process pool, so Rust
thread pools are never forked, or Ray).

Odd input: a shape that fails (a mesh without faces included, even one of several of a
part) is a ``failed`` row naming the file; file and folder names that are not UTF-8 are kept
(surrogateescape: ``manifest.csv`` holds their bytes, ``manifest.json`` has ``\\udcxx``
escapes); an ``out`` that is a file is a :class:`~kinmo.errors.KinmoDataError`.

Default cache folder (:func:`default_cache_dir`): ``./cache/<name of the dataset folder>``
relative to the current directory.

Length: over 500 lines, about 35 % of them docstrings: one topic, the ``kinmo prepare`` stage
(its options, manifest rows, the build of one shape with its resume check, the manifest check
later stages call, and the run); what it shares with the other per-shape stages is
:mod:`kinmo.stages`.
"""

from __future__ import annotations

import logging
import os
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from functools import partial
from pathlib import Path
from typing import Any, ClassVar

from kinmo import stages
from kinmo.data.build import build_graph
from kinmo.data.graph import CACHE_VERSION, PartGraph
from kinmo.data.readers import detect_format, read_meta, read_shape
from kinmo.errors import KinmoDataError
from kinmo.io import check_outputs_apart, output_dir
from kinmo.parallel import available_cpus, resolve_workers
from kinmo.stages import (
    MANIFEST_INTERVAL_S,
    ShapeStage,
    StageRow,
    cache_key,
    matches,
    one_line,
    source_fingerprint,
)

logger = logging.getLogger(__name__)

__all__ = [
    "MANIFEST_COLUMNS",
    "MANIFEST_INTERVAL_S",
    "ManifestRow",
    "PrepareConfig",
    "PrepareResult",
    "cache_key",
    "default_cache_dir",
    "prepare_dataset",
    "prepare_one",
    "read_manifest",
    "source_fingerprint",
]

MANIFEST_COLUMNS: tuple[str, ...] = (
    "id",
    "category",
    "format",
    "n_nodes",
    "n_leaves",
    "n_sibling_edges",
    "n_moving_joints",
    "status",
    "error",
    "fingerprint",
    "seconds",
    "source",
)


@dataclass(frozen=True)
class PrepareConfig:
    """Everything that changes the content of a cached graph.

    Attributes
    ----------
    n_points : int
        Surface points per node.
    seed : int
        Sampling seed.
    contact_tolerance : float
        Contact threshold, fraction of the shape's bounding-box diagonal.
    distance_cap : float
        Distance clip, fraction of the diagonal.
    hierarchy : {"result", "merged"}
        Hierarchy file preference (:func:`kinmo.data.readers.read_shape`).
    """

    n_points: int = 1024
    seed: int = 0
    contact_tolerance: float = 0.01
    distance_cap: float = 0.1
    hierarchy: str = "result"

    def __post_init__(self) -> None:
        if self.n_points < 1:
            raise ValueError(f"n_points must be >= 1, got {self.n_points}")
        if not 0 <= self.contact_tolerance <= self.distance_cap:
            raise ValueError(
                "need 0 <= contact_tolerance <= distance_cap, got "
                f"{self.contact_tolerance}, {self.distance_cap}"
            )
        if self.hierarchy not in ("result", "merged"):
            raise ValueError(f"hierarchy must be 'result' or 'merged', got {self.hierarchy!r}")

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready dict (stored in every graph's ``meta["config"]``)."""
        return asdict(self)


@dataclass
class ManifestRow(StageRow):
    """One shape's line in the manifest (see :data:`MANIFEST_COLUMNS`).

    Counts are ``None`` when unknown (failed shapes). ``error`` is one line naming the file
    and the problem, empty unless ``status == "failed"``. ``fingerprint`` is
    :func:`source_fingerprint` of the shape folder, ``seconds`` the time spent on it.
    """

    id: str
    source: str
    status: str
    category: str = ""
    format: str = ""
    n_nodes: int | None = None
    n_leaves: int | None = None
    n_sibling_edges: int | None = None
    n_moving_joints: int | None = None
    error: str = ""
    fingerprint: str = ""
    seconds: float = 0.0

    columns: ClassVar[tuple[str, ...]] = MANIFEST_COLUMNS


@dataclass
class PrepareResult:
    """Outcome of :func:`prepare_dataset`.

    Attributes
    ----------
    out : Path
        The cache folder.
    rows : list of ManifestRow
        One per shape processed, sorted by ``id``.
    n_shapes : int
        Shapes found under the root.
    seconds : float
        Wall time of the run.
    stopped : bool
        True when ``strict`` stopped the run at a failure (some shapes not processed).
    """

    out: Path
    rows: list[ManifestRow]
    n_shapes: int
    seconds: float
    stopped: bool = False

    def count(self, status: str) -> int:
        """Number of rows with this status."""
        return sum(r.status == status for r in self.rows)

    @property
    def failures(self) -> list[ManifestRow]:
        """Failed rows."""
        return [r for r in self.rows if r.status == "failed"]

    @property
    def ok(self) -> bool:
        """True when every shape was processed and none failed."""
        return not self.stopped and not self.failures and len(self.rows) == self.n_shapes


# ------------------------------------------------------------------------------ per shape


def _cached_row(npz: Path, key: str, folder: Path, config: PrepareConfig, fp: str) -> ManifestRow | None:
    """The row of an up-to-date cache file, or None when it must be (re)built.

    The file is read whole and its checksum checked (:meth:`PartGraph.load`): a corrupt file
    is rebuilt, never reported up to date."""

    if not npz.is_file():
        return None
    try:
        graph = PartGraph.load(npz)
    except KinmoDataError as e:  # unreadable, corrupt or foreign file: rebuild it
        logger.info("rebuilding a damaged cache file: %s", e)
        return None
    meta, category, fmt = graph.meta, graph.category, graph.format
    if not matches(meta, {"cache_version": CACHE_VERSION, "config": config.as_dict(),
                          "fingerprint": fp}):
        return None
    c = meta.get("counts", {})
    return ManifestRow(
        id=key,
        source=str(folder),
        status="skipped",
        category=category,
        format=fmt,
        n_nodes=c.get("n_nodes"),
        n_leaves=c.get("n_leaves"),
        n_sibling_edges=c.get("n_sibling_edges"),
        n_moving_joints=c.get("n_moving_joints"),
        fingerprint=fp,
    )


def _up_to_date(folder: Path, key: str, out: Path, config: PrepareConfig) -> ManifestRow | None:
    t0 = time.perf_counter()
    try:
        fp = source_fingerprint(folder)
    except KinmoDataError:
        return None
    row = _cached_row(out / f"{key}.npz", key, folder, config, fp)
    if row is not None:
        row.seconds = round(time.perf_counter() - t0, 4)
    return row


def prepare_one(
    path: str | Path,
    out_dir: str | Path,
    config: PrepareConfig,
    key: str | None = None,
    force: bool = False,
) -> ManifestRow:
    """Build, save and report one shape; never raises for bad input.

    A pure function of its (picklable) arguments, safe to run in any worker process or on
    another machine sharing the file system (e.g. wrapped by ``ray.remote``).

    Parameters
    ----------
    path : str or Path
        The shape folder.
    out_dir : str or Path
        The cache folder; the graph goes to ``out_dir/<key>.npz`` (atomic write).
    config : PrepareConfig
    key : str, optional
        Cache file stem; the folder name by default.
    force : bool
        Rebuild even when the cache file is up to date.

    Returns
    -------
    ManifestRow
        ``ok`` (built now), ``skipped`` (an up-to-date cache file exists) or ``failed`` with
        a one-line ``error``: a :class:`~kinmo.errors.KinmoDataError`'s message (naming the
        file), or for an unexpected exception ``"<folder>: internal error <Type>: <message>"``.
    """

    t0 = time.perf_counter()
    folder = Path(path)
    out_dir = Path(out_dir)
    key = key or folder.name
    row = ManifestRow(id=key, source=str(folder), status="failed")
    try:
        row.fingerprint = source_fingerprint(folder)
        if not force:
            cached = _cached_row(out_dir / f"{key}.npz", key, folder, config, row.fingerprint)
            if cached is not None:
                cached.seconds = round(time.perf_counter() - t0, 4)
                return cached
        shape = read_shape(folder, config.hierarchy)  # type: ignore[arg-type]
        row.category, row.format = shape.category, shape.format.value
        graph = build_graph(
            shape,
            n_points=config.n_points,
            seed=config.seed,
            contact_tolerance=config.contact_tolerance,
            distance_cap=config.distance_cap,
        )
        graph.meta["config"] = config.as_dict()
        graph.meta["fingerprint"] = row.fingerprint
        graph.meta["key"] = key
        graph.save(out_dir / f"{key}.npz")
        c = graph.meta["counts"]
        row.n_nodes, row.n_leaves = c["n_nodes"], c["n_leaves"]
        row.n_sibling_edges, row.n_moving_joints = c["n_sibling_edges"], c["n_moving_joints"]
        row.status = "ok"
    except KinmoDataError as e:
        row.error = one_line(str(e))
    except Exception as e:  # a bug or an environment problem: still one row, the run goes on
        row.error = one_line(f"{folder}: internal error {type(e).__name__}: {e}")
    if row.status == "failed":
        # Best effort: fill the format and category when they are readable.
        try:
            row.format = row.format or detect_format(folder).value
            row.category = row.category or read_meta(folder)[0]
        except Exception:
            pass
    row.seconds = round(time.perf_counter() - t0, 4)
    return row


# ------------------------------------------------------------------------------- manifest


def read_manifest(path: str | Path) -> list[ManifestRow]:
    """Read ``manifest.csv`` (or a cache folder holding one) back into rows.

    Raises
    ------
    KinmoDataError
        Missing or malformed manifest.
    """
    return stages.read_manifest(path, ManifestRow)


# ------------------------------------------------------------------------------- the run


def default_cache_dir(root: str | Path) -> Path:
    """``./cache/<name of root>`` (relative to the current directory)."""
    return Path("cache") / Path(root).resolve().name


def _init_worker(threads: int) -> None:
    # Rust (rayon) thread pools size themselves on first use: give each worker its share.
    os.environ.setdefault("RAYON_NUM_THREADS", str(threads))


def _prepare_job(job: tuple[Path, str], out: Path, config: PrepareConfig, force: bool
                 ) -> ManifestRow:
    f, key = job
    return prepare_one(f, out, config, key, force)


def _worker_failed(job: tuple[Path, str], e: Exception) -> ManifestRow:
    # the worker raised or died (e.g. killed for memory)
    f, key = job
    return ManifestRow(
        id=key, source=str(f), status="failed",
        error=stages.worker_error(f, e),
    )


def prepare_dataset(
    root: str | Path,
    out: str | Path | None = None,
    config: PrepareConfig | None = None,
    workers: int = 0,
    strict: bool = False,
    force: bool = False,
    progress: bool = True,
    on_row: Callable[[ManifestRow], None] | None = None,
    executor: str = "local",
) -> PrepareResult:
    """Prepare every shape under ``root`` into the cache folder ``out``.

    Parameters
    ----------
    root : str or Path
        Dataset folder (either format, possibly nested) or a single shape folder.
    out : str or Path, optional
        Cache folder, created if needed; :func:`default_cache_dir` by default.
    config : PrepareConfig, optional
    workers : int
        Worker processes; 0 = one per available CPU; 1 = in this process.
    strict : bool
        Stop at the first failed shape (pending shapes are cancelled).
    force : bool
        Rebuild shapes whose cache file is up to date.
    progress : bool
        Show a rich progress bar (on stderr).
    on_row : callable, optional
        Called in this process with each row as it completes.
    executor : str
        ``local``, ``ray``, ``ray:auto`` or ``ray:ADDRESS`` (:mod:`kinmo.executor`).

    Returns
    -------
    PrepareResult
        Failed shapes are reported in it and in the manifest, never raised.

    Raises
    ------
    KinmoDataError
        ``root`` is not a folder or holds no shape folder.
    KinmoError
        Another run holds the cache folder's lock.
    KinmoUsageError
        The cache folder is, lies inside or holds ``root`` (outputs never overwrite inputs).
    """
    t0 = time.perf_counter()
    config = config or PrepareConfig()
    root = Path(root)
    jobs = stages.shape_jobs(root)
    out = out if out is not None else default_cache_dir(root)
    check_outputs_apart(out, [root])
    out = output_dir(out)

    def save(rows: list[ManifestRow], complete: bool) -> None:
        stages.write_manifest(
            out, sorted(rows, key=lambda r: r.id), MANIFEST_COLUMNS,
            {"cache_version": CACHE_VERSION, "root": str(root), "config": config.as_dict(),
             "n_shapes": len(jobs)}, "shapes", complete)

    # The manifest is written incomplete first: a run killed at any point leaves
    # ``complete: false`` (readers then say how many graphs are missing, check_manifest).
    stage: ShapeStage[ManifestRow] = ShapeStage(
        out, "kinmo prepare", len(jobs), save=save, title="prepare", description=root.name,
        progress=progress, on_result=on_row, stop_on_failure=strict)
    with stage:
        # Up-to-date shapes are settled here, so that a resumed run starts no worker for
        # them (prepare_one checks again, for callers that use it alone).
        todo = stage.resume(jobs, None if force else (lambda job: _up_to_date(*job, out, config)))
        n_workers = resolve_workers(workers, len(todo))
        stage.map(
            partial(_prepare_job, out=out, config=config, force=force), todo, n_workers,
            _worker_failed, initializer=_init_worker,
            initargs=(max(1, available_cpus() // n_workers),), executor=executor,
        )
    return PrepareResult(
        out=out,
        rows=sorted(stage.results, key=lambda r: r.id),
        n_shapes=len(jobs),
        seconds=time.perf_counter() - t0,
        stopped=stage.stopped,
    )
