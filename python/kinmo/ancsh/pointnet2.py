"""PointNet++ in pure PyTorch (Qi et al. NeurIPS 2017): no compiled CUDA ops, so it installs
anywhere and runs on CPU or GPU. The backbone of ANCSH (Li et al. CVPR 2020).

Building blocks: farthest point sampling, ball query, grouping, set abstraction (SA) and
feature propagation (FP) layers, and a segmentation-style backbone producing per-point
features. Features are channels-last (``(B, N, C)``): the shared MLPs' 1x1 convolutions run
as dense matrix products over all positions (:func:`pointwise`), with the parameters and
state dict of convolution layers.

**Geometry plans.** Which points become centres (farthest point sampling), which points each
centre groups (ball query) and which coarse points each point interpolates from (3 nearest
neighbours) depend only on the input coordinates. :func:`build_plan` computes them for all
three SA and FP levels of a batch at once, outside autograd, as a :class:`GeometryPlan`
(indices and interpolation weights) that :class:`PointNet2Backbone` takes with the
coordinates; the network itself is then only gathers, convolutions and pooling. The plan is
computed by the Rust core (:mod:`kinmo.geometry.pointnet`, parallel over the batch, on CPU:
CUDA inputs are copied to the CPU for planning and the indices copied back), or, as a
reference, by the PyTorch functions of this module (``backend="torch"``). Called without a
plan, the backbone builds one itself with the Rust core, so inference and old callers need no
change. Training (:func:`kinmo.ancsh.fit.train_step`) builds each batch's plan before the
forward pass. The computation before plans (neighbourhoods inside each layer, channels-first
convolutions) is kept as ``forward_reference`` of the layers and the backbone, the reference
of the tests and of ``bench/bench_ancsh.py``.

**Reproducibility rule of plans** (Rust backend, :mod:`kinmo.geometry.pointnet`):

- farthest point sampling starts at point 0 of every cloud and keeps float32 distances
  evaluated as PyTorch evaluates them, taking the first point of largest distance: the
  centres are exactly the reference's, cloud by cloud, whatever the batch or thread count;
- a ball holds the first ``k`` points in index order whose float64 squared distance to the
  centre is at most ``radius ** 2`` (padded with the first). The reference compares
  ``torch.cdist``'s float32 distances, computed through a matrix product; the two can
  disagree only for points within about ``1e-6`` of the radius (float ties at the boundary);
- feature propagation interpolates from the 3 nearest coarse points by float64 distance,
  ties by index, with weights ``1 / (d + 1e-8)`` normalised. The distances are exact, where
  ``torch.cdist``'s matrix product leaves about ``1e-4`` for a point on a coarse point
  (itself), so the reference gives such points a weight of ~0.99 on themselves where the plan
  gives 1: the networks agree to about 1e-3 relative, not bit for bit.

Every plan is deterministic: the same coordinates give the same plan on any machine.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np
import torch
import torch.nn.functional as F
from torch import nn

from kinmo.geometry import pointnet as _rust

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
    """The neighbourhoods of every level of a :class:`PointNet2Backbone` for one batch.

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
    m = min(n_centers, xyz.shape[1])
    with torch.no_grad():
        if backend == "torch":
            cidx = farthest_point_sample(xyz, m, seed=None)
            return SALevel(cidx, ball_query(radius, k, xyz, gather_points(xyz, cidx)))
        p = xyz.detach().to("cpu", torch.float32).numpy()
        c = _rust.farthest_point_sample(p, m)
        g = _rust.ball_query(p, np.take_along_axis(p, c[..., None], 1), radius, min(k, p.shape[1]))
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
    k = min(3, coarse_xyz.shape[1])
    with torch.no_grad():
        if backend == "torch":
            d, idx = torch.cdist(xyz, coarse_xyz).topk(k, dim=-1, largest=False)
            return FPLevel(idx, _weights(d))
        idx, d = _rust.k_nearest(coarse_xyz.detach().to("cpu", torch.float32).numpy(),
                                 xyz.detach().to("cpu", torch.float32).numpy(), k)
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
        ``"rust"``: :mod:`kinmo.geometry.pointnet` on CPU (the module's reproducibility rule);
        ``"torch"``: the reference functions of this module, on ``xyz``'s device.

    Returns
    -------
    GeometryPlan
        On ``xyz``'s device.
    """
    if backend not in ("rust", "torch"):
        raise ValueError(f"unknown plan backend {backend!r} (rust or torch)")
    if backend == "torch":
        return _build_plan_torch(xyz, n_centers, radii, k)
    with torch.no_grad():
        p = xyz.detach().to("cpu", torch.float32).contiguous().numpy()
    levels, clouds = [], [p]
    for m, r in zip(n_centers, radii):
        cur = clouds[-1]
        c = _rust.farthest_point_sample(cur, min(m, cur.shape[1]))
        nxt = np.take_along_axis(cur, c[..., None], 1)
        levels.append((c, _rust.ball_query(cur, nxt, r, min(k, cur.shape[1]))))
        clouds.append(nxt)
    fps = []
    for fine, coarse in ((clouds[2], clouds[3]), (clouds[1], clouds[2]), (clouds[0], clouds[1])):
        idx, d = _rust.k_nearest(coarse, fine, min(3, coarse.shape[1]))
        fps.append((idx, d))
    dev = xyz.device
    return GeometryPlan(
        tuple(SALevel(torch.from_numpy(c).to(dev), torch.from_numpy(g).to(dev)) for c, g in levels),
        tuple(FPLevel(torch.from_numpy(i).to(dev), _weights(torch.from_numpy(d)).to(dev)) for i, d in fps))


def _build_plan_torch(xyz: torch.Tensor, n_centers: tuple[int, ...], radii: tuple[float, ...],
                      k: int) -> GeometryPlan:
    with torch.no_grad():
        clouds, levels = [xyz.detach()], []
        for m, r in zip(n_centers, radii):
            lv = plan_set_abstraction(clouds[-1], m, r, k, "torch")
            levels.append(lv)
            clouds.append(gather_points(clouds[-1], lv.centers))
        fps = tuple(plan_propagation(fine, coarse, "torch")
                    for fine, coarse in ((clouds[2], clouds[3]), (clouds[1], clouds[2]), (clouds[0], clouds[1])))
    return GeometryPlan(tuple(levels), fps)


def batch_norm_rows(bn: nn.modules.batchnorm._BatchNorm, h: torch.Tensor) -> torch.Tensor:
    """``bn`` (a ``BatchNorm1d`` / ``2d``) applied to ``h (P, C)``, one row per position.

    The same normalisation, running averages and batch counter as ``bn`` on the
    channels-first tensor of those ``P`` positions (statistics are over every position of
    the batch either way).
    """
    factor = 0.0
    if bn.training and bn.track_running_stats and bn.num_batches_tracked is not None:
        bn.num_batches_tracked.add_(1)
        factor = 1.0 / float(bn.num_batches_tracked) if bn.momentum is None else bn.momentum
    batch_stats = bn.training or bn.running_mean is None
    return F.batch_norm(h, bn.running_mean if not bn.training or bn.track_running_stats else None,
                        bn.running_var if not bn.training or bn.track_running_stats else None,
                        bn.weight, bn.bias, batch_stats, factor, bn.eps)


def pointwise(layers: Sequence[nn.Module], x: torch.Tensor) -> torch.Tensor:
    """Kernel-size-1 convolutions, batch norms and ReLUs applied to channels-last ``x``.

    Each 1x1 ``Conv1d`` / ``Conv2d`` is the matrix product with its weight (and bias), each
    batch norm :func:`batch_norm_rows`: the same function and parameters as the layers on the
    channels-first tensor, without its transposes and with dense matrix products.

    Shapes:
        x (..., C_in) -> (..., C_out)
    """
    shape = x.shape[:-1]
    h = x.reshape(-1, x.shape[-1])
    for layer in layers:
        if isinstance(layer, (nn.Conv1d, nn.Conv2d)):
            h = F.linear(h, layer.weight.reshape(layer.out_channels, -1), layer.bias)
        elif isinstance(layer, nn.modules.batchnorm._BatchNorm):
            h = batch_norm_rows(layer, h)
        elif isinstance(layer, nn.ReLU):
            h = F.relu(h, inplace=layer.inplace)
        else:
            raise TypeError(f"pointwise: unsupported layer {type(layer).__name__}")
    return h.reshape(*shape, h.shape[-1])


class SharedMLP(nn.Sequential):
    """1x1 convolutions with batch norm and ReLU over the channel dimension.

    The layers are ``Conv{dims}d`` / ``BatchNorm{dims}d`` / ``ReLU`` (the parameters and
    state dict of the reference PointNet++), applied to channels-last inputs with
    :func:`pointwise`.

    Shapes:
        input (..., C_in) -> output (..., C_out)
    """

    def __init__(self, channels: list[int], dims: int = 2) -> None:
        conv = nn.Conv2d if dims == 2 else nn.Conv1d
        bn = nn.BatchNorm2d if dims == 2 else nn.BatchNorm1d
        layers: list[nn.Module] = []
        for cin, cout in zip(channels[:-1], channels[1:]):
            layers += [conv(cin, cout, 1, bias=False), bn(cout), nn.ReLU(inplace=True)]
        super().__init__(*layers)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return pointwise(self, x)


class SetAbstraction(nn.Module):
    """PointNet++ set abstraction: FPS centres, ball-query groups, shared MLP, max-pool.

    The centres and groups come from ``level`` (:func:`plan_set_abstraction`), planned here
    with the Rust core when not given.

    Shapes:
        xyz (B, N, 3), features (B, N, C) or None
        -> new_xyz (B, M, 3), new_features (B, M, mlp[-1])
    """

    def __init__(self, n_centers: int, radius: float, k: int, in_channels: int, mlp: list[int]) -> None:
        super().__init__()
        self.n_centers, self.radius, self.k = n_centers, radius, k
        self.mlp = SharedMLP([in_channels + 3, *mlp])

    def forward(self, xyz: torch.Tensor, features: torch.Tensor | None,
                level: SALevel | None = None) -> tuple[torch.Tensor, torch.Tensor]:
        if level is None:
            level = plan_set_abstraction(xyz, self.n_centers, self.radius, self.k)
        centers = gather_points(xyz, level.centers)
        gidx = level.groups  # (B, M, k)
        rel = gather_points(xyz, gidx) - centers.unsqueeze(2)  # (B, M, k, 3)
        grouped = rel if features is None else torch.cat([rel, gather_points(features, gidx)], -1)
        return centers, self.mlp(grouped).max(2).values  # (B, M, k, C) -> (B, M, C)

    def forward_reference(self, xyz: torch.Tensor, features: torch.Tensor | None) -> tuple[torch.Tensor, torch.Tensor]:
        """The computation before geometry plans (kept as the reference of tests and
        ``bench/bench_ancsh.py``): PyTorch FPS and ball query inline, channels-first 1x1
        convolutions."""
        m = min(self.n_centers, xyz.shape[1])
        cidx = farthest_point_sample(xyz, m, seed=None)
        centers = gather_points(xyz, cidx)
        gidx = ball_query(self.radius, self.k, xyz, centers)  # (B, M, k)
        rel = gather_points(xyz, gidx) - centers.unsqueeze(2)  # (B, M, k, 3)
        grouped = rel if features is None else torch.cat([rel, gather_points(features, gidx)], -1)
        out = nn.Sequential.forward(self.mlp, grouped.permute(0, 3, 1, 2))  # (B, C, M, k)
        return centers, out.max(-1).values.transpose(1, 2)


class FeaturePropagation(nn.Module):
    """PointNet++ feature propagation: inverse-distance interpolation from the 3 nearest
    coarse points, concatenated with the skip features, then a shared MLP.

    The neighbours and weights come from ``level`` (:func:`plan_propagation`), planned here
    with the Rust core when not given.

    Shapes:
        xyz (B, N, 3), coarse_xyz (B, M, 3), skip (B, N, C1) or None, coarse (B, M, C2)
        -> (B, N, mlp[-1])
    """

    def __init__(self, in_channels: int, mlp: list[int]) -> None:
        super().__init__()
        self.mlp = SharedMLP([in_channels, *mlp], dims=1)

    def forward(
        self, xyz: torch.Tensor, coarse_xyz: torch.Tensor, skip: torch.Tensor | None, coarse: torch.Tensor,
        level: FPLevel | None = None,
    ) -> torch.Tensor:
        if level is None:
            level = plan_propagation(xyz, coarse_xyz)
        interp = (gather_points(coarse, level.index) * level.weight.unsqueeze(-1)).sum(2)
        x = interp if skip is None else torch.cat([skip, interp], -1)
        return self.mlp(x)

    def forward_reference(
        self, xyz: torch.Tensor, coarse_xyz: torch.Tensor, skip: torch.Tensor | None, coarse: torch.Tensor
    ) -> torch.Tensor:
        """The computation before geometry plans (see :meth:`SetAbstraction.forward_reference`):
        ``torch.cdist`` nearest neighbours inline, channels-first 1x1 convolutions."""
        k = min(3, coarse_xyz.shape[1])
        d, idx = torch.cdist(xyz, coarse_xyz).topk(k, dim=-1, largest=False)
        w = 1.0 / (d + 1e-8)
        w = w / w.sum(-1, keepdim=True)
        interp = (gather_points(coarse, idx) * w.unsqueeze(-1)).sum(2)
        x = interp if skip is None else torch.cat([skip, interp], -1)
        return nn.Sequential.forward(self.mlp, x.transpose(1, 2)).transpose(1, 2)


class PointNet2Backbone(nn.Module):
    """Segmentation-style PointNet++ (SSG): 3 SA levels down, 3 FP levels up.

    Parameters
    ----------
    width : int
        Base channel width (64 in the paper's backbone; smaller for CPU presets).
    n_centers : tuple of int
        Centres of the three SA levels.
    radii : tuple of float
        Ball radii (input units; inputs are expected normalised to about unit size).
    k : int
        Group size of the ball queries.

    Shapes:
        xyz (B, N, 3), optional plan (:class:`GeometryPlan` of ``xyz``, :meth:`plan`)
        -> per-point features (B, N, out_channels)
    """

    def __init__(
        self,
        width: int = 64,
        n_centers: tuple[int, int, int] = (512, 128, 32),
        radii: tuple[float, float, float] = (0.1, 0.2, 0.4),
        k: int = 32,
    ) -> None:
        super().__init__()
        w = width
        self.n_centers, self.radii, self.k = tuple(n_centers), tuple(radii), k
        self.sa1 = SetAbstraction(n_centers[0], radii[0], k, 0, [w, w, 2 * w])
        self.sa2 = SetAbstraction(n_centers[1], radii[1], k, 2 * w, [2 * w, 2 * w, 4 * w])
        self.sa3 = SetAbstraction(n_centers[2], radii[2], k, 4 * w, [4 * w, 4 * w, 8 * w])
        self.fp3 = FeaturePropagation(8 * w + 4 * w, [4 * w, 4 * w])
        self.fp2 = FeaturePropagation(4 * w + 2 * w, [4 * w, 2 * w])
        self.fp1 = FeaturePropagation(2 * w, [2 * w, 2 * w])
        self.out_channels = 2 * w

    def plan(self, xyz: torch.Tensor, backend: Backend = "rust") -> GeometryPlan:
        """The :class:`GeometryPlan` of ``xyz (B, N, 3)`` for this backbone (:func:`build_plan`)."""
        return build_plan(xyz, self.n_centers, self.radii, self.k, backend)

    def forward(self, xyz: torch.Tensor, plan: GeometryPlan | None = None) -> torch.Tensor:
        if plan is None:
            plan = self.plan(xyz)
        elif plan.fp[2].index.shape[:2] != xyz.shape[:2]:
            raise ValueError(f"the plan is of a batch of {tuple(plan.fp[2].index.shape[:2])} points, "
                             f"the input of {tuple(xyz.shape[:2])}")
        x1, f1 = self.sa1(xyz, None, plan.sa[0])
        x2, f2 = self.sa2(x1, f1, plan.sa[1])
        x3, f3 = self.sa3(x2, f2, plan.sa[2])
        f2 = self.fp3(x2, x3, f2, f3, plan.fp[0])
        f1 = self.fp2(x1, x2, f1, f2, plan.fp[1])
        return self.fp1(xyz, x1, None, f1, plan.fp[2])

    def forward_reference(self, xyz: torch.Tensor) -> torch.Tensor:
        """The computation before geometry plans, the reference of tests and benchmarks: the
        neighbourhoods computed inside each layer by this module's PyTorch functions, the 1x1
        convolutions channels-first. Same parameters, same function as :meth:`forward` up to
        the plan's rule (module docstring) and float rounding."""
        x1, f1 = self.sa1.forward_reference(xyz, None)
        x2, f2 = self.sa2.forward_reference(x1, f1)
        x3, f3 = self.sa3.forward_reference(x2, f2)
        f2 = self.fp3.forward_reference(x2, x3, f2, f3)
        f1 = self.fp2.forward_reference(x1, x2, f1, f2)
        return self.fp1.forward_reference(xyz, x1, None, f1)
