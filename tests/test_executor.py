"""kinmo.executor: the local pool or Ray tasks behind prepare, render and pseudo-label.

Ray runs locally with 2 CPUs (one instance for the module, as a cluster of one node). The
per-item functions are builtins or kinmo functions, so that Ray workers unpickle them without
importing this test module.
"""

from __future__ import annotations

import math
import os
import sys
from functools import partial
from pathlib import Path

import numpy as np
import pytest
import ray  # in the test extra: CI always has it

from kinmo.errors import KinmoError
from kinmo.executor import ExecutorSpec, map_unordered, parse_executor
from pool_helpers import collect


@pytest.fixture(scope="module")
def local_ray():
    """A local Ray of 2 CPUs, shared by the tests of this module (map_unordered uses it and
    leaves it running because it did not start it)."""
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False, configure_logging=False,
             object_store_memory=100 * 2**20)
    yield
    ray.shutdown()


_collect = partial(collect, map_unordered)


def test_parse_executor():
    assert parse_executor("local") == ExecutorSpec("local")
    assert parse_executor("ray") == ExecutorSpec("ray", None)
    assert parse_executor("ray:auto") == ExecutorSpec("ray", "auto")
    assert parse_executor(" ray:10.0.0.5:6379 ") == ExecutorSpec("ray", "10.0.0.5:6379")
    assert parse_executor("ray:ray://head:10001").address == "ray://head:10001"
    for bad in ("", "dask", "ray:", "Ray", "local:2"):
        with pytest.raises(KinmoError, match="unknown executor"):
            parse_executor(bad)


def test_local_is_the_process_pool():
    stopped, res, err = _collect(math.sqrt, [1.0, 4.0, 9.0], 1, executor="local")
    assert not stopped and not err and res == {1.0: 1.0, 4.0: 2.0, 9.0: 3.0}


def test_missing_ray_is_a_clear_error(monkeypatch):
    monkeypatch.setitem(sys.modules, "ray", None)  # import ray -> ImportError
    with pytest.raises(KinmoError, match=r"pip install 'kinmo\[ray\]'"):
        _collect(math.sqrt, [1.0], 1, executor="ray")


def test_ray_tasks_results_and_per_item_failures(local_ray):
    # math.sqrt(-1) raises ValueError in the worker: that item's result, the others go on
    items = [4.0, -1.0, 9.0, 16.0, 25.0]
    stopped, res, err = _collect(math.sqrt, items, 2, executor="ray")
    assert not stopped
    assert res == {4.0: 2.0, -1.0: "failed", 9.0: 3.0, 16.0: 4.0, 25.0: 5.0}
    assert set(err) == {-1.0} and isinstance(err[-1.0], ValueError)


def test_ray_worker_death_is_that_items_failure(local_ray):
    # os._exit kills the Ray worker process running item 3: only item 3 fails
    stopped, res, err = _collect(os._exit, [3], 2, executor="ray")
    assert res == {3: "failed"} and "3" not in str(type(err[3]))
    stopped, res, err = _collect(abs, [-1, -2, -3], 2, executor="ray")
    assert res == {-1: 1, -2: 2, -3: 3} and not err


def test_ray_initializer_runs_in_the_workers(local_ray):
    # the initializer sets an attribute of a module in each worker before its first item
    fn = partial(getattr, math)
    stopped, res, err = _collect(fn, ["kinmo_executor_test"] * 1, 2, executor="ray",
                                 initializer=setattr, initargs=(math, "kinmo_executor_test", 7))
    assert not err and res == {"kinmo_executor_test": 7}
    assert not hasattr(math, "kinmo_executor_test")  # not in this process


def test_ray_stop_early(local_ray):
    seen = []

    def on_result(item, result):
        seen.append(item)
        return True  # stop at the first result

    stopped = map_unordered(abs, list(range(-20, 0)), 1, on_result, lambda i, e: None,
                            executor="ray", in_flight_per_worker=1)
    assert stopped and len(seen) == 1


def _npz(path: Path) -> dict[str, np.ndarray]:
    with np.load(path, allow_pickle=False) as z:
        return {k: z[k] for k in z.files}


@pytest.mark.exactdata
def test_prepare_on_ray_matches_local_and_resumes(local_ray, mobility_root: Path, tmp_path: Path):
    from kinmo.prepare import PrepareConfig, prepare_dataset

    root = tmp_path / "data"
    root.mkdir()
    for oid in ("10849", "3596"):
        (root / oid).symlink_to(mobility_root / oid, target_is_directory=True)
    (root / "broken").mkdir()
    (root / "broken" / "mobility_v2.json").write_text("not json")
    cfg = PrepareConfig(n_points=64)
    local = prepare_dataset(root, tmp_path / "local", cfg, workers=1, progress=False)
    on_ray = prepare_dataset(root, tmp_path / "ray", cfg, workers=2, progress=False,
                             executor="ray")
    assert [(r.id, r.status) for r in on_ray.rows] == [(r.id, r.status) for r in local.rows]
    assert [r.status for r in on_ray.rows].count("failed") == 1
    for r in local.rows:
        if r.status == "ok":
            a, b = _npz(tmp_path / "local" / f"{r.id}.npz"), _npz(tmp_path / "ray" / f"{r.id}.npz")
            assert a.keys() == b.keys()
            for k in a:
                np.testing.assert_array_equal(a[k], b[k], err_msg=k)
    again = prepare_dataset(root, tmp_path / "ray", cfg, workers=2, progress=False, executor="ray")
    assert again.count("skipped") == 2 and again.count("ok") == 0


@pytest.mark.exactdata
def test_render_on_ray(local_ray, mobility_root: Path, tmp_path: Path):
    from kinmo.render.dataset import RenderConfig, render_dataset

    root = tmp_path / "objects"
    root.mkdir()
    (root / "10849").symlink_to(mobility_root / "10849", target_is_directory=True)
    cfg = RenderConfig(width=64, height=48, seed=3)
    local = render_dataset(root, tmp_path / "local", 2, cfg, workers=1, progress=False)
    on_ray = render_dataset(root, tmp_path / "ray", 2, cfg, workers=2, progress=False,
                            executor="ray")
    assert [r.status for r in on_ray.rows] == [r.status for r in local.rows] == ["ok", "ok"]
    for r in local.rows:
        a, b = _npz(tmp_path / "local" / r.file), _npz(tmp_path / "ray" / r.file)
        np.testing.assert_array_equal(a["points"], b["points"])


def test_cli_rejects_a_bad_executor(tmp_path: Path):
    from typer.testing import CliRunner

    from kinmo.cli import app

    for cmd in (["prepare", str(tmp_path)], ["render", str(tmp_path), "--out", str(tmp_path)]):
        res = CliRunner().invoke(app, [*cmd, "--executor", "dask"])
        assert res.exit_code == 2 and "unknown executor" in res.output, res.output
