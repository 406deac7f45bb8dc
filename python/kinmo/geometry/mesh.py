"""OBJ mesh loading in Rust (``tobj``), parallel for many files."""

from __future__ import annotations

from collections.abc import Sequence
from os import PathLike

import numpy as np

from kinmo import _core, limits

Mesh = tuple[np.ndarray, np.ndarray]
"""A triangle mesh: vertices ``(V, 3) float64`` and faces ``(F, 3) int64``."""


def load_obj(path: str | PathLike[str]) -> Mesh:
    """Read a Wavefront OBJ file as one triangle mesh.

    Polygons are triangulated, all objects/groups of the file are merged, materials and
    texture coordinates are ignored (a missing ``.mtl`` is not an error).

    Parameters
    ----------
    path : str or PathLike
        The ``.obj`` file.

    Returns
    -------
    vertices : (V, 3) float64
        Mesh frame, file units.
    faces : (F, 3) int64
        Zero-based vertex indices.

    Raises
    ------
    OSError
        The file is missing, unreadable or larger than the ``file_bytes`` limit
        (:mod:`kinmo.limits`, ``kinmo --limit file_bytes=N``; message names the file).
    ValueError
        The file does not parse, has non-finite vertices or out-of-range face indices
        (message names the file and the problem).
    """
    return _core.load_obj(str(path), limits.limit("file_bytes"))


def load_objs(paths: Sequence[str | PathLike[str]]) -> list[Mesh]:
    """Read many OBJ files in parallel (Rust threads); same contract as :func:`load_obj`.

    The first failing file raises, naming that file.
    """
    return _core.load_objs([str(p) for p in paths], limits.limit("file_bytes"))
