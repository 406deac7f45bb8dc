"""Atomic file writes (an interrupted run never leaves a half-written file), the lock that
keeps two runs from writing one output folder, and the check that outputs never overwrite
inputs."""

from __future__ import annotations

import itertools
import json
import os
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import IO, Any

from kinmo import limits
from kinmo.errors import KinmoDataError, KinmoError, KinmoUsageError


#: Numbers the temporary files of :func:`atomic_path` within a process (with the process id,
#: a name no other writer picks).
_TMP_SERIAL = itertools.count()
#: :func:`atomic_path` gives up after this many names taken in a row (stale files of a process
#: that had the same id).
_TMP_TRIES = 100


def _create_tmp(path: Path) -> Path:
    """Create an empty file ``.<name>.<pid>-<n>.tmp`` beside ``path``, exclusively (``O_EXCL``:
    never an existing file or link), with a normal file's permissions (``0o666`` less the
    umask); the next name when one is taken."""
    for _ in range(_TMP_TRIES):
        tmp = path.parent / f".{path.name}.{os.getpid()}-{next(_TMP_SERIAL)}.tmp"
        try:
            os.close(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_CLOEXEC", 0), 0o666))
        except FileExistsError:
            continue
        return tmp
    raise FileExistsError(f"{path.parent}: no free temporary name for {path.name!r} after {_TMP_TRIES} tries")


@contextmanager
def atomic_path(path: str | Path) -> Iterator[Path]:
    """Yield a temporary path next to ``path``; on success rename it onto ``path``.

    The rename is atomic on POSIX file systems, so readers see either the old file or the
    complete new one. On an exception the temporary file is removed and ``path`` is untouched.
    The temporary file (``.<name>.<pid>-<n>.tmp``, created empty and exclusively, with the
    permissions of a normal file) takes fewer system calls than :func:`tempfile.mkstemp` and a
    ``chmod``: an export writes one per convex collision piece, thousands per object folder.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp_path = _create_tmp(path)
    try:
        yield tmp_path
        os.replace(tmp_path, path)
    except BaseException:
        tmp_path.unlink(missing_ok=True)
        raise


def atomic_write(
    path: str | Path, write: Callable[[IO[Any]], None], mode: str = "w", errors: str | None = None
) -> None:
    """Write ``path`` atomically by calling ``write(file)`` on a temporary file.

    ``errors`` is :func:`open`'s (text mode), e.g. ``"surrogateescape"`` to write non-UTF-8
    file names back as their original bytes.
    """
    with atomic_path(path) as tmp:
        with open(tmp, mode, errors=errors) as f:
            write(f)
            f.flush()
            os.fsync(f.fileno())


def write_text(path: str | Path, text: str, errors: str | None = None) -> None:
    """Write a text file atomically (``errors``: see :func:`atomic_write`)."""
    atomic_write(path, lambda f: f.write(text), errors=errors)


def output_dir(path: str | Path) -> Path:
    """Create the output folder ``path`` (and its parents) if needed and return it.

    Raises
    ------
    KinmoDataError
        ``path`` (or a parent) exists and is not a folder, or cannot be created; one line
        naming it.
    """

    path = Path(path)
    if path.exists() and not path.is_dir():
        raise KinmoDataError(path, "exists and is not a folder (the output must be a folder)")
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise KinmoDataError(e.filename or path, f"cannot create the output folder: {e.strerror or e}"
                             ) from None
    return path


def read_checkpoint(path: str | Path, fmt: str, what: str) -> dict[str, Any]:
    """Load a kinmo ``torch.save`` checkpoint with ``torch.load(weights_only=True)``.

    The one loader of every model checkpoint (motion GNN, axis network, ANCSH): only plain
    tensors, dicts, lists, tuples, strings and numbers are unpickled, never code, and a
    damaged file gets one line naming it instead of torch's multi-line text.

    Parameters
    ----------
    path : str or Path
        The ``.pt`` file.
    fmt : str
        The ``"format"`` entry the checkpoint must carry (e.g. ``"kinmo-motion-gnn"``);
        a checkpoint without one is accepted.
    what : str
        What it is, for messages (``"motion-GNN"``).

    Returns
    -------
    dict
        The checkpoint, tensors on the CPU.

    Raises
    ------
    KinmoDataError
        Missing, empty, truncated or garbage file, or a file that is not a ``what``
        checkpoint.
    """
    import pickle
    import zipfile

    import torch

    path = Path(path)
    try:
        size = path.stat().st_size
    except OSError as e:
        raise KinmoDataError(path, f"cannot read the {what} checkpoint: {e.strerror or e}") from None
    if size == 0:
        raise KinmoDataError(path, f"empty file (0 bytes), not a {what} checkpoint")
    if not zipfile.is_zipfile(path):
        raise KinmoDataError(
            path, f"not a {what} checkpoint: not a torch.save archive (truncated or corrupt file?)"
        )
    try:
        payload = torch.load(path, map_location="cpu", weights_only=True)
    except pickle.UnpicklingError as e:
        first = str(e).strip().splitlines()[-1] if str(e).strip() else type(e).__name__
        raise KinmoDataError(
            path, f"not a {what} checkpoint: refused by torch.load(weights_only=True) ({first.strip()})"
        ) from None
    except Exception as e:  # torch raises many types for damaged archives
        first = (str(e).strip().splitlines() or [type(e).__name__])[0]
        raise KinmoDataError(path, f"cannot read the {what} checkpoint (corrupt file?): {first}"
                             ) from None
    if not isinstance(payload, dict) or payload.get("format", fmt) != fmt:
        raise KinmoDataError(path, f"not a kinmo {what} checkpoint")
    return payload


def read_json_document(path: str | Path, fmt: str, max_version: int, what: str,
                       missing: str) -> dict[str, Any]:
    """Read a kinmo JSON document (``{"format": fmt, "version": n, ...}``) as untrusted input.

    The one reader of kinmo's own JSON files that carry a format and a version (the model
    bundle's ``bundle.json``, the range prior's ``ranges.json``): size bounded
    (:func:`kinmo.limits.check_file`) before reading, then the format and version checked.

    Parameters
    ----------
    path : str or Path
    fmt : str
        The ``"format"`` entry the document must carry.
    max_version : int
        The newest ``"version"`` this kinmo reads.
    what : str
        What it is, for messages (``"model bundle"``).
    missing : str
        The message of a missing file.

    Returns
    -------
    dict
        The document.

    Raises
    ------
    KinmoDataError
        Missing, too large, malformed JSON, another format or a newer version (one line
        naming the file).
    """
    p = Path(path)
    limits.check_file(p)
    try:
        doc = json.loads(p.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise KinmoDataError(p, missing) from None
    except (OSError, ValueError) as e:
        raise KinmoDataError(p, f"malformed {what}: {e}") from None
    if not isinstance(doc, dict) or doc.get("format") != fmt:
        raise KinmoDataError(p, f"not a {what} (format is not {fmt!r})")
    if not isinstance(doc.get("version"), int) or doc["version"] > max_version:
        raise KinmoDataError(p, f"{what} version {doc.get('version')!r} is not supported "
                                f"(this kinmo reads up to {max_version})")
    return doc


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


def check_outputs_apart(out: str | Path, inputs: Iterable[str | Path],
                        written: Iterable[str] | None = None, option: str = "--out") -> None:
    """Refuse an output folder whose writes could replace an input file.

    Outputs never overwrite inputs: a command checks this before any work. Paths are compared
    with every symbolic link resolved. The output folder ``out`` conflicts with an input when

    - ``out`` is the input, or lies inside an input folder (``kinmo predict DIR -o DIR``,
      ``-o DIR/<object>``), or
    - an input is, or lies inside, one of the entries the command writes directly in ``out``
      (``written``: object folders ``<id>``, summary files); when ``written`` is ``None``
      any input inside ``out`` conflicts.

    Parameters
    ----------
    out : str or Path
        The output folder (need not exist).
    inputs : iterable of str or Path
        The command's input files and folders (dataset roots, shape folders, asset files).
    written : iterable of str, optional
        Names of the entries written directly in ``out``.
    option : str
        The option that named ``out``, for the message.

    Raises
    ------
    KinmoUsageError
        One line naming ``out``, the input and what to do; the command line exits with code 2.
    """

    o = Path(os.path.realpath(out))
    names = None if written is None else set(written)
    for inp in inputs:
        i = Path(os.path.realpath(inp))
        if o == i or i in o.parents:
            where = "is" if o == i else "lies inside"
            raise KinmoUsageError(out, f"{option} {where} the input {inp}: outputs never "
                                  f"overwrite inputs; choose an {option} folder outside it")
        if o in i.parents:
            top = i.relative_to(o).parts[0]
            if names is None or top in names:
                raise KinmoUsageError(out, f"{option} holds the input {inp}, which this command "
                                      f"would overwrite ({o.name}/{top}); outputs never "
                                      f"overwrite inputs: choose another {option} folder")


def parse_xml(path: str | Path) -> Any:
    """Parse an untrusted XML file (a URDF) with no document type and no entities.

    The standard library's parser does not fetch external entities, but it expands internal
    ones ("billion laughs"); a document type declaration is refused before parsing, so no
    entity can be defined. The file size is bounded by the ``file_bytes`` limit
    (:mod:`kinmo.limits`).

    Returns
    -------
    xml.etree.ElementTree.ElementTree

    Raises
    ------
    KinmoDataError
        Unreadable, over the limit, not UTF-8 compatible, a ``<!DOCTYPE`` / ``<!ENTITY``
        declaration, or not well-formed XML (line and column).
    """
    import xml.etree.ElementTree as ET


    path = Path(path)
    limits.check_file(path)
    try:
        raw = path.read_bytes()
    except OSError as e:
        raise KinmoDataError(path, f"cannot read: {e.strerror}") from None
    if b"<!DOCTYPE" in raw.upper() or b"<!ENTITY" in raw.upper():
        raise KinmoDataError(path, "XML with a document type or entity declarations refused "
                                   "(entity expansion)")
    parser = ET.XMLParser()
    try:
        parser.feed(raw)
        root = parser.close()
    except ET.ParseError as e:
        raise KinmoDataError(path, f"not well-formed XML ({e})") from None
    return ET.ElementTree(root)


def link_or_copy(src: str | Path, dst: str | Path) -> Path:
    """Put the file ``src`` at ``dst``: a hard link where the file system allows it, else an
    atomic copy. An existing ``dst`` with the same content (same inode, or same size and
    bytes) is kept; another one is replaced atomically. Never a symbolic link: the output
    folder stays whole when the source is moved or deleted (issue 21, finding 11).

    Returns
    -------
    Path
        ``dst``.
    """
    import filecmp
    import shutil

    src, dst = Path(src), Path(dst)
    if dst.exists():
        try:
            if os.path.samefile(src, dst) or filecmp.cmp(src, dst, shallow=False):
                return dst
        except OSError:
            pass
    dst.parent.mkdir(parents=True, exist_ok=True)
    tmp = dst.parent / f".{dst.name}.{os.getpid()}.link.tmp"
    tmp.unlink(missing_ok=True)
    try:
        os.link(src, tmp)
    except OSError:
        with atomic_path(dst) as t:
            shutil.copyfile(src, t)
        return dst
    try:
        os.replace(tmp, dst)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    return dst


@contextmanager
def staged_folder(dst: str | Path) -> Iterator[Path]:
    """Yield a temporary sibling of the folder ``dst`` to write an object into; on success it
    appears at ``dst`` whole (issue 21, finding 12).

    When ``dst`` does not exist (or is empty) the sibling is renamed onto it: one atomic step,
    so a reader sees no object or the complete one, and ``kill -9`` leaves only a hidden
    ``.<name>.partial-<pid>`` folder (removed by the next run into ``dst``). When ``dst``
    already holds files (a rerun), each written entry replaces its namesake by a rename
    (files atomically, folders by a swap); other files of ``dst`` are kept. On an exception
    the sibling is removed and ``dst`` is untouched.
    """
    import shutil

    dst = Path(dst)
    dst.parent.mkdir(parents=True, exist_ok=True)
    for old in dst.parent.glob(f".{dst.name}.partial-*"):
        pid = old.name.rsplit("-", 1)[-1]
        if not (pid.isdigit() and _alive(int(pid))):
            shutil.rmtree(old, ignore_errors=True)
    tmp = dst.parent / f".{dst.name}.partial-{os.getpid()}"
    shutil.rmtree(tmp, ignore_errors=True)
    tmp.mkdir()
    try:
        yield tmp
        if dst.is_dir() and not any(dst.iterdir()):
            dst.rmdir()
        if not dst.exists():
            os.replace(tmp, dst)
            return
        for entry in sorted(tmp.iterdir()):
            target = dst / entry.name
            if entry.is_dir() and target.is_dir():
                trash = dst / f".{entry.name}.old-{os.getpid()}"
                os.replace(target, trash)
                os.replace(entry, target)
                shutil.rmtree(trash, ignore_errors=True)
            else:
                os.replace(entry, target)
        shutil.rmtree(tmp, ignore_errors=True)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:
        return True
    return True
