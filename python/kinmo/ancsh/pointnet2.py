"""PointNet++ in pure PyTorch (Qi et al. NeurIPS 2017): no compiled CUDA ops, so it installs
anywhere and runs on CPU or GPU. The backbone of ANCSH (Li et al. CVPR 2020).

Building blocks: farthest point sampling, ball query, grouping, set abstraction (SA) and
feature propagation (FP) layers, and a segmentation-style backbone producing per-point
features.
"""

from __future__ import annotations

import torch
from torch import nn


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


class SharedMLP(nn.Sequential):
    """1x1 convolutions with batch norm and ReLU over the channel dimension.

    Shapes:
        input (B, C_in, ...) -> output (B, C_out, ...) with ``len(...)`` of 1 or 2.
    """

    def __init__(self, channels: list[int], dims: int = 2) -> None:
        conv = nn.Conv2d if dims == 2 else nn.Conv1d
        bn = nn.BatchNorm2d if dims == 2 else nn.BatchNorm1d
        layers: list[nn.Module] = []
        for cin, cout in zip(channels[:-1], channels[1:]):
            layers += [conv(cin, cout, 1, bias=False), bn(cout), nn.ReLU(inplace=True)]
        super().__init__(*layers)


class SetAbstraction(nn.Module):
    """PointNet++ set abstraction: FPS centres, ball-query groups, shared MLP, max-pool.

    Shapes:
        xyz (B, N, 3), features (B, N, C) or None
        -> new_xyz (B, M, 3), new_features (B, M, mlp[-1])
    """

    def __init__(self, n_centers: int, radius: float, k: int, in_channels: int, mlp: list[int]) -> None:
        super().__init__()
        self.n_centers, self.radius, self.k = n_centers, radius, k
        self.mlp = SharedMLP([in_channels + 3, *mlp])

    def forward(self, xyz: torch.Tensor, features: torch.Tensor | None) -> tuple[torch.Tensor, torch.Tensor]:
        m = min(self.n_centers, xyz.shape[1])
        cidx = farthest_point_sample(xyz, m, seed=None)
        centers = gather_points(xyz, cidx)
        gidx = ball_query(self.radius, self.k, xyz, centers)  # (B, M, k)
        rel = gather_points(xyz, gidx) - centers.unsqueeze(2)  # (B, M, k, 3)
        grouped = rel if features is None else torch.cat([rel, gather_points(features, gidx)], -1)
        out = self.mlp(grouped.permute(0, 3, 1, 2))  # (B, C, M, k)
        return centers, out.max(-1).values.transpose(1, 2)


class FeaturePropagation(nn.Module):
    """PointNet++ feature propagation: inverse-distance interpolation from the 3 nearest
    coarse points, concatenated with the skip features, then a shared MLP.

    Shapes:
        xyz (B, N, 3), coarse_xyz (B, M, 3), skip (B, N, C1) or None, coarse (B, M, C2)
        -> (B, N, mlp[-1])
    """

    def __init__(self, in_channels: int, mlp: list[int]) -> None:
        super().__init__()
        self.mlp = SharedMLP([in_channels, *mlp], dims=1)

    def forward(
        self, xyz: torch.Tensor, coarse_xyz: torch.Tensor, skip: torch.Tensor | None, coarse: torch.Tensor
    ) -> torch.Tensor:
        k = min(3, coarse_xyz.shape[1])
        d, idx = torch.cdist(xyz, coarse_xyz).topk(k, dim=-1, largest=False)
        w = 1.0 / (d + 1e-8)
        w = w / w.sum(-1, keepdim=True)
        interp = (gather_points(coarse, idx) * w.unsqueeze(-1)).sum(2)
        x = interp if skip is None else torch.cat([skip, interp], -1)
        return self.mlp(x.transpose(1, 2)).transpose(1, 2)


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

    Shapes:
        xyz (B, N, 3) -> per-point features (B, N, out_channels)
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
        self.sa1 = SetAbstraction(n_centers[0], radii[0], k, 0, [w, w, 2 * w])
        self.sa2 = SetAbstraction(n_centers[1], radii[1], k, 2 * w, [2 * w, 2 * w, 4 * w])
        self.sa3 = SetAbstraction(n_centers[2], radii[2], k, 4 * w, [4 * w, 4 * w, 8 * w])
        self.fp3 = FeaturePropagation(8 * w + 4 * w, [4 * w, 4 * w])
        self.fp2 = FeaturePropagation(4 * w + 2 * w, [4 * w, 2 * w])
        self.fp1 = FeaturePropagation(2 * w, [2 * w, 2 * w])
        self.out_channels = 2 * w

    def forward(self, xyz: torch.Tensor) -> torch.Tensor:
        x1, f1 = self.sa1(xyz, None)
        x2, f2 = self.sa2(x1, f1)
        x3, f3 = self.sa3(x2, f2)
        f2 = self.fp3(x2, x3, f2, f3)
        f1 = self.fp2(x1, x2, f1, f2)
        return self.fp1(xyz, x1, None, f1)
