"""The process pool of kinmo's per-shape stages (prepare, render, pseudo-label).

Each of these stages applies one function to every shape folder of a dataset, and every
shape is independent. :func:`map_unordered` is the loop they share:

- **worker count**: ``workers`` as the command line takes it, 0 = one process per available
  CPU (:func:`available_cpus`, the CPUs this process may run on), never more processes than
  items (:func:`resolve_workers`); one worker means no pool at all: the items run in this
  process, in order, which is what tests and debuggers want;
- **spawn**: the pool starts its workers with the ``spawn`` method, never ``fork``: the
  parent has Rust (rayon) and torch thread pools running, and a forked child would inherit
  their locks in whatever state they were in;
- **bounded submission**: at most ``in_flight_per_worker * workers`` items are submitted at
  a time (2 per worker by default: one running, one queued so that no worker waits), and
  more are submitted as results arrive, so memory stays flat however many items there are,
  and stopping early (``on_result`` returning True, or Ctrl-C) cancels little work;
- **unordered results**: results are handed to ``on_result`` in this process as they
  complete (input order in the serial case); the stages record rows and sort them at the
  end, so completion order is all they need;
- **per-item failures**: an exception of one item in a worker (or the death of a worker,
  e.g. killed for memory) is turned into that item's result by ``on_error`` and the other
  items go on; in the serial case the per-item function's exceptions propagate (the stages'
  functions never raise for bad input, so an exception there is a bug, shown with its
  traceback);
- **clean shutdown**: whether the loop ends, stops early or is interrupted (Ctrl-C raises
  KeyboardInterrupt in this process; on a terminal the workers, in the same process group,
  are interrupted too), the pool is shut down before the call returns or raises: items not
  started are cancelled and the running ones are waited for, so no worker process outlives
  the call;
- **workers end with their parent**: a worker dies with the process that started it however
  that one ends: SIGTERM to the parent terminates the workers (a handler installed for the
  call, in the main thread, then the exception ``SystemExit(143)``, so callers' ``finally``
  blocks still run, e.g. the last manifest write of ``kinmo prepare``); SIGKILL (or any
  death) of the parent is seen by each worker (Linux: ``prctl(PR_SET_PDEATHSIG)``;
  everywhere: a thread polling :func:`os.getppid`), which then exits. The resource tracker
  of :mod:`multiprocessing` exits by itself once parent and workers are gone.

What stays in the stages: which items to run (resume / skip logic), how a result is recorded
(manifests, progress bar, counters), what a failed item's row looks like (``on_error``), and
per-worker set-up (``initializer``: thread counts, loading models once per worker). The
thread-count helpers the stages share are here (:func:`single_threaded_worker`,
:func:`torch_threads`); they import torch only where they set its threads, so a process that
only hands items to workers never loads it.

Scaling out: the unit of work is a plain picklable function of one item (a module-level
function, or a :func:`functools.partial` of one with picklable arguments) returning a
picklable result, with no shared state but what ``initializer`` sets up. The same ``fn``
can therefore be shipped unchanged to a cluster, e.g. ``ray.util.multiprocessing.Pool(
initializer=..., initargs=...).imap_unordered(fn, items)`` (a drop-in for
:mod:`multiprocessing`'s pool), or as ray tasks (``ray.remote(fn)`` submitted in bounded
batches with ``ray.wait``), feeding the same ``on_result`` callback. kinmo does not depend on
Ray; nothing here needs changing for that but the executor.
"""

from __future__ import annotations

import importlib
import os
import signal
import sys
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from multiprocessing import get_context
from typing import Any, TypeVar

__all__ = [
    "IN_FLIGHT_PER_WORKER", "available_cpus", "map_unordered", "resolve_workers", "sigterm_raises",
    "single_threaded_worker", "torch_threads",
]

T = TypeVar("T")
R = TypeVar("R")

IN_FLIGHT_PER_WORKER = 2
"""Items submitted per worker at a time by :func:`map_unordered`."""


def available_cpus() -> int:
    """The number of CPUs this process may run on.

    Returns
    -------
    int
        The size of the CPU affinity mask where the platform has one (it honours
        ``taskset`` and container CPU sets), else :func:`os.cpu_count`; at least 1.
    """
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - no affinity on this platform
        return os.cpu_count() or 1


def resolve_workers(workers: int, n_items: int) -> int:
    """The number of processes to use for ``n_items`` items.

    Parameters
    ----------
    workers : int
        The requested count; 0 (or less) = one per available CPU (:func:`available_cpus`).
    n_items : int
        Number of items to process.

    Returns
    -------
    int
        ``workers`` (or the CPU count), at most ``n_items``, at least 1. 1 means: run in
        this process. Resolving a resolved count again gives it back.
    """
    n = workers if workers > 0 else available_cpus()
    return max(1, min(n, n_items))


#: Seconds between two parent checks of a worker's watch thread.
PARENT_POLL_S = 0.5


def single_threaded_worker() -> None:
    """Start a worker process of a per-shape pool on one thread: torch's (set now) and
    rayon's (``RAYON_NUM_THREADS``, read when the Rust core first runs a parallel loop,
    unless the environment already sets it). The caller runs torch on one thread too
    (:func:`torch_threads`), so every worker count adds in the same order and writes the
    same bytes."""
    import torch  # the workers run the models; the process that starts them need not

    torch.set_num_threads(1)
    os.environ.setdefault("RAYON_NUM_THREADS", "1")


@contextmanager
def torch_threads(n: int) -> Iterator[None]:
    """torch's CPU threads set to ``n`` (0: unchanged) for the duration, then restored.

    With ``n <= 0`` in a process that has not imported torch there is nothing to set or
    restore, and torch is not imported: the process that only hands shapes to a pool of
    workers (``kinmo pseudo-label -j N``) starts them without paying torch's import (about
    2 s).
    """
    torch = importlib.import_module("torch") if n > 0 else sys.modules.get("torch")
    if torch is None:
        yield
        return
    old = torch.get_num_threads()
    if n > 0:
        torch.set_num_threads(n)
    try:
        yield
    finally:
        torch.set_num_threads(old)


def _exit_with_parent(parent_pid: int) -> None:
    """Make this (worker) process end when the process ``parent_pid`` that started it ends.

    Does nothing unless this is a :mod:`multiprocessing` child of ``parent_pid`` (an executor
    running the initializer in threads, or in processes it started otherwise, is left alone).
    """
    import multiprocessing

    parent = multiprocessing.parent_process()
    if os.getpid() == parent_pid or parent is None or parent.pid != parent_pid:
        return
    if sys.platform.startswith("linux"):
        try:
            import ctypes

            pr_set_pdeathsig = 1
            ctypes.CDLL(None, use_errno=True).prctl(pr_set_pdeathsig, int(signal.SIGKILL), 0, 0, 0)
        except (OSError, AttributeError):  # pragma: no cover - no prctl: the thread below
            pass
    if os.getppid() != parent_pid:  # the parent died before prctl was set
        os._exit(1)

    def watch() -> None:
        while True:
            time.sleep(PARENT_POLL_S)
            if os.getppid() != parent_pid:
                os._exit(1)

    threading.Thread(target=watch, name="kinmo-parent-watch", daemon=True).start()


def _start_worker(parent_pid: int, initializer: Callable[..., Any] | None,
                  initargs: tuple[Any, ...]) -> None:
    """Pool initializer: tie the worker to its parent, then the caller's initializer."""
    _exit_with_parent(parent_pid)
    if initializer is not None:
        initializer(*initargs)


def _terminate_workers(ex: ProcessPoolExecutor) -> None:
    # ProcessPoolExecutor has no public way to stop running items: terminate its processes
    # (the pool then reports itself broken and shuts down without waiting for them)
    for p in list((getattr(ex, "_processes", None) or {}).values()):
        try:
            p.terminate()
        except (OSError, ValueError):  # already gone
            pass


@contextmanager
def _sigterm_raises() -> Iterator[dict[str, bool]]:
    """While the block runs, SIGTERM raises ``SystemExit(128 + SIGTERM)`` in the main thread
    (elsewhere signals cannot be handled: nothing is installed). A second SIGTERM gets the
    default action. Yields a dict whose ``"terminated"`` says whether it happened."""
    state = {"terminated": False}
    if threading.current_thread() is not threading.main_thread():
        yield state
        return

    def on_term(signum: int, frame: Any) -> None:
        state["terminated"] = True
        signal.signal(signal.SIGTERM, signal.SIG_DFL)
        raise SystemExit(128 + signum)

    previous = signal.signal(signal.SIGTERM, on_term)
    try:
        yield state
    finally:
        signal.signal(signal.SIGTERM, previous)


#: Public name: commands wrap work that leaves temporary files (V-HACD folders, staged
#: objects) in it, so SIGTERM runs their cleanups (issue 21, finding 12).
sigterm_raises = _sigterm_raises


def map_unordered(
    fn: Callable[[T], R],
    items: Sequence[T],
    workers: int,
    on_result: Callable[[T, R], bool | None],
    on_error: Callable[[T, Exception], R],
    *,
    initializer: Callable[..., Any] | None = None,
    initargs: tuple[Any, ...] = (),
    in_flight_per_worker: int = IN_FLIGHT_PER_WORKER,
    max_tasks_per_child: int | None = None,
) -> bool:
    """Apply ``fn`` to every item, in worker processes, handing results over as they come.

    Parameters
    ----------
    fn : callable
        ``fn(item) -> result``. With more than one worker it runs in ``spawn`` worker
        processes, so it and every item and result must be picklable (a module-level
        function, or a :func:`functools.partial` of one).
    items : sequence
        The items, submitted in this order.
    workers : int
        Worker processes (:func:`resolve_workers`: 0 = one per available CPU, capped at
        ``len(items)``). 1: no pool, ``fn`` runs in this process, in order.
    on_result : callable
        ``on_result(item, result)``, called in this process for every item as it completes
        (completion order). Return True to stop: no further item is submitted, the results
        already completed in the same round are still handed over (in the serial case,
        nothing more runs), pending items are cancelled and running ones waited for.
    on_error : callable
        ``on_error(item, exception) -> result``: the result to record for an item whose
        ``fn`` raised in a worker (the exception is re-raised from the worker, with the
        worker's traceback as its ``__cause__``) or whose worker died
        (:class:`~concurrent.futures.process.BrokenProcessPool`). Its return value goes to
        ``on_result`` like any result. Not used in the serial case: there ``fn``'s
        exceptions propagate.
    initializer : callable, optional
        Called once in each worker process, with ``initargs``, before its first item (e.g.
        to set thread counts or load models once per process). Not called in the serial
        case: set up what ``fn`` needs in this process yourself.
    initargs : tuple
        Picklable arguments of ``initializer``.
    in_flight_per_worker : int
        Items submitted at a time per worker (bounded submission; >= 1).
    max_tasks_per_child : int, optional
        Replace a worker process by a fresh one after it has run this many items (and
        run ``initializer`` again there): bounds the memory of libraries whose
        process-wide state grows with every item (PyBullet in ``kinmo render``). None: a
        worker lives as long as the pool. Needs Python >= 3.11 (ignored before).

    Returns
    -------
    bool
        True if ``on_result`` asked to stop, else False (every item was handed over).

    Raises
    ------
    KeyboardInterrupt
        On Ctrl-C, after the pool is shut down (pending items cancelled, running ones
        waited for).
    SystemExit
        On SIGTERM (code 143, pool case, main thread), after the workers are terminated.
    BrokenProcessPool
        When a worker died: the items in flight are first handed to ``on_error``, then
        submitting the next item raises (the pool cannot be used any more).
    Exception
        Whatever ``fn`` raises in the serial case, or ``on_result`` / ``on_error`` raise.

    Notes
    -----
    The pool is shut down (``cancel_futures=True``, waiting for running items) on every
    way out, so no worker outlives the call.
    """
    n_workers = resolve_workers(workers, len(items))
    if n_workers == 1:
        for item in items:
            if on_result(item, fn(item)):
                return True
        return False

    max_in_flight = max(1, in_flight_per_worker) * n_workers
    with _sigterm_raises() as sigterm:
        recycle = ({"max_tasks_per_child": max_tasks_per_child}
                   if max_tasks_per_child is not None and sys.version_info >= (3, 11) else {})
        ex = ProcessPoolExecutor(
            max_workers=n_workers,
            mp_context=get_context("spawn"),
            initializer=_start_worker,
            initargs=(os.getpid(), initializer, initargs),
            **recycle,
        )
        return _run_pool(ex, fn, items, on_result, on_error, max_in_flight, sigterm)


def _run_pool(ex: ProcessPoolExecutor, fn: Callable[[T], R], items: Sequence[T],
              on_result: Callable[[T, R], bool | None], on_error: Callable[[T, Exception], R],
              max_in_flight: int, sigterm: dict[str, bool]) -> bool:
    stopped = False
    try:
        pending: dict[Future[R], T] = {}
        it = iter(items)

        def fill() -> None:
            while len(pending) < max_in_flight:
                try:
                    item = next(it)
                except StopIteration:
                    return
                pending[ex.submit(fn, item)] = item

        fill()
        while pending:
            done, _ = wait(pending, return_when=FIRST_COMPLETED)
            for fut in done:
                item = pending.pop(fut)
                try:
                    result = fut.result()
                except Exception as e:  # raised by fn in the worker, or the worker died
                    result = on_error(item, e)
                if on_result(item, result):
                    stopped = True
            if stopped:
                break
            fill()
    finally:
        if sigterm["terminated"]:
            _terminate_workers(ex)
        ex.shutdown(wait=True, cancel_futures=True)
    return stopped
