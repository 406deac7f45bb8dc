"""Resource limits on untrusted inputs (issue 21, finding 4; ``docs/security.md``).

An asset from a third party can ask for any amount of memory: a 260 KB GLB of 500 boxes
becomes 250,000 sibling edges, a 254 MB OBJ ten million faces. Every reader checks the
size it is about to allocate against these limits first and refuses with one line naming
the file and the limit (:class:`~kinmo.errors.KinmoDataError`).

====================  =============  ==========================================================
name                  default        what
====================  =============  ==========================================================
``parts``             2,000          parts (leaves, scene nodes with a mesh, URDF links) of one
                                     shape
``edges``             300,000        directed sibling edges of one part graph (quadratic in the
                                     parts: ``n (n - 1)`` for ``n`` flat parts)
``triangles``         2,000,000      triangles of one mesh file (OBJ, GLB, glTF accessor counts)
``file_bytes``        4 GiB          bytes of one input file (OBJ, GLB, JSON, URDF); the Rust
                                     OBJ reader gets it (``load_obj_bounded``: one limit)
``nodes``             100,000        nodes of one glTF scene graph
``range_entries``     20,000         entries of one range-of-motion prior (``ranges.json``,
                                     :mod:`kinmo.ranges`; one per fitted (kind, category, part
                                     name) group: the pretrained one has 214)
====================  =============  ==========================================================

The defaults accept every object of the shared PartNet-Mobility and PartNet data, flattened
to one level or not (the 116-leaf keyboard flattened has about 13,000 directed sibling
edges). Raise one with ``kinmo --limit NAME=N COMMAND ...`` or the environment variable
``KINMO_MAX_<NAME>`` (e.g. ``KINMO_MAX_PARTS=5000``); the command-line option sets the
variable, so worker processes see the same limits.
"""

from __future__ import annotations

import os
from pathlib import Path

from kinmo.errors import KinmoDataError, KinmoUsageError

__all__ = ["DEFAULTS", "check", "check_file", "limit", "set_limit"]

#: Default limit of each name (see the module table).
DEFAULTS: dict[str, int] = {
    "parts": 2_000,
    "edges": 300_000,
    "triangles": 2_000_000,
    "file_bytes": 1 << 32,
    "nodes": 100_000,
    "range_entries": 20_000,
}

_WHAT = {
    "parts": "parts per shape",
    "edges": "sibling edges per graph",
    "triangles": "triangles per mesh",
    "file_bytes": "bytes per input file",
    "nodes": "nodes per glTF scene",
    "range_entries": "entries per range prior",
}


def _env(name: str) -> str:
    return f"KINMO_MAX_{name.upper()}"


def limit(name: str) -> int:
    """The limit ``name`` (a key of :data:`DEFAULTS`): ``KINMO_MAX_<NAME>`` when set, else the
    default.

    Raises
    ------
    KinmoUsageError
        Unknown name, or the environment variable is not a positive integer.
    """
    if name not in DEFAULTS:
        raise KinmoUsageError(name, f"unknown limit; known: {', '.join(DEFAULTS)}")
    raw = os.environ.get(_env(name), "").strip().replace("_", "")
    if not raw:
        return DEFAULTS[name]
    if not raw.isdigit() or int(raw) <= 0:
        raise KinmoUsageError(_env(name), f"expected a positive integer, got {raw!r}")
    return int(raw)


def set_limit(spec: str) -> tuple[str, int]:
    """Apply ``NAME=N`` (the ``kinmo --limit`` option) to this process and its children.

    Raises
    ------
    KinmoUsageError
        Not ``NAME=N``, unknown name, or ``N`` not a positive integer.
    """
    name, sep, value = spec.partition("=")
    name = name.strip().lower().replace("-", "_")
    value = value.strip().replace("_", "")
    if not sep or name not in DEFAULTS or not value.isdigit() or int(value) <= 0:
        raise KinmoUsageError(f"--limit {spec}", "expected NAME=N with N a positive integer and "
                              f"NAME one of {', '.join(DEFAULTS)}")
    os.environ[_env(name)] = value
    return name, int(value)


def check(name: str, count: int, file: str | Path) -> None:
    """Refuse ``count`` over the limit ``name`` for ``file``, before it is allocated.

    Raises
    ------
    KinmoDataError
        ``"<file>: <count> <what> exceeds the limit of <N> (raise it with --limit name=M or
        KINMO_MAX_<NAME>)"``.
    """
    n = limit(name)
    if count > n:
        raise KinmoDataError(file, f"{count:,} {_WHAT[name]} exceeds the limit of {n:,} (raise it "
                                   f"with kinmo --limit {name}=N or {_env(name)})")


def check_file(path: str | Path) -> None:
    """:func:`check` the size of the file ``path`` against ``file_bytes`` (a missing file
    passes: its reader reports it)."""
    try:
        size = os.stat(path).st_size
    except OSError:
        return
    check("file_bytes", size, path)
