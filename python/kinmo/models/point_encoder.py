"""Per-part point-cloud encoders: PointNet (Qi et al. 2017) and DGCNN (Wang et al. 2019).

Both map each part's points ``(N, P, 3)`` to one feature vector ``(N, F)`` by a shared
per-point network followed by a symmetric max-pooling, so the result does not depend on the
order of the points. SWMP (the paper's code) encodes parts with DGCNN; PointNet is the cheap
default for CPUs.
"""

from __future__ import annotations

from collections.abc import Sequence

import torch
from torch import nn

__all__ = ["DGCNN", "PointNet", "make_point_encoder"]


class PointNet(nn.Module):
    """Vanilla PointNet encoder without input transforms.

    Parameters
    ----------
    widths : sequence of int
        Hidden widths of the shared per-point MLP, e.g. ``(64, 128)``.
    out_dim : int
        Feature width ``F``.

    Shapes:
        - input ``points``: ``(N, P, 3)`` float32, one point set per part.
        - output: ``(N, F)`` float32.
    """

    def __init__(self, widths: Sequence[int], out_dim: int) -> None:
        super().__init__()
        layers: list[nn.Module] = []
        d = 3
        for w in widths:
            layers += [nn.Linear(d, w), nn.ReLU()]
            d = w
        layers += [nn.Linear(d, out_dim)]
        self.mlp = nn.Sequential(*layers)
        self.out = nn.Sequential(nn.ReLU(), nn.Linear(out_dim, out_dim))
        self.out_dim = out_dim

    def forward(self, points: torch.Tensor) -> torch.Tensor:
        if points.ndim != 3 or points.shape[-1] != 3:
            raise ValueError(f"points must be (N, P, 3), got {tuple(points.shape)}")
        return self.out(self.mlp(points).max(dim=1).values)


def _knn(x: torch.Tensor, k: int) -> torch.Tensor:
    """Indices ``(N, P, k)`` of the ``k`` nearest neighbours (self included) in feature space."""
    d = torch.cdist(x, x)
    return d.topk(k, dim=-1, largest=False).indices


class _EdgeConv(nn.Module):
    """EdgeConv: ``max_k MLP([x_i, x_j - x_i])`` over the k-NN graph of the features."""

    def __init__(self, in_dim: int, out_dim: int, k: int) -> None:
        super().__init__()
        self.k = k
        self.mlp = nn.Sequential(nn.Linear(2 * in_dim, out_dim), nn.LeakyReLU(0.2))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        n, p, c = x.shape
        k = min(self.k, p)
        idx = _knn(x, k)  # (N, P, k)
        flat = x.reshape(n * p, c)
        base = (torch.arange(n, device=x.device) * p).view(n, 1, 1)
        nb = flat[(idx + base).reshape(-1)].reshape(n, p, k, c)  # neighbour features
        xi = x.unsqueeze(2).expand(n, p, k, c)
        return self.mlp(torch.cat([xi, nb - xi], dim=-1)).max(dim=2).values


class DGCNN(nn.Module):
    """DGCNN classification backbone (dynamic graph CNN) as a part encoder.

    Parameters
    ----------
    widths : sequence of int
        Output widths of the EdgeConv layers, e.g. ``(64, 64, 128)``.
    out_dim : int
        Feature width ``F``.
    k : int
        Neighbours per point (20 in the original).
    chunk : int
        Parts processed at a time (bounds the ``(chunk, P, k, C)`` memory).

    Shapes:
        - input ``points``: ``(N, P, 3)`` float32.
        - output: ``(N, F)`` float32.
    """

    def __init__(self, widths: Sequence[int], out_dim: int, k: int = 20, chunk: int = 64) -> None:
        super().__init__()
        self.convs = nn.ModuleList()
        d = 3
        for w in widths:
            self.convs.append(_EdgeConv(d, w, k))
            d = w
        self.proj = nn.Sequential(nn.Linear(sum(widths), out_dim), nn.LeakyReLU(0.2))
        self.out = nn.Linear(2 * out_dim, out_dim)
        self.chunk = chunk
        self.out_dim = out_dim

    def _encode(self, x: torch.Tensor) -> torch.Tensor:
        feats = []
        for conv in self.convs:
            x = conv(x)
            feats.append(x)
        h = self.proj(torch.cat(feats, dim=-1))
        return self.out(torch.cat([h.max(dim=1).values, h.mean(dim=1)], dim=-1))

    def forward(self, points: torch.Tensor) -> torch.Tensor:
        if points.ndim != 3 or points.shape[-1] != 3:
            raise ValueError(f"points must be (N, P, 3), got {tuple(points.shape)}")
        if points.shape[0] == 0:
            return points.new_zeros(0, self.out_dim)
        return torch.cat([self._encode(c) for c in points.split(self.chunk)], dim=0)


def make_point_encoder(kind: str, widths: Sequence[int], out_dim: int, k: int = 20) -> nn.Module:
    """Build ``"pointnet"`` or ``"dgcnn"``.

    Raises
    ------
    ValueError
        Unknown ``kind``.
    """
    if kind == "pointnet":
        return PointNet(widths, out_dim)
    if kind == "dgcnn":
        return DGCNN(widths, out_dim, k=k)
    raise ValueError(f"unknown point encoder {kind!r} (expected 'pointnet' or 'dgcnn')")
