"""PointNet++ geometry plans: the neighbourhoods of every level of a batch, before the network.

Which points become centres (farthest point sampling), which points each centre groups (ball
query) and which coarse points each point interpolates from (3 nearest neighbours) depend
only on the input coordinates (Qi et al. NeurIPS 2017). :func:`build_plan` computes them for
the three set-abstraction (SA) and feature-propagation (FP) levels of
:class:`kinmo.ancsh.pointnet2.PointNet2Backbone` for a whole batch at once, outside
autograd, as a :class:`GeometryPlan` (indices and interpolation weights) that the backbone
takes with the coordinates; the network itself is then only gathers, matrix products and
pooling. A plan is computed by the Rust core (:mod:`kinmo.geometry.pointnet`, parallel over
the batch, on CPU: CUDA inputs are copied to the CPU for planning and the indices copied
back), or, as a reference, by this module's PyTorch functions (``backend="torch"``:
:func:`farthest_point_sample`, :func:`ball_query`, ``torch.cdist``, the computation the
layers did inline before plans).

**Reproducibility rule of plans** (Rust backend, :mod:`kinmo.geometry.pointnet`):

- farthest point sampling starts at point 0 of every cloud and keeps float32 distances
  evaluated as PyTorch evaluates them, taking the first point of largest distance: the
  centres are exactly the reference's, cloud by cloud, whatever the batch or thread count;
- a ball holds the first ``min(k, N)`` points in index order whose float64 squared distance
  to the centre is at most ``radius ** 2`` (padded with the first). The reference compares
  ``torch.cdist``'s float32 distances, computed through a matrix product; the two can
  disagree only for points within about ``1e-6`` of the radius (float ties at the boundary);
- feature propagation interpolates from the 3 nearest coarse points by float64 distance,
  ties by index, with weights ``1 / (d + 1e-8)`` normalised. The distances are exact, where
  ``torch.cdist``'s matrix product leaves about ``1e-4`` for a point that is itself a coarse
  point, so the reference gives such points a weight of ~0.99 on themselves where the plan
  gives 1: forward passes and losses agree to about 1e-4 relative, gradients to about 2e-2
  (tests/ancsh/test_pointnet2_plan.py), not bit for bit.

Every plan is deterministic: the same float32 coordinates give the same plan on any machine,
batch by batch or cloud by cloud.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
import torch

from kinmo.geometry import pointnet as _rust

__all__ = [
    "Backend", "FPLevel", "GeometryPlan", "SALevel", "ball_query", "build_plan",
    "farthest_point_sample", "gather_points", "plan_propagation", "plan_set_abstraction",
]

#: Where a plan is computed: the Rust core (default) or this module's PyTorch functions.
Backend = Literal["rust", "torch"]


def farthest_point_sample(xyz: torch.Tensor, n_samples: int, seed: int | None = 0) -> torch.Tensor:
    """Iterative farthest point sampling.

    Parameters
    ----------
    xyz : (B, N, 3) float tensor
    n_samples : int
        M <= N.
    seed : int or None
        First point chosen: index 0 when ``seed`` is None, else drawn with a generator seeded
        by ``seed`` (reproducible).

    Returns
    -------
    (B, M) int64 tensor of indices into N.
    """
    b, n, _ = xyz.shape
    device = xyz.device
    idx = torch.zeros(b, n_samples, dtype=torch.long, device=device)
    dist = torch.full((b, n), float("inf"), device=device, dtype=xyz.dtype)
    if seed is None:
        far = torch.zeros(b, dtype=torch.long, device=device)
    else:
        g = torch.Generator().manual_seed(seed)
        far = torch.randint(0, n, (b,), generator=g).to(device)
    ar = torch.arange(b, device=device)
    for i in range(n_samples):
        idx[:, i] = far
        centroid = xyz[ar, far].unsqueeze(1)
        d = ((xyz - centroid) ** 2).sum(-1)
        dist = torch.minimum(dist, d)
        far = dist.argmax(-1)
    return idx


def gather_points(x: torch.Tensor, idx: torch.Tensor) -> torch.Tensor:
    """Gather ``x (B, N, C)`` at ``idx (B, ...)`` -> ``(B, ..., C)``."""
    b = x.shape[0]
    flat = idx.reshape(b, -1)
    out = torch.gather(x, 1, flat.unsqueeze(-1).expand(-1, -1, x.shape[-1]))
    return out.reshape(*idx.shape, x.shape[-1])


def ball_query(radius: float, k: int, xyz: torch.Tensor, centers: torch.Tensor) -> torch.Tensor:
    """Indices of up to ``k`` points within ``radius`` of each centre.

    Slots beyond the number of neighbours repeat the first neighbour (the centre itself is
    always a neighbour when centres are a subset of ``xyz``), as in the reference PointNet++.

    Parameters
    ----------
    radius : float
    k : int
    xyz : (B, N, 3)
    centers : (B, M, 3)

    Returns
    -------
    (B, M, k) int64
    """
    n = xyz.shape[1]
    d2 = torch.cdist(centers, xyz).pow(2)  # (B, M, N)
    ar = torch.arange(n, device=xyz.device).expand_as(d2)
    key = torch.where(d2 <= radius * radius, ar, torch.full_like(ar, n))
    key = key.sort(dim=-1).values[..., :k]
    first = key[..., :1].expand_as(key)
    key = torch.where(key == n, first, key)
    # a centre with no neighbour at all (cannot happen for subset centres): use nearest
    nearest = d2.argmin(-1, keepdim=True).expand_as(key)
    return torch.where(key == n, nearest, key)


@dataclass(frozen=True)
class SALevel:
    """Indices of one set abstraction level.

    Attributes
    ----------
    centers : (B, M) int64
        The centres (farthest point sampling) among the level's ``N`` input points.
    groups : (B, M, min(k, N)) int64
        Each centre's group (ball query), indices into ``N``.
    """

    centers: torch.Tensor
    groups: torch.Tensor


@dataclass(frozen=True)
class FPLevel:
    """Interpolation of one feature propagation level: ``N`` points from ``M`` coarse ones.

    Attributes
    ----------
    index : (B, N, k) int64
        The ``k = min(3, M)`` nearest coarse points, nearest first.
    weight : (B, N, k) float32
        Normalised inverse-distance weights ``1 / (d + 1e-8)``.
    """

    index: torch.Tensor
    weight: torch.Tensor


@dataclass(frozen=True)
class GeometryPlan:
    """The neighbourhoods of every level of a
    :class:`~kinmo.ancsh.pointnet2.PointNet2Backbone` for one batch.

    Attributes
    ----------
    sa : tuple of SALevel
        Levels 1, 2, 3 (level ``l + 1`` indexes the centres of level ``l``).
    fp : tuple of FPLevel
        In the order the backbone runs them: level-2 centres from level-3 centres, level-1
        centres from level-2 centres, input points from level-1 centres.
    """

    sa: tuple[SALevel, ...]
    fp: tuple[FPLevel, ...]

    def to(self, device: torch.device | str, non_blocking: bool = False) -> GeometryPlan:
        """The plan with every tensor on ``device``."""
        mv = lambda t: t.to(device, non_blocking=non_blocking)  # noqa: E731
        return GeometryPlan(tuple(SALevel(mv(s.centers), mv(s.groups)) for s in self.sa),
                            tuple(FPLevel(mv(f.index), mv(f.weight)) for f in self.fp))


def _weights(d: torch.Tensor) -> torch.Tensor:
    w = 1.0 / (d + 1e-8)
    return w / w.sum(-1, keepdim=True)


def _cpu(xyz: torch.Tensor) -> np.ndarray:
    """``(B, N, 3)`` coordinates as a float32 CPU array for the Rust core."""
    return xyz.detach().to("cpu", torch.float32).contiguous().numpy()


def _rust_sa(p: np.ndarray, n_centers: int, radius: float, k: int
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Centres ``(B, M)``, groups ``(B, M, min(k, N))`` and the centres' coordinates
    ``(B, M, 3)`` (the next level's cloud) of the clouds ``p (B, N, 3)``."""
    c = _rust.farthest_point_sample(p, min(n_centers, p.shape[1]))
    xyz = np.take_along_axis(p, c[..., None], 1)
    return c, _rust.ball_query(p, xyz, radius, min(k, p.shape[1])), xyz


def _rust_fp(fine: np.ndarray, coarse: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The ``min(3, M)`` nearest of ``coarse (B, M, 3)`` to each of ``fine (B, N, 3)``:
    indices and distances."""
    return _rust.k_nearest(coarse, fine, min(3, coarse.shape[1]))


def plan_set_abstraction(xyz: torch.Tensor, n_centers: int, radius: float, k: int,
                         backend: Backend = "rust") -> SALevel:
    """The centres and groups of one SA level (module docstring).

    Parameters
    ----------
    xyz : (B, N, 3) float tensor
    n_centers : int
        Centres wanted; ``min(n_centers, N)`` are taken.
    radius : float
    k : int
    backend : {"rust", "torch"}

    Returns
    -------
    SALevel
        On ``xyz``'s device.
    """
    with torch.no_grad():
        if backend == "torch":
            cidx = farthest_point_sample(xyz, min(n_centers, xyz.shape[1]), seed=None)
            return SALevel(cidx, ball_query(radius, k, xyz, gather_points(xyz, cidx)))
        c, g, _ = _rust_sa(_cpu(xyz), n_centers, radius, k)
        return SALevel(torch.from_numpy(c).to(xyz.device), torch.from_numpy(g).to(xyz.device))


def plan_propagation(xyz: torch.Tensor, coarse_xyz: torch.Tensor, backend: Backend = "rust") -> FPLevel:
    """The interpolation of one FP level (module docstring).

    Parameters
    ----------
    xyz : (B, N, 3) float tensor
    coarse_xyz : (B, M, 3) float tensor
    backend : {"rust", "torch"}

    Returns
    -------
    FPLevel
        On ``xyz``'s device.
    """
    with torch.no_grad():
        if backend == "torch":
            d, idx = torch.cdist(xyz, coarse_xyz).topk(min(3, coarse_xyz.shape[1]), dim=-1, largest=False)
            return FPLevel(idx, _weights(d))
        idx, d = _rust_fp(_cpu(xyz), _cpu(coarse_xyz))
        return FPLevel(torch.from_numpy(idx).to(xyz.device), _weights(torch.from_numpy(d)).to(xyz.device))


def build_plan(
    xyz: torch.Tensor,
    n_centers: tuple[int, ...],
    radii: tuple[float, ...],
    k: int,
    backend: Backend = "rust",
) -> GeometryPlan:
    """The :class:`GeometryPlan` of a batch for a backbone of these sizes.

    Parameters
    ----------
    xyz : (B, N, 3) float tensor
        The backbone's input.
    n_centers, radii : tuples of 3
    k : int
        Group size.
    backend : {"rust", "torch"}
        ``"rust"``: :mod:`kinmo.geometry.pointnet` on CPU (the module's reproducibility rule;
        the levels are planned on one CPU copy of ``xyz``, so a CUDA batch crosses to the
        CPU once); ``"torch"``: the reference functions of this module, on ``xyz``'s device.

    Returns
    -------
    GeometryPlan
        On ``xyz``'s device.
    """
    if backend not in ("rust", "torch"):
        raise ValueError(f"unknown plan backend {backend!r} (rust or torch)")
    if backend == "torch":
        return _build_plan_torch(xyz, n_centers, radii, k)
    levels, clouds = [], [_cpu(xyz)]
    for m, r in zip(n_centers, radii):
        c, g, nxt = _rust_sa(clouds[-1], m, r, k)
        levels.append((c, g))
        clouds.append(nxt)
    fps = [_rust_fp(fine, coarse) for fine, coarse in _fp_pairs(clouds)]
    dev = xyz.device
    return GeometryPlan(
        tuple(SALevel(torch.from_numpy(c).to(dev), torch.from_numpy(g).to(dev)) for c, g in levels),
        tuple(FPLevel(torch.from_numpy(i).to(dev), _weights(torch.from_numpy(d)).to(dev)) for i, d in fps))


def _fp_pairs(clouds: list) -> tuple:
    """(fine, coarse) clouds of the FP levels, in the backbone's order (:class:`GeometryPlan`)."""
    return (clouds[2], clouds[3]), (clouds[1], clouds[2]), (clouds[0], clouds[1])


def _build_plan_torch(xyz: torch.Tensor, n_centers: tuple[int, ...], radii: tuple[float, ...],
                      k: int) -> GeometryPlan:
    with torch.no_grad():
        clouds, levels = [xyz.detach()], []
        for m, r in zip(n_centers, radii):
            lv = plan_set_abstraction(clouds[-1], m, r, k, "torch")
            levels.append(lv)
            clouds.append(gather_points(clouds[-1], lv.centers))
        fps = tuple(plan_propagation(fine, coarse, "torch") for fine, coarse in _fp_pairs(clouds))
    return GeometryPlan(tuple(levels), fps)
