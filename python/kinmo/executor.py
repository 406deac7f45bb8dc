"""Where kinmo's per-shape stages run: the local process pool or a Ray cluster.

``kinmo prepare | render | pseudo-label ... --executor SPEC`` picks the executor of the
stage's per-shape loop; the stages call :func:`map_unordered` here, which has the contract
of :func:`kinmo.parallel.map_unordered` (same arguments, same callbacks, same failure
handling) plus one argument, ``executor``:

- ``"local"`` (default): :func:`kinmo.parallel.map_unordered`, the ``spawn`` process pool of
  this machine (``workers`` processes, 0 = one per CPU, 1 = in this process);
- ``"ray"``: a Ray instance started here for the call, with ``workers`` CPUs (0 = every
  CPU of this machine), shut down at the end; if Ray is already initialised in this process
  (e.g. by a notebook or a test), that instance is used and left running;
- ``"ray:auto"``: the running Ray cluster this machine belongs to (``ray start --head`` on
  one node, ``ray start --address HEAD:6379`` on the others);
- ``"ray:ADDRESS"``: the Ray cluster at ``ADDRESS`` (``HOST:PORT`` of the head node's GCS,
  or ``ray://HOST:10001`` for Ray Client).

On Ray every item is one **Ray task** (``num_cpus=1``, no retry) running the same pure
per-item function as the local pool. Submission is bounded (``in_flight_per_worker`` tasks
per CPU, CPUs = ``workers`` or, for 0, the cluster's CPU count), so memory in this process
stays flat for any number of shapes; results are handed to ``on_result`` in this process as
they complete (``ray.wait``), which is where the stages update their rich progress bar,
manifests and counters, exactly as with the local pool. The per-item functions write their
outputs atomically themselves (:mod:`kinmo.io`), so resume and the output-folder lock (held
by this process) work unchanged. A task that raised, or whose worker process died, becomes
that item's result through ``on_error`` (with the remote exception), and the other items go
on. ``initializer(*initargs)`` runs once per Ray worker process, before its first item of
this call (e.g. loading the models of ``kinmo pseudo-label`` once per worker).

On a cluster the input and output folders must be at the same path on every node (a shared
file system), and kinmo must be installed in the same environment on every node.

Ray is optional: ``pip install kinmo[ray]``; asking for it without it installed raises
:class:`~kinmo.errors.KinmoError` with that instruction.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, TypeVar

from kinmo.errors import KinmoError
from kinmo.parallel import IN_FLIGHT_PER_WORKER, resolve_workers
from kinmo.parallel import map_unordered as _local_map

__all__ = ["EXECUTOR_HELP", "ExecutorSpec", "map_unordered", "parse_executor"]

T = TypeVar("T")
R = TypeVar("R")

EXECUTOR_HELP = (
    "Where the per-shape work runs: 'local' (process pool), 'ray' (a local Ray with --workers "
    "CPUs), 'ray:auto' (the running Ray cluster) or 'ray:ADDRESS'."
)
"""The ``--executor`` help text shared by the commands."""


@dataclass(frozen=True)
class ExecutorSpec:
    """A parsed ``--executor`` value.

    Attributes
    ----------
    kind : {"local", "ray"}
    address : str or None
        Ray cluster address (``"auto"``, ``HOST:PORT``, ``ray://HOST:PORT``); None: start a
        local Ray instance (or use the one already initialised in this process).
    """

    kind: str
    address: str | None = None


def parse_executor(spec: str | ExecutorSpec) -> ExecutorSpec:
    """Parse ``local``, ``ray``, ``ray:auto`` or ``ray:ADDRESS``.

    Parameters
    ----------
    spec : str or ExecutorSpec

    Returns
    -------
    ExecutorSpec

    Raises
    ------
    KinmoError
        Any other value (one line, naming the accepted forms).
    """
    if isinstance(spec, ExecutorSpec):
        return spec
    s = spec.strip()
    if s == "local":
        return ExecutorSpec("local")
    if s == "ray":
        return ExecutorSpec("ray")
    if s.startswith("ray:") and s[4:].strip():
        return ExecutorSpec("ray", s[4:].strip())
    raise KinmoError(f"unknown executor {spec!r}: use 'local', 'ray', 'ray:auto' or 'ray:ADDRESS'")


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
    executor: str | ExecutorSpec = "local",
) -> bool:
    """Apply ``fn`` to every item on the chosen executor (module docstring).

    Parameters
    ----------
    fn, items, workers, on_result, on_error, initializer, initargs, in_flight_per_worker
    max_tasks_per_child
        As :func:`kinmo.parallel.map_unordered` (on Ray: the task's ``max_calls``, after
        which Ray replaces its worker process). On Ray, ``workers`` is the number of CPUs
        of a Ray started here (0: every CPU of this machine) or, on a cluster, the most
        tasks in flight per ``in_flight_per_worker`` (0: the cluster's CPU count); ``fn``,
        the items and the results travel by (cloud)pickle, and ``on_error`` is used for
        every failed item, also when there is a single worker.
    executor : str or ExecutorSpec
        ``"local"``, ``"ray"``, ``"ray:auto"`` or ``"ray:ADDRESS"`` (:func:`parse_executor`).

    Returns
    -------
    bool
        True if ``on_result`` asked to stop.

    Raises
    ------
    KinmoError
        Bad ``executor`` value, Ray not installed, or the Ray cluster cannot be reached.
    KeyboardInterrupt
        On Ctrl-C, after the tasks in flight are cancelled.
    """
    spec = parse_executor(executor)
    if spec.kind == "local":
        return _local_map(fn, items, workers, on_result, on_error, initializer=initializer,
                          initargs=initargs, in_flight_per_worker=in_flight_per_worker,
                          max_tasks_per_child=max_tasks_per_child)
    if not items:
        return False
    ray = _import_ray()
    started = _ray_init(ray, spec.address, workers)
    try:
        n_cpus = workers if workers > 0 else max(1, int(ray.cluster_resources().get("CPU", 1)))
        n_cpus = resolve_workers(n_cpus, len(items))
        return _ray_map(ray, fn, items, n_cpus, on_result, on_error, initializer, initargs,
                        max(1, in_flight_per_worker), max_tasks_per_child)
    finally:
        if started:
            ray.shutdown()


def _import_ray() -> Any:
    try:
        import ray
    except ImportError:
        raise KinmoError(
            "--executor ray needs Ray, which is not installed: pip install 'kinmo[ray]' "
            "(or pip install 'ray[default]')"
        ) from None
    return ray


def _ray_init(ray: Any, address: str | None, workers: int) -> bool:
    """Connect to (or start) Ray; True if this call started it (and must shut it down)."""
    if ray.is_initialized():
        return False
    kwargs: dict[str, Any] = {"include_dashboard": False, "log_to_driver": False,
                              "configure_logging": False}
    if address is None:
        from kinmo.parallel import available_cpus

        kwargs["num_cpus"] = workers if workers > 0 else available_cpus()
    else:
        kwargs["address"] = address
    try:
        ray.init(**kwargs)
    except (Exception, SystemExit) as e:  # ConnectionError, ...; Ray exits when no GCS answers
        where = f"the Ray cluster at {address!r}" if address else "a local Ray instance"
        msg = " ".join(str(e).split())
        raise KinmoError(f"cannot start or reach {where}: {type(e).__name__}: {msg}") from None
    return True


# --- in the Ray worker processes -------------------------------------------------------

_INIT_DONE: set[bytes] = set()
_INIT_LOCK = threading.Lock()


def _run_task(fn: Callable[[Any], Any], item: Any, initializer: Callable[..., Any] | None,
              initargs: tuple[Any, ...], init_key: bytes) -> Any:
    """One item in a Ray worker: the call's initializer once per process, then ``fn(item)``."""
    if initializer is not None and init_key not in _INIT_DONE:
        with _INIT_LOCK:
            if init_key not in _INIT_DONE:
                initializer(*initargs)
                _INIT_DONE.add(init_key)
    return fn(item)


def _ray_map(ray: Any, fn: Callable[[T], R], items: Sequence[T], n_cpus: int,
             on_result: Callable[[T, R], bool | None], on_error: Callable[[T, Exception], R],
             initializer: Callable[..., Any] | None, initargs: tuple[Any, ...],
             in_flight_per_worker: int, max_tasks_per_child: int | None = None) -> bool:
    import uuid

    recycle = {"max_calls": max_tasks_per_child} if max_tasks_per_child else {}
    task = ray.remote(num_cpus=1, max_retries=0, **recycle)(_run_task)
    fn_ref = ray.put(fn)  # shared by every task: shipped to the object store once
    init_key = uuid.uuid4().bytes  # a new key per call: the initializer runs again
    max_in_flight = in_flight_per_worker * n_cpus
    pending: dict[Any, T] = {}
    it = iter(items)
    stopped = False

    def fill() -> None:
        while len(pending) < max_in_flight:
            try:
                item = next(it)
            except StopIteration:
                return
            ref = task.remote(fn_ref, item, initializer, initargs, init_key)
            pending[ref] = item

    try:
        fill()
        while pending:
            done, _ = ray.wait(list(pending), num_returns=1)
            for ref in done:
                item = pending.pop(ref)
                try:
                    result = ray.get(ref)
                except Exception as e:  # RayTaskError (fn raised), WorkerCrashedError, ...
                    result = on_error(item, _remote_cause(e))
                if on_result(item, result):
                    stopped = True
            if stopped:
                break
            fill()
    finally:
        for ref in pending:  # stopped early or interrupted: cancel what is left
            ray.cancel(ref, force=False)
    return stopped


def _remote_cause(e: Exception) -> Exception:
    """The exception the task raised (RayTaskError wraps it) or the Ray error itself."""
    cause = getattr(e, "cause", None)
    return cause if isinstance(cause, Exception) else e
