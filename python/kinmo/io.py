"""Atomic file writes (an interrupted run never leaves a half-written file) and the lock that
keeps two runs from writing one output folder."""

from __future__ import annotations

import json
import os
import tempfile
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import IO, Any


def _read_umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


_UMASK = _read_umask()  # read once at import: os.umask can only be read by setting it


@contextmanager
def atomic_path(path: str | Path) -> Iterator[Path]:
    """Yield a temporary path next to ``path``; on success rename it onto ``path``.

    The rename is atomic on POSIX file systems, so readers see either the old file or the
    complete new one. On an exception the temporary file is removed and ``path`` is untouched.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    os.close(fd)
    tmp_path = Path(tmp)
    try:
        yield tmp_path
        # mkstemp creates the file owner-only: give it the permissions of a normal file
        os.chmod(tmp_path, 0o666 & ~_UMASK)
        os.replace(tmp_path, path)
    except BaseException:
        tmp_path.unlink(missing_ok=True)
        raise


def atomic_write(path: str | Path, write: Callable[[IO[Any]], None], mode: str = "w") -> None:
    """Write ``path`` atomically by calling ``write(file)`` on a temporary file."""
    with atomic_path(path) as tmp:
        with open(tmp, mode) as f:
            write(f)
            f.flush()
            os.fsync(f.fileno())


def write_text(path: str | Path, text: str) -> None:
    """Write a text file atomically."""
    atomic_write(path, lambda f: f.write(text))


def write_json(path: str | Path, obj: Any, indent: int | None = 2) -> None:
    """Write a JSON file atomically."""
    write_text(path, json.dumps(obj, indent=indent) + "\n")


@contextmanager
def folder_lock(folder: str | Path, command: str) -> Iterator[None]:
    """Hold an exclusive lock on ``folder/.lock`` while the block runs (POSIX ``flock``).

    A second process that tries to lock the same folder fails at once instead of waiting.
    The lock dies with the process, so an interrupted run never leaves a stale lock. Without
    ``fcntl`` (not POSIX) the block runs unlocked.

    Parameters
    ----------
    folder : str or Path
        An existing output folder.
    command : str
        What holds the lock, for the error (``"kinmo prepare"``).

    Raises
    ------
    KinmoError
        Another process holds the lock: ``"<folder>: another <command> is writing this folder"``.
    """
    from kinmo.errors import KinmoError

    try:
        import fcntl
    except ImportError:  # pragma: no cover - not POSIX: no lock
        yield
        return
    fh = open(Path(folder) / ".lock", "a+")
    try:
        try:
            fcntl.flock(fh, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            raise KinmoError(f"{folder}: another {command} is writing this folder") from None
        yield
    finally:
        fh.close()
