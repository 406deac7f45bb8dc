"""PointNet++ neighbourhoods (:mod:`kinmo.geometry.pointnet`, Rust) against brute force in
numpy and the PyTorch reference of :mod:`kinmo.ancsh.pointnet2`."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st

from kinmo.ancsh import pointnet2 as ref
from kinmo.geometry import ball_query, farthest_point_sample, k_nearest


def _clouds(seed: int, b: int, n: int, repeats: bool = False) -> np.ndarray:
    rng = np.random.default_rng(seed)
    x = rng.normal(size=(b, n, 3)).astype(np.float32)
    if repeats:  # small scans are padded by repeated points (kinmo.ancsh.dataset)
        x[:, n // 2:] = x[:, : n - n // 2]
    return x / np.linalg.norm(x, axis=-1).max()


@pytest.mark.parametrize(("b", "n", "m", "repeats"), [(1, 50, 50, False), (4, 300, 64, False),
                                                      (3, 512, 128, True), (2, 1024, 512, False)])
def test_fps_equals_the_torch_reference_exactly(b, n, m, repeats):
    x = _clouds(n + m, b, n, repeats)
    want = ref.farthest_point_sample(torch.from_numpy(x), m, seed=None).numpy()
    got = farthest_point_sample(x, m)
    assert got.dtype == np.int64 and got.shape == (b, m)
    np.testing.assert_array_equal(got, want)
    np.testing.assert_array_equal(farthest_point_sample(x[1 % b], m), want[1 % b])  # one cloud


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(1, 200), b=st.integers(1, 3), repeats=st.booleans())
def test_fps_equals_the_reference_on_random_clouds(seed, n, b, repeats):
    x = _clouds(seed, b, n, repeats and n > 1)
    m = 1 + seed % n
    np.testing.assert_array_equal(farthest_point_sample(x, m),
                                  ref.farthest_point_sample(torch.from_numpy(x), m, seed=None).numpy())


def _ball_brute(x, c, r, k):
    d2 = ((c[:, :, None, :].astype(np.float64) - x[:, None, :, :].astype(np.float64)) ** 2).sum(-1)
    out = np.empty(c.shape[:2] + (k,), dtype=np.int64)
    for i in range(c.shape[0]):
        for j in range(c.shape[1]):
            inside = np.flatnonzero(d2[i, j] <= r * r)[:k]
            fill = inside[0] if len(inside) else int(np.argmin(d2[i, j]))
            out[i, j] = np.concatenate([inside, np.full(k - len(inside), fill)])
    return out, np.sqrt(d2)


@pytest.mark.parametrize(("r", "k"), [(0.05, 8), (0.2, 32), (0.4, 32), (0.8, 16), (5.0, 4)])
def test_ball_query_equals_brute_force_and_the_reference_off_the_boundary(r, k):
    x = _clouds(7, 3, 400)
    c = np.take_along_axis(x, farthest_point_sample(x, 60)[..., None], 1)
    got = ball_query(x, c, r, k)
    want, d = _ball_brute(x, c, r, k)
    np.testing.assert_array_equal(got, want)
    torch_ref = ref.ball_query(r, k, torch.from_numpy(x), torch.from_numpy(c)).numpy()
    differ = np.any(got != torch_ref, axis=-1)
    # the torch reference's float32 cdist may decide points within 1e-5 of the radius otherwise
    near = np.any(np.abs(d - r) < 1e-5, axis=-1)
    assert not np.any(differ & ~near)


def test_ball_query_pads_and_falls_back_to_the_nearest():
    x = np.array([[[0, 0, 0], [1, 0, 0], [0.05, 0, 0], [3, 0, 0]]], dtype=np.float32)
    c = np.array([[[0, 0, 0], [2.9, 0, 0], [10, 0, 0]]], dtype=np.float32)
    got = ball_query(x, c, 0.1, 4)
    np.testing.assert_array_equal(got[0], [[0, 2, 0, 0], [3, 3, 3, 3], [3, 3, 3, 3]])


@pytest.mark.parametrize(("m", "n"), [(8, 32), (128, 512), (512, 1024), (2, 50)])
def test_k_nearest_equals_the_reference_off_ties(m, n):
    x = _clouds(m, 2, n)
    c = np.take_along_axis(x, farthest_point_sample(x, m)[..., None], 1)
    k = min(3, m)
    idx, dist = k_nearest(c, x, k)
    d64 = np.sqrt(((x[:, :, None].astype(np.float64) - c[:, None].astype(np.float64)) ** 2).sum(-1))
    want = np.argsort(d64, axis=-1, kind="stable")[..., :k]
    np.testing.assert_array_equal(idx, want)
    np.testing.assert_allclose(dist, np.take_along_axis(d64, want, -1), rtol=1e-6, atol=0)
    tdist, tidx = torch.cdist(torch.from_numpy(x), torch.from_numpy(c)).topk(k, dim=-1, largest=False)
    assert np.array_equal(idx, tidx.numpy())  # no ties on random clouds
    # the points that are centres lie at distance 0 of themselves (cdist leaves ~1e-4 there)
    centres = farthest_point_sample(x, m)[0]
    np.testing.assert_array_equal(idx[0, centres, 0], np.arange(m))
    assert np.all(dist[0, centres, 0] == 0)


def test_k_nearest_breaks_ties_by_index():
    p = np.array([[1, 0, 0], [0, 1, 0], [1, 0, 0], [-1, 0, 0], [0, 0, 2]], dtype=np.float32)
    idx, dist = k_nearest(p, np.zeros((1, 3), np.float32), 4)
    np.testing.assert_array_equal(idx, [[0, 1, 2, 3]])
    np.testing.assert_array_equal(dist, [[1, 1, 1, 1]])


def test_bad_arguments_are_value_errors_naming_them():
    x = _clouds(0, 2, 10)
    with pytest.raises(ValueError, match="m:"):
        farthest_point_sample(x, 11)
    with pytest.raises(ValueError, match="m:"):
        farthest_point_sample(x, 0)
    with pytest.raises(ValueError, match="radius"):
        ball_query(x, x, -1.0, 4)
    with pytest.raises(ValueError, match="k:"):
        ball_query(x, x, 0.1, 0)
    with pytest.raises(ValueError, match="k:"):
        k_nearest(x, x, 11)
    with pytest.raises(ValueError, match="centers: batch size 1"):
        ball_query(x, x[:1], 0.1, 4)
    with pytest.raises(ValueError, match=r"points: expected shape \(B, N, 3\)"):
        farthest_point_sample(np.zeros((2, 5, 2), np.float32), 1)
    bad = x.copy()
    bad[1, 3, 2] = np.nan
    with pytest.raises(ValueError, match="queries: non-finite value at index 41"):
        k_nearest(x, bad, 1)
    with pytest.raises(ValueError, match="more than the limit"):
        ball_query(x, x, 0.1, 2**40)


def test_huge_views_are_refused_before_copying():
    huge = np.broadcast_to(np.zeros((1, 1, 3), np.float32), (2**16, 2**15, 3))  # 6 * 2**30 values
    small = np.zeros((2**16, 1, 3), np.float32)
    with pytest.raises(ValueError, match=r"points: an array of shape \(65536, 32768, 3\)"):
        farthest_point_sample(huge, 1)
    with pytest.raises(ValueError, match="centers: an array of shape"):
        ball_query(small, huge, 0.1, 1)
    with pytest.raises(ValueError, match="queries: an array of shape"):
        k_nearest(small, huge, 1)
