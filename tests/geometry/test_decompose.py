"""Convex pieces of concave meshes (:mod:`kinmo.geometry.decompose`): the binding's
conversions and errors, and the pieces' contract on random box soups (hypothesis)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from kinmo.geometry import concave_pieces

SETTINGS = dict(max_depth=4, max_components=16, hull_samples=64, flat_relative=1e-9,
                slab_thickness=1e-3)


def box(lo, size) -> tuple[np.ndarray, np.ndarray]:
    """Axis-aligned box ``[lo, lo + size]``: 8 vertices, 12 outward triangles."""
    corners = np.array([[(i >> k) & 1 for k in range(3)] for i in range(8)], float)
    f = np.array([[0, 2, 1], [1, 2, 3], [4, 5, 6], [5, 7, 6], [0, 1, 4], [1, 5, 4],
                  [2, 6, 3], [3, 6, 7], [0, 4, 2], [2, 4, 6], [1, 3, 5], [3, 7, 5]])
    return np.asarray(lo, float) + corners * np.asarray(size, float), f


def soup(boxes) -> tuple[np.ndarray, np.ndarray]:
    vs, fs, base = [], [], 0
    for v, f in boxes:
        vs.append(v)
        fs.append(f + base)
        base += len(v)
    return np.concatenate(vs), np.concatenate(fs)


def u_shape() -> tuple[np.ndarray, np.ndarray]:
    """Two posts on a base, a slot 1 wide and 3 deep between them, one mesh."""
    return soup([box((0, 0, 0), (3, 1, 1)), box((0, 1, 0), (1, 3, 1)), box((2, 1, 0), (1, 3, 1))])


def test_leaves_share_vertices_and_each_gets_its_pieces():
    u_v, u_f = u_shape()
    b_v, b_f = box((10, 0, 0), (1, 1, 1))
    v = np.concatenate([u_v, b_v])
    leaves = [u_f, b_f + len(u_v)]
    got = concave_pieces(v, leaves, 0.2, **SETTINGS)  # the slot is 0.5 from its walls
    assert len(got) == 2
    assert len(got[0]) > 1  # the U is cut
    assert len(got[1]) == 1  # the box is its own hull
    pv, pf, ids = got[1][0]
    assert pv.dtype == np.float64 and pf.dtype == np.int64 and ids.dtype == np.int64
    assert np.array_equal(pv, b_v) and np.array_equal(ids, np.arange(12))
    ids = np.sort(np.concatenate([i for _, _, i in got[0]]))
    assert np.array_equal(ids, np.arange(len(u_f)))  # every face in exactly one piece
    # a piece never fills the slot
    slot = np.array([1.5, 2.5, 0.5])
    for pv, pf, _ in got[0]:
        a, b, c = pv[pf[:, 0]], pv[pf[:, 1]], pv[pf[:, 2]]
        assert (np.einsum("ij,ij->i", np.cross(b - a, c - a), slot - a) > 0).any()
    assert concave_pieces(u_v, [u_f], 0.0, **SETTINGS)[0][0][2].size == len(u_f)  # tol 0


@pytest.mark.parametrize("change, match", [
    (lambda v, f: (v, [f + 100]), r"leaves\[0\]"),
    (lambda v, f: (np.where(np.arange(24).reshape(8, 3) == 4, np.nan, v), [f]), "vertices"),
    (lambda v, f: (v[:, :2], [f]), "vertices"),
    (lambda v, f: (v, [f[:, :2]]), r"leaves\[0\]"),
])
def test_bad_arrays_name_the_argument(change, match):
    v, f = box((0, 0, 0), (1, 1, 1))
    v, leaves = change(v, f)
    with pytest.raises(ValueError, match=match):
        concave_pieces(v, leaves, 0.1, **SETTINGS)


def test_bad_settings_raise():
    v, f = box((0, 0, 0), (1, 1, 1))
    with pytest.raises(ValueError):
        concave_pieces(v, [f], -0.1, **SETTINGS)
    with pytest.raises(ValueError):
        concave_pieces(v, [f], 0.1, **{**SETTINGS, "hull_samples": 0})


@settings(max_examples=40, deadline=None)
@given(st.lists(st.tuples(st.tuples(*[st.floats(-3, 3)] * 3), st.tuples(*[st.floats(0.1, 2)] * 3)),
                min_size=1, max_size=5),
       st.floats(0.0, 0.3))
def test_pieces_partition_the_faces_and_are_convex(boxes, tol):
    v, f = soup([box(lo, size) for lo, size in boxes])
    (pieces,) = concave_pieces(v, [f], tol, **SETTINGS)
    ids = np.sort(np.concatenate([i for _, _, i in pieces]))
    assert np.array_equal(ids, np.arange(len(f)))
    for pv, pf, _ in pieces:
        a, b, c = pv[pf[:, 0]], pv[pf[:, 1]], pv[pf[:, 2]]
        n = np.cross(b - a, c - a)
        # every corner on or behind every face: convex, faces outward
        assert (np.einsum("fk,fvk->fv", n, pv[None] - a[:, None]) <= 1e-9 * max(1.0, np.abs(pv).max()) ** 3).all()
