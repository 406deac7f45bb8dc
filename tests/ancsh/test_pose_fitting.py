import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from kinmo.ancsh.pose_fitting import ransac_similarity, umeyama


def _random_similarity(rng):
    r = Rotation.random(random_state=int(rng.integers(1 << 30))).as_matrix()
    return r, rng.normal(size=3), float(rng.uniform(0.3, 3.0))


def test_umeyama_recovers_exact_similarity():
    rng = np.random.default_rng(0)
    src = rng.normal(size=(50, 3))
    r, t, s = _random_similarity(rng)
    dst = s * src @ r.T + t
    est = umeyama(src, dst)
    np.testing.assert_allclose(est.rotation, r, atol=1e-10)
    np.testing.assert_allclose(est.translation, t, atol=1e-10)
    assert est.scale == pytest.approx(s, rel=1e-10)
    assert np.linalg.det(est.rotation) == pytest.approx(1.0)


def test_umeyama_never_returns_a_reflection():
    rng = np.random.default_rng(1)
    src = rng.normal(size=(30, 3))
    dst = src * np.array([1, 1, -1])  # a mirror image: best proper rotation, not the reflection
    est = umeyama(src, dst)
    assert np.linalg.det(est.rotation) == pytest.approx(1.0)


@pytest.mark.parametrize(
    "src,dst,msg",
    [
        (np.zeros((2, 3)), np.zeros((2, 3)), "at least 3"),
        (np.zeros((5, 3)), np.zeros((4, 3)), r"\(N, 3\)"),
        (np.ones((5, 3)), np.zeros((5, 3)), "degenerate"),
        (np.full((5, 3), np.nan), np.zeros((5, 3)), "non-finite"),
    ],
)
def test_umeyama_rejects_bad_input(src, dst, msg):
    with pytest.raises(ValueError, match=msg):
        umeyama(src, dst)


def test_ransac_recovers_pose_from_noisy_correspondences_with_outliers():
    rng = np.random.default_rng(2)
    src = rng.uniform(-0.5, 0.5, size=(400, 3))
    r, t, s = _random_similarity(rng)
    dst = s * src @ r.T + t + rng.normal(scale=0.005, size=src.shape)
    outliers = rng.random(400) < 0.3
    dst[outliers] = rng.normal(scale=2.0, size=(outliers.sum(), 3))
    res = ransac_similarity(src, dst, threshold=0.03, seed=0)
    ang = np.degrees(np.arccos(np.clip((np.trace(res.transform.rotation.T @ r) - 1) / 2, -1, 1)))
    assert ang < 1.0
    assert np.linalg.norm(res.transform.translation - t) < 0.02
    assert res.transform.scale == pytest.approx(s, rel=0.02)
    # the outliers are recognised as such
    assert (res.inliers & outliers).sum() < 0.05 * outliers.sum()
    assert res.inliers[~outliers].mean() > 0.9
    # plain least squares is ruined by the same outliers
    ls = umeyama(src, dst)
    ang_ls = np.degrees(np.arccos(np.clip((np.trace(ls.rotation.T @ r) - 1) / 2, -1, 1)))
    assert ang_ls > 5 * ang


def test_ransac_is_reproducible():
    rng = np.random.default_rng(3)
    src = rng.normal(size=(100, 3))
    dst = src + rng.normal(scale=0.1, size=src.shape)
    a = ransac_similarity(src, dst, threshold=0.1, seed=7)
    b = ransac_similarity(src, dst, threshold=0.1, seed=7)
    np.testing.assert_array_equal(a.inliers, b.inliers)
    np.testing.assert_array_equal(a.transform.rotation, b.transform.rotation)


def test_ransac_max_scale_rejects_degenerate_blow_ups():
    rng = np.random.default_rng(4)
    src = 0.5 + rng.normal(scale=1e-4, size=(200, 3))  # a collapsed prediction
    dst = rng.normal(size=(200, 3))
    res = ransac_similarity(src, dst, threshold=0.1, seed=0, max_scale=5.0)
    assert res.transform.scale <= 5.0 + 1e-9
    assert np.isfinite(res.transform.translation).all()
