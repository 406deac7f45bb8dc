"""Worker processes end with their parent: SIGTERM or SIGKILL to a process running
:func:`kinmo.parallel.map_unordered` (or ``kinmo prepare -j 2``) leaves no worker and no
resource tracker behind (issue 14)."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest
from conftest import REPO, write_cabinet

pytestmark = pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs /proc (Linux)")


def _stat(pid: int) -> tuple[str, int] | None:
    """(state, parent pid) of a process, None when it is gone."""
    try:
        text = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return None
    fields = text[text.rindex(")") + 2:].split()
    return fields[0], int(fields[1])


def _children(pid: int) -> list[int]:
    out = []
    for d in Path("/proc").iterdir():
        if d.name.isdigit():
            st = _stat(int(d.name))
            if st is not None and st[1] == pid:
                out.append(int(d.name))
    return out


def _alive(pid: int) -> bool:
    st = _stat(pid)
    return st is not None and st[0] not in ("Z", "X")


def _kill_and_check(proc: subprocess.Popen, sig: int, kids: list[int]) -> None:
    os.kill(proc.pid, sig)
    proc.wait(timeout=30)
    deadline = time.monotonic() + 5.0
    while time.monotonic() < deadline and any(_alive(k) for k in kids):
        time.sleep(0.05)
    left = [k for k in kids if _alive(k)]
    assert not left, f"processes left behind after {signal.Signals(sig).name}: {left}"


def _cleanup(proc: subprocess.Popen) -> None:
    # the test's own process group (start_new_session): nothing stays behind even on failure
    try:
        os.killpg(proc.pid, signal.SIGKILL)
    except ProcessLookupError:
        pass
    proc.wait(timeout=30)


SCRIPT = """
import sys, time
from pathlib import Path

def work(i):
    Path(sys.argv[1], f"started-{i}").touch()
    time.sleep(120)
    return i

if __name__ == "__main__":
    from kinmo.parallel import map_unordered
    map_unordered(work, list(range(6)), 2, on_result=lambda i, r: None,
                  on_error=lambda i, e: None)
"""


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGKILL])
def test_map_unordered_workers_end_with_their_parent(tmp_path: Path, sig: int) -> None:
    script = tmp_path / "sleepy.py"
    script.write_text(textwrap.dedent(SCRIPT))
    proc = subprocess.Popen([sys.executable, str(script), str(tmp_path)], start_new_session=True,
                            cwd=tmp_path)
    try:
        deadline = time.monotonic() + 60
        while len(list(tmp_path.glob("started-*"))) < 2:  # both workers are in their items
            assert time.monotonic() < deadline and proc.poll() is None, "workers did not start"
            time.sleep(0.05)
        kids = _children(proc.pid)
        assert len(kids) >= 2  # the workers (and the resource tracker)
        _kill_and_check(proc, sig, kids)
    finally:
        _cleanup(proc)


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGKILL])
def test_prepare_killed_leaves_no_process_and_an_incomplete_manifest(tmp_path: Path, sig: int) -> None:
    from kinmo.errors import KinmoDataError
    from kinmo.data.cache import load_cache

    root = tmp_path / "data"
    for i in range(60):
        write_cabinet(root / f"s{i:02d}")
    out = tmp_path / "cache"
    log = open(tmp_path / "log.txt", "wb")
    proc = subprocess.Popen(
        [sys.executable, "-m", "kinmo", "prepare", str(root), "--out", str(out), "-j", "2", "-q",
         "--n-points", "30000"],
        start_new_session=True, cwd=REPO, stdout=log, stderr=subprocess.STDOUT,
    )
    try:
        deadline = time.monotonic() + 60
        while not list(out.glob("*.npz")):  # the workers are running
            assert time.monotonic() < deadline and proc.poll() is None, \
                (tmp_path / "log.txt").read_text()
            time.sleep(0.05)
        kids = _children(proc.pid)
        assert len(kids) >= 2
        _kill_and_check(proc, sig, kids)
    finally:
        _cleanup(proc)
        log.close()
    assert not json.loads((out / "manifest.json").read_text())["complete"]
    with pytest.raises(KinmoDataError, match="incomplete cache"):
        load_cache(out)
    if sig == signal.SIGTERM:
        assert proc.returncode == 128 + signal.SIGTERM
        assert "Traceback" not in (tmp_path / "log.txt").read_text()


def test_the_parent_check_leaves_non_workers_alone() -> None:
    """The pool initializer ties only spawn children of the caller to it: run here (as an
    executor of threads would) it just calls the caller's initializer."""
    from kinmo.parallel import _start_worker

    seen = []
    _start_worker(os.getpid(), seen.append, (1,))
    _start_worker(os.getppid(), seen.append, (2,))  # not our multiprocessing parent either
    assert seen == [1, 2]
