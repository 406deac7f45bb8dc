"""Atomic writes and the output-folder lock (kinmo.io)."""

from __future__ import annotations

import json
import os
import stat
import subprocess
import sys

import pytest

from kinmo.errors import KinmoError
import kinmo.io as kio
from kinmo.io import atomic_path, atomic_write, folder_lock, write_json, write_text


def test_atomic_write_leaves_the_old_file_when_the_writer_fails(tmp_path):
    p = tmp_path / "a.txt"
    write_text(p, "old")

    def boom(fh):
        fh.write("half")
        raise RuntimeError("interrupted")

    with pytest.raises(RuntimeError):
        atomic_write(p, boom)
    assert p.read_text() == "old"
    assert sorted(x.name for x in tmp_path.iterdir()) == ["a.txt"]  # no temporary left
    write_json(p, {"k": [1, 2]})
    assert json.loads(p.read_text()) == {"k": [1, 2]}


def test_atomic_path_skips_taken_names_and_gives_a_normal_files_permissions(tmp_path, monkeypatch):
    # the next temporary names of this process are taken: by a stale file and by a link
    # to a file that must not be touched; the write goes on under the name after them
    serial = next(kio._TMP_SERIAL) + 1
    pid = os.getpid()
    stale = tmp_path / f".a.obj.{pid}-{serial}.tmp"
    stale.write_text("stale")
    victim = tmp_path / "victim.txt"
    victim.write_text("keep")
    (tmp_path / f".a.obj.{pid}-{serial + 1}.tmp").symlink_to(victim)
    old = os.umask(0o027)
    try:
        with atomic_path(tmp_path / "a.obj") as tmp:
            assert tmp.name == f".a.obj.{pid}-{serial + 2}.tmp" and tmp.read_bytes() == b""
            tmp.write_text("v 0 0 0\n")
    finally:
        os.umask(old)
    out = tmp_path / "a.obj"
    assert out.read_text() == "v 0 0 0\n" and stale.read_text() == "stale" and victim.read_text() == "keep"
    assert stat.S_IMODE(out.stat().st_mode) == 0o640  # 0o666 less the umask, as a plain open gives
    monkeypatch.setattr(kio, "_TMP_TRIES", 0)
    with pytest.raises(FileExistsError, match="no free temporary name"):
        with atomic_path(tmp_path / "b.obj"):
            pass
    assert not (tmp_path / "b.obj").exists()


def test_folder_lock_excludes_a_second_process_and_is_released(tmp_path):
    holder = (
        "import sys, time\n"
        "from kinmo.io import folder_lock\n"
        "with folder_lock(sys.argv[1], 'kinmo test'):\n"
        "    print('locked', flush=True)\n"
        "    sys.stdin.readline()\n"
    )
    proc = subprocess.Popen([sys.executable, "-c", holder, str(tmp_path)], stdin=subprocess.PIPE,
                            stdout=subprocess.PIPE, text=True)
    try:
        assert proc.stdout.readline().strip() == "locked"
        with pytest.raises(KinmoError, match=r"another kinmo test is writing this folder"):
            with folder_lock(tmp_path, "kinmo test"):
                pass
    finally:
        proc.communicate("\n", timeout=60)
    assert proc.returncode == 0
    # released with the other process: the lock is free again, and re-entrant across blocks
    ran = []
    with folder_lock(tmp_path, "kinmo test"):
        ran.append(1)
    with folder_lock(tmp_path, "kinmo test"):
        ran.append(2)
    assert ran == [1, 2]


# ------------------------------------------------------------------- outputs never overwrite inputs


def test_outputs_apart_from_inputs(tmp_path):
    from kinmo.errors import KinmoUsageError
    from kinmo.io import check_outputs_apart

    data = tmp_path / "data"
    (data / "obj1").mkdir(parents=True)
    asset = tmp_path / "assets" / "chair.glb"
    asset.parent.mkdir()
    asset.write_bytes(b"glb")
    for out, inputs, written in [
        (data, [data], None),                          # OUT is the input
        (data / "obj1", [data], None),                 # OUT inside the input
        (data / "obj1" / "x", [data / "obj1"], None),
        (tmp_path, [data], None),                      # holds it, writes unknown
        (tmp_path, [data], ["data"]),                  # holds it where it writes
        (data, [data / "obj1"], ["obj1"]),             # OUT/<id> is the input shape
        (asset, [asset], None),                        # OUT is the input file
        (tmp_path / "assets", [asset], ["chair.glb"]),
    ]:
        with pytest.raises(KinmoUsageError, match="outputs never overwrite inputs"):
            check_outputs_apart(out, inputs, written)
    # apart, or beside without touching
    check_outputs_apart(tmp_path / "out", [data, asset])
    check_outputs_apart(tmp_path, [data], written=["obj1", "predictions.csv"])
    check_outputs_apart(tmp_path / "assets", [asset], written=["chair", ".staging"])


def test_outputs_apart_resolves_links(tmp_path):
    from kinmo.errors import KinmoUsageError
    from kinmo.io import check_outputs_apart

    (tmp_path / "data").mkdir()
    (tmp_path / "alias").symlink_to(tmp_path / "data", target_is_directory=True)
    with pytest.raises(KinmoUsageError):
        check_outputs_apart(tmp_path / "alias" / "out", [tmp_path / "data"])
