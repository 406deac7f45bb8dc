"""PointNet++ in pure PyTorch (Qi et al. NeurIPS 2017): no compiled CUDA ops, so it installs
anywhere and runs on CPU or GPU. The backbone of ANCSH (Li et al. CVPR 2020).

Building blocks: set abstraction (SA) and feature propagation (FP) layers and a
segmentation-style backbone producing per-point features. The neighbourhoods of every level
(farthest point sampling, ball query, 3 nearest neighbours) come from a
:class:`~kinmo.ancsh.plan.GeometryPlan` computed before the network
(:mod:`kinmo.ancsh.plan`, the Rust core); called without one, the backbone builds it itself,
so inference and old callers need no change. Training (:func:`kinmo.ancsh.fit.train_step`)
builds each batch's plan before the forward pass. Features are channels-last
(``(B, N, C)``): the shared MLPs' 1x1 convolutions run as dense matrix products over all
positions (:func:`pointwise`), with the parameters and state dict of convolution layers.

The computation before plans (neighbourhoods by PyTorch inside each layer, channels-first
convolutions) is kept as ``forward_reference`` of the layers and the backbone: the reference
of the tests and the "before" of ``bench/bench_ancsh.py``.
"""

from __future__ import annotations

from collections.abc import Sequence

import torch
import torch.nn.functional as F
from torch import nn

from kinmo.ancsh.plan import (
    Backend,
    FPLevel,
    GeometryPlan,
    SALevel,
    ball_query,
    build_plan,
    farthest_point_sample,
    gather_points,
    plan_propagation,
    plan_set_abstraction,
)

__all__ = [
    "FPLevel", "FeaturePropagation", "GeometryPlan", "PointNet2Backbone", "SALevel", "SetAbstraction",
    "SharedMLP", "ball_query", "batch_norm_rows", "build_plan", "farthest_point_sample", "gather_points",
    "pointwise",
]


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
        ``bench/bench_ancsh.py``): the neighbourhoods planned in the layer by the PyTorch
        reference (:func:`plan_set_abstraction`, ``"torch"``), channels-first 1x1 convolutions."""
        level = plan_set_abstraction(xyz, self.n_centers, self.radius, self.k, "torch")
        centers = gather_points(xyz, level.centers)
        gidx = level.groups  # (B, M, k)
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
        ``torch.cdist`` nearest neighbours in the layer (:func:`plan_propagation`, ``"torch"``),
        channels-first 1x1 convolutions."""
        level = plan_propagation(xyz, coarse_xyz, "torch")
        interp = (gather_points(coarse, level.index) * level.weight.unsqueeze(-1)).sum(2)
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
        neighbourhoods computed inside each layer by :mod:`kinmo.ancsh.plan`'s PyTorch functions, the 1x1
        convolutions channels-first. Same parameters, same function as :meth:`forward` up to
        the plan's rule (:mod:`kinmo.ancsh.plan`) and float rounding."""
        x1, f1 = self.sa1.forward_reference(xyz, None)
        x2, f2 = self.sa2.forward_reference(x1, f1)
        x3, f3 = self.sa3.forward_reference(x2, f2)
        f2 = self.fp3.forward_reference(x2, x3, f2, f3)
        f1 = self.fp2.forward_reference(x1, x2, f1, f2)
        return self.fp1.forward_reference(xyz, x1, None, f1)
