"""Exact convex hulls (:mod:`kinmo.geometry.hull`, Rust) against qhull (scipy), on random
clouds and on real PartNet-Mobility part meshes."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.spatial import ConvexHull

from kinmo.data.readers import find_shapes
from kinmo.geometry import convex_hull, load_obj


def _volume(v: np.ndarray, f: np.ndarray) -> float:
    a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
    return float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0)


def _check_against_qhull(p: np.ndarray) -> None:
    v, f = convex_hull(p)
    q = ConvexHull(p)
    ours, theirs = {tuple(x) for x in v}, {tuple(x) for x in p[q.vertices]}
    assert theirs <= ours
    # a corner only the exact hull keeps lies on qhull's surface up to rounding (exact
    # predicates see it strictly outside a face that qhull's tolerances take as flat)
    diag = float(np.linalg.norm(np.ptp(p, axis=0)))
    extra = np.array(sorted(ours - theirs)).reshape(-1, 3)
    if len(extra):
        assert (extra @ q.equations[:, :3].T + q.equations[:, 3]).max() <= 1e-12 * diag
    # outward faces: a positive signed volume equal to qhull's, and a closed surface (every
    # edge in exactly two faces, once each way)
    assert _volume(v, f) == pytest.approx(q.volume, rel=1e-9)
    edges = {(int(a), int(b)) for t in f for a, b in ((t[0], t[1]), (t[1], t[2]), (t[2], t[0]))}
    assert len(edges) == 3 * len(f) and all((b, a) in edges for a, b in edges)


@pytest.mark.parametrize("n", [4, 30, 1000])
def test_random_clouds_give_qhulls_corners_outward_and_closed(n):
    rng = np.random.default_rng(n)
    _check_against_qhull(rng.normal(size=(n, 3)))


def test_real_part_meshes_give_qhulls_corners(mobility_root: Path):
    """Up to 8 part meshes of each of the data's first objects, until 16 are full-dimensional
    (whichever objects the data holds)."""
    checked = 0
    for folder in find_shapes(mobility_root):
        for obj in sorted((folder / "textured_objs").glob("*.obj"))[:8]:
            v, _ = load_obj(obj)
            if len(np.unique(v, axis=0)) < 4 or np.linalg.matrix_rank(v - v.mean(0), tol=1e-9) < 3:
                continue
            _check_against_qhull(v)
            checked += 1
        if checked >= 16:
            break
    assert checked >= 12


def test_flat_short_and_bad_inputs():
    square = np.array([[x, y, 0.0] for x in range(3) for y in range(3)])
    assert convex_hull(square) is None
    assert convex_hull(np.eye(3)) is None  # three points
    assert convex_hull(np.zeros((0, 3))) is None
    with pytest.raises(ValueError, match="points"):
        convex_hull(np.array([[0.0, np.nan, 0.0]] * 4))
    with pytest.raises(ValueError, match="points"):
        convex_hull(np.zeros((4, 2)))
