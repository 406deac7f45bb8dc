"""kinmo.parallel.map_unordered: the process-pool loop of prepare, render and pseudo-label.

The per-item functions are builtins (math.sqrt, pow, os.getenv, os._exit, time.sleep), so
that ``spawn`` workers unpickle them without importing this test module.
"""

from __future__ import annotations

import math
import multiprocessing
import os
import time
from concurrent.futures import Future, ThreadPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from functools import partial

import pytest

import kinmo.parallel
from kinmo.parallel import available_cpus, map_unordered, resolve_workers
from kinmo.prepare import _init_worker
from pool_helpers import collect


_collect = partial(collect, map_unordered)


# ----------------------------------------------------------------------------- worker count


def test_resolve_workers(monkeypatch):
    monkeypatch.setattr(os, "sched_getaffinity", lambda pid: {0, 1, 2}, raising=False)
    assert available_cpus() == 3
    assert resolve_workers(0, 10) == 3  # 0 = all available CPUs
    assert resolve_workers(-1, 10) == 3
    assert resolve_workers(0, 2) == 2  # never more processes than items
    assert resolve_workers(5, 10) == 5  # an explicit count may exceed the CPUs
    assert resolve_workers(5, 4) == 4
    assert resolve_workers(1, 10) == 1
    assert resolve_workers(0, 0) == 1 and resolve_workers(4, 0) == 1
    for w in (0, 1, 2, 7):
        n = resolve_workers(w, 5)
        assert resolve_workers(n, 5) == n  # resolving again changes nothing


def test_available_cpus_is_the_affinity():
    if hasattr(os, "sched_getaffinity"):
        assert available_cpus() == len(os.sched_getaffinity(0))
    assert available_cpus() >= 1


# ----------------------------------------------------------------------------- serial


def test_serial_runs_in_order_in_this_process():
    seen = []
    stopped = map_unordered(math.sqrt, [9.0, 4.0, 1.0], 1, lambda i, r: seen.append((i, r)),
                            on_error=lambda i, e: pytest.fail("no error expected"))
    assert stopped is False and seen == [(9.0, 3.0), (4.0, 2.0), (1.0, 1.0)]
    # one item: no pool whatever the worker count
    calls = []
    map_unordered(lambda x: calls.append(os.getpid()) or x, [1], 0, lambda i, r: None,
                  on_error=lambda i, e: None)
    assert calls == [os.getpid()]


def test_serial_exceptions_propagate():
    errors = []
    seen = []
    with pytest.raises(ValueError, match="math domain error"):
        map_unordered(math.sqrt, [4.0, -1.0, 9.0], 1, lambda i, r: seen.append(i),
                      on_error=lambda i, e: errors.append(i))
    assert seen == [4.0] and errors == []


def test_serial_stop():
    seen = []
    stopped = map_unordered(math.sqrt, [1.0, 4.0, 9.0], 1,
                            lambda i, r: seen.append(i) or i == 4.0, on_error=lambda i, e: None)
    assert stopped is True and seen == [1.0, 4.0]


def test_serial_does_not_call_the_initializer(monkeypatch):
    monkeypatch.delenv("RAYON_NUM_THREADS", raising=False)
    _, results, _ = _collect(os.getenv, ["RAYON_NUM_THREADS"], 1, initializer=_init_worker,
                             initargs=(3,))
    assert results == {"RAYON_NUM_THREADS": None}


# ----------------------------------------------------------------------------- pool


def test_pool_gives_every_result_like_the_serial_path():
    items = list(range(12))
    fn = partial(pow, exp=2)  # a picklable partial, the pattern the stages use
    s_stopped, serial, s_errors = _collect(fn, items, 1)
    p_stopped, pooled, p_errors = _collect(fn, items, 2)
    assert serial == pooled == {i: i * i for i in items}
    assert not s_stopped and not p_stopped and not s_errors and not p_errors


def test_pool_failure_of_one_item_is_reported_for_it_and_the_others_go_on():
    items = [4.0, -1.0, 9.0, 16.0, -4.0, 25.0]
    stopped, results, errors = _collect(math.sqrt, items, 2)
    assert stopped is False
    assert set(results) == set(items)  # every item handed over, failed ones too
    assert set(errors) == {-1.0, -4.0}
    assert all(isinstance(e, ValueError) and "math domain error" in str(e)
               for e in errors.values())
    assert results[-1.0] == results[-4.0] == "failed"  # on_error's value goes to on_result
    assert {i: results[i] for i in (4.0, 9.0, 16.0, 25.0)} == {4.0: 2.0, 9.0: 3.0, 16.0: 4.0,
                                                               25.0: 5.0}


def test_pool_worker_death_is_reported_per_item():
    # os._exit(3) kills the worker process running it: the pool breaks
    stopped, results, errors = _collect(os._exit, [3, 4], 2)
    assert stopped is False and set(results) == set(errors) == {3, 4}
    assert all(isinstance(e, BrokenProcessPool) for e in errors.values())
    assert not multiprocessing.active_children()


def test_pool_runs_the_initializer_in_each_worker(monkeypatch):
    monkeypatch.delenv("RAYON_NUM_THREADS", raising=False)
    got = []
    map_unordered(os.getenv, ["RAYON_NUM_THREADS"] * 4, 2, lambda i, r: got.append(r),
                  on_error=lambda i, e: pytest.fail(repr(e)), initializer=_init_worker,
                  initargs=(3,))
    assert got == ["3"] * 4


def _pid_after(_item: int) -> int:
    time.sleep(0.05)  # keep both workers busy, so each process really runs its share
    return os.getpid()


def test_pool_recycles_workers_after_max_tasks_per_child():
    # kinmo render recycles its workers (PyBullet's process state grows per object): with
    # max_tasks_per_child=2, 8 items on 2 workers need at least 4 distinct processes.
    got: list[int] = []
    map_unordered(_pid_after, list(range(8)), 2, lambda i, r: got.append(r),
                  on_error=lambda i, e: pytest.fail(repr(e)), max_tasks_per_child=2)
    assert len(got) == 8
    assert len(set(got)) >= 4 and os.getpid() not in got
    plain: list[int] = []
    map_unordered(_pid_after, list(range(8)), 2, lambda i, r: plain.append(r),
                  on_error=lambda i, e: pytest.fail(repr(e)))
    assert len(set(plain)) <= 2


def test_pool_keyboard_interrupt_shuts_the_pool_down():
    handed = []

    def on_result(item, result):
        handed.append(time.perf_counter())
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        map_unordered(time.sleep, [0.5] * 40, 2, on_result, on_error=lambda i, e: None)
    assert len(handed) == 1
    # the items not started were cancelled: running them all would take ~10 s
    assert time.perf_counter() - handed[0] < 5.0
    assert not multiprocessing.active_children()


# ----------------------------------------------------------------------------- the loop logic
# (threads in place of processes: fast, and the submissions can be observed)


class _ThreadPool(ThreadPoolExecutor):
    """A stand-in for ProcessPoolExecutor that counts what is in flight."""

    in_flight = 0
    most = 0

    def __init__(self, max_workers, mp_context=None, initializer=None, initargs=()):
        super().__init__(max_workers, initializer=initializer, initargs=initargs)

    def submit(self, fn, /, *args, **kwargs) -> Future:
        cls = type(self)
        cls.in_flight += 1
        cls.most = max(cls.most, cls.in_flight)
        return super().submit(fn, *args, **kwargs)


@pytest.fixture
def threads(monkeypatch):
    _ThreadPool.in_flight = _ThreadPool.most = 0
    monkeypatch.setattr(kinmo.parallel, "ProcessPoolExecutor", _ThreadPool)
    return _ThreadPool


def test_submission_is_bounded(threads):
    seen = []

    def on_result(item, result):
        threads.in_flight -= 1
        seen.append(item)

    map_unordered(lambda x: time.sleep(0.001) or x, list(range(50)), 3, on_result,
                  on_error=lambda i, e: None)
    assert sorted(seen) == list(range(50))
    assert threads.most == 2 * 3
    threads.in_flight = threads.most = 0
    map_unordered(lambda x: x, list(range(50)), 3, lambda i, r: setattr(
        threads, "in_flight", threads.in_flight - 1), on_error=lambda i, e: None,
        in_flight_per_worker=1)
    assert threads.most == 3


def test_pool_stop_submits_nothing_more(threads):
    seen = []
    stopped = map_unordered(lambda x: x, list(range(100)), 2,
                            lambda i, r: seen.append(i) or True, on_error=lambda i, e: None)
    assert stopped is True
    assert 1 <= len(seen) <= 4  # only the first round (at most 2 per worker in flight)
