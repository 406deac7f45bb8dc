"""Similarity-transform fitting for ANCSH post-processing (Li et al. CVPR 2020, Sec. 4.3).

ANCSH predicts, per point of a partial scan, its NPCS coordinates (normalised part
coordinate space). The pose and scale of each part follow from the correspondences between
NPCS and the observed camera-frame points: the Umeyama (1991) least-squares similarity
transform inside a RANSAC loop, robust to badly predicted points.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np


class Similarity(NamedTuple):
    """A similarity transform ``y = scale * rotation @ x + translation``.

    Attributes
    ----------
    rotation : (3, 3) float64
        Proper rotation (det = +1).
    translation : (3,) float64
    scale : float
    """

    rotation: np.ndarray
    translation: np.ndarray
    scale: float

    def apply(self, points: np.ndarray) -> np.ndarray:
        """Transform ``points (N, 3)``; returns ``(N, 3) float64``."""
        return self.scale * np.asarray(points, float) @ self.rotation.T + self.translation


def umeyama(source: np.ndarray, target: np.ndarray, with_scale: bool = True) -> Similarity:
    """Least-squares similarity transform mapping ``source`` onto ``target`` (Umeyama 1991).

    Parameters
    ----------
    source, target : (N, 3) float64
        Corresponding points, N >= 3 and not all collinear for a unique rotation.
    with_scale : bool
        Estimate the scale (else 1).

    Returns
    -------
    Similarity
        Minimises ``sum ||target_i - (s R source_i + t)||^2`` with ``det R = +1``.

    Raises
    ------
    ValueError
        Mismatched shapes, fewer than 3 points, non-finite values, or a degenerate source
        (all points equal).
    """
    src = np.asarray(source, dtype=np.float64)
    dst = np.asarray(target, dtype=np.float64)
    if src.ndim != 2 or src.shape[1] != 3 or src.shape != dst.shape:
        raise ValueError(f"umeyama: source and target must both be (N, 3), got {src.shape} and {dst.shape}")
    if src.shape[0] < 3:
        raise ValueError(f"umeyama: need at least 3 correspondences, got {src.shape[0]}")
    if not (np.isfinite(src).all() and np.isfinite(dst).all()):
        raise ValueError("umeyama: non-finite coordinates")
    mu_s, mu_d = src.mean(0), dst.mean(0)
    xs, xd = src - mu_s, dst - mu_d
    var_s = (xs**2).sum() / len(src)
    if var_s <= 0:
        raise ValueError("umeyama: degenerate source (all points equal)")
    cov = xd.T @ xs / len(src)
    u, d, vt = np.linalg.svd(cov)
    sign = np.ones(3)
    if np.linalg.det(u) * np.linalg.det(vt) < 0:
        sign[2] = -1.0
    rot = u @ np.diag(sign) @ vt
    scale = float((d * sign).sum() / var_s) if with_scale else 1.0
    trans = mu_d - scale * rot @ mu_s
    return Similarity(rot, trans, scale)


class RansacResult(NamedTuple):
    """Outcome of :func:`ransac_similarity`.

    Attributes
    ----------
    transform : Similarity
        Refit on all inliers of the best hypothesis.
    inliers : (N,) bool
    n_iterations : int
    """

    transform: Similarity
    inliers: np.ndarray
    n_iterations: int


def ransac_similarity(
    source: np.ndarray,
    target: np.ndarray,
    threshold: float,
    max_iterations: int = 200,
    confidence: float = 0.999,
    sample_size: int = 4,
    seed: int = 0,
    max_scale: float | None = None,
) -> RansacResult:
    """Robust similarity transform by RANSAC around :func:`umeyama` (ANCSH Sec. 4.3).

    Each iteration fits a hypothesis to ``sample_size`` random correspondences and counts the
    inliers (residual ``||target - T(source)|| < threshold``); the hypothesis with the most
    inliers is refit on them. Iterations stop early once the adaptive bound for
    ``confidence`` is reached.

    Parameters
    ----------
    source, target : (N, 3) float64
        Correspondences (e.g. NPCS coordinates and camera-frame points), N >= 3.
    threshold : float
        Inlier distance, in target units.
    max_iterations : int
    confidence : float
        Probability of drawing at least one all-inlier sample.
    sample_size : int
        Minimal sample, >= 3.
    seed : int
        Seed of the sampler (reproducible).
    max_scale : float, optional
        Hypotheses with a larger scale are rejected (degenerate samples of nearly equal
        source points give huge scales); the final refit is clipped to it too.

    Returns
    -------
    RansacResult

    Raises
    ------
    ValueError
        As :func:`umeyama`, or a non-positive threshold.
    """
    src = np.asarray(source, dtype=np.float64)
    dst = np.asarray(target, dtype=np.float64)
    if not threshold > 0:
        raise ValueError(f"ransac_similarity: threshold must be > 0, got {threshold}")
    n = len(src)
    if n < 3 or src.shape != dst.shape:
        raise ValueError(f"ransac_similarity: need matching (N, 3) arrays with N >= 3, got {src.shape}, {dst.shape}")
    k = min(max(sample_size, 3), n)
    rng = np.random.default_rng(seed)
    best_inliers = np.zeros(n, dtype=bool)
    best_count = -1
    needed = max_iterations
    it = 0
    while it < min(max_iterations, needed):
        it += 1
        idx = rng.choice(n, size=k, replace=False)
        try:
            hyp = umeyama(src[idx], dst[idx])
        except ValueError:
            continue
        if not np.isfinite(hyp.scale) or hyp.scale <= 0 or (max_scale is not None and hyp.scale > max_scale):
            continue
        res = np.linalg.norm(hyp.apply(src) - dst, axis=1)
        inl = res < threshold
        c = int(inl.sum())
        if c > best_count:
            best_count, best_inliers = c, inl
            w = c / n
            if w >= 1.0:
                needed = it
            elif w > 0:
                needed = int(np.ceil(np.log(1 - confidence) / np.log(max(1 - w**k, 1e-12))))
    if best_count < 3:
        best_inliers = np.ones(n, dtype=bool)
    final = umeyama(src[best_inliers], dst[best_inliers])
    # one re-selection pass with the refit model
    res = np.linalg.norm(final.apply(src) - dst, axis=1)
    inl = res < threshold
    if inl.sum() >= max(3, best_inliers.sum()):
        final = umeyama(src[inl], dst[inl])
        best_inliers = inl
    if max_scale is not None and final.scale > max_scale:
        # keep the rotation, refit the translation at the largest allowed scale
        s = float(max_scale)
        t = (dst[best_inliers] - s * src[best_inliers] @ final.rotation.T).mean(0)
        final = Similarity(final.rotation, t, s)
    return RansacResult(final, best_inliers, it)
