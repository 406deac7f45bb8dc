"""Batched candidate motions: revolute, prismatic, or both (screw about an axis)."""

from __future__ import annotations

import numpy as np

from kinmo import _core


def _args(origins, directions, angles, translations):
    o = np.ascontiguousarray(origins, dtype=np.float64)
    d = np.ascontiguousarray(directions, dtype=np.float64)
    c = o.shape[0] if o.ndim == 2 else -1
    a = np.zeros(max(c, 0)) if angles is None else np.ascontiguousarray(angles, dtype=np.float64)
    t = (
        np.zeros(max(c, 0))
        if translations is None
        else np.ascontiguousarray(translations, dtype=np.float64)
    )
    return o, d, a, t


def motion_transforms(
    origins: np.ndarray,
    directions: np.ndarray,
    angles: np.ndarray | None = None,
    translations: np.ndarray | None = None,
) -> np.ndarray:
    """Rigid transforms of C candidate motions about/along axes.

    Motion ``c`` rotates by ``angles[c]`` radians about the line through ``origins[c]`` with
    direction ``directions[c]`` (right-hand rule), then translates by ``translations[c]``
    along the unit direction. Revolute: translation 0; prismatic: angle 0.

    Parameters
    ----------
    origins : (C, 3) float64
    directions : (C, 3) float64
        Normalised internally; zero length is a ``ValueError``.
    angles : (C,) float64, radians, optional (default 0)
    translations : (C,) float64, input units, optional (default 0)

    Returns
    -------
    (C, 4, 4) float64
        Homogeneous matrices acting on column vectors: ``x' = M[:3, :3] x + M[:3, 3]``.

    Raises
    ------
    ValueError
        Wrong shapes or lengths, NaN/inf values, or a zero-length direction (the message
        names the argument and the candidate index).
    """
    return _core.motion_transforms(*_args(origins, directions, angles, translations))


def apply_motions(
    points: np.ndarray,
    origins: np.ndarray,
    directions: np.ndarray,
    angles: np.ndarray | None = None,
    translations: np.ndarray | None = None,
) -> np.ndarray:
    """Apply C candidate motions (see :func:`motion_transforms`) to one point cloud.

    Parameters
    ----------
    points : (N, 3) float64
    origins, directions, angles, translations : as in :func:`motion_transforms`

    Returns
    -------
    (C, N, 3) float64
        ``out[c, i]`` is point ``i`` moved by candidate ``c``. Parallel over candidates and
        blocks of points (Rust threads, GIL released), written straight into the output.

    Raises
    ------
    ValueError
        As :func:`motion_transforms`, or ``points`` not of shape ``(N, 3)`` / not finite.
    """
    p = np.ascontiguousarray(points, dtype=np.float64)
    return _core.apply_motions(p, *_args(origins, directions, angles, translations))
