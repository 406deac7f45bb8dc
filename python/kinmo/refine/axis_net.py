"""The axis-selection network: a Siamese DGCNN judging whether a motion is feasible.

Liu et al. 2023, Sec. 3.3: a candidate axis is good when moving the part about / along it
gives a plausible configuration of the object (a door swinging out of its frame, not through
the cabinet). The network sees the moving and reference parts before and after a candidate
motion (:mod:`kinmo.refine.motions`): each state is a point cloud of ``N`` points with 4
channels (pair-frame ``x, y, z`` and a moving/reference flag). One DGCNN encoder (Wang et al.,
*Dynamic Graph CNN for Learning on Point Clouds*, TOG 2019), shared by both states, maps each
cloud to a global feature; the two features are concatenated and a small MLP predicts the
logit of "this motion is feasible". Trained with binary cross-entropy on motions about the
true axis (positives) and about wrong candidates (negatives), :mod:`kinmo.refine.train`.

The encoder follows DGCNN's classification backbone as used by the paper's code: EdgeConv
layers ``h(x_i, x_j - x_i)`` max-pooled over the ``k`` nearest neighbours, the first graph
built on the coordinates, the later ones dynamically in feature space; the per-point outputs
of all layers are concatenated, lifted to ``emb_dim`` and pooled by max and mean. Pure PyTorch
(no CUDA ops), so it runs on CPUs.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Literal

import torch
from pydantic import BaseModel, ConfigDict, Field
from torch import nn

__all__ = ["AxisNetConfig", "AxisSelectionNet", "DGCNNEncoder", "EdgeConv", "knn"]

#: Input channels: pair-frame coordinates and the moving flag.
IN_CHANNELS = 4


class AxisNetConfig(BaseModel):
    """Architecture of :class:`AxisSelectionNet` (saved with every checkpoint).

    Attributes
    ----------
    n_points : int
        Points per cloud ``N`` (half moving, half reference).
    k : int
        Neighbours of the EdgeConv graphs (DGCNN: 20).
    widths : list of int
        Output channels of the EdgeConv layers (DGCNN / the paper's code: 64, 64, 128).
    emb_dim : int
        Per-point embedding width before pooling; the global feature is ``2 * emb_dim``
        (max and mean pooling).
    head : list of int
        Hidden widths of the classifier on the concatenated features.
    dropout : float
        Dropout of the classifier's hidden layers.
    norm : {"batch", "group", "none"}
        Normalisation after each layer (DGCNN: batch).
    dynamic : bool
        Rebuild the k-NN graph in feature space before every EdgeConv layer after the first
        (DGCNN); False keeps the graph of the coordinates for all layers (cheaper: the
        ``top-k`` search dominates the cost on CPUs).
    context_fraction : float
        Share of the ``N`` points sampled from the rest of the shape (neither the moving nor
        the reference part, :func:`kinmo.refine.motions.shape_context`); part of the input
        format, so training and refinement use the same.
    crop : float or None
        Static points farther than ``crop`` times the moving part's size from it are left
        out (:func:`kinmo.refine.motions.pair_cloud`); None: the whole parts. Input format
        too.
    input : {"pair", "shape"}
        Static points from the reference part plus context (``"pair"``, kinmo) or from the
        whole shape without the moving part (``"shape"``, the paper's code;
        :func:`kinmo.refine.motions.edge_cloud`). Input format too.
    """

    model_config = ConfigDict(extra="forbid")

    n_points: int = Field(1024, ge=8)
    k: int = Field(20, ge=2)
    widths: list[int] = Field(default_factory=lambda: [64, 64, 128], min_length=1)
    emb_dim: int = Field(256, ge=1)
    head: list[int] = Field(default_factory=lambda: [256, 128])
    dropout: float = Field(0.5, ge=0.0, lt=1.0)
    norm: Literal["batch", "group", "none"] = "batch"
    dynamic: bool = True
    context_fraction: float = Field(0.25, ge=0.0, lt=0.5)
    crop: float | None = Field(None, gt=0.0)
    input: Literal["pair", "shape"] = "pair"


class _ChannelNorm(nn.Module):
    """Batch / group / no normalisation of channel-last features ``(..., C)``."""

    def __init__(self, kind: str, channels: int) -> None:
        super().__init__()
        self.kind = kind
        if kind == "batch":
            self.norm: nn.Module = nn.BatchNorm1d(channels)
        elif kind == "group":
            self.norm = nn.GroupNorm(next(g for g in (8, 4, 2, 1) if channels % g == 0), channels)
        else:
            self.norm = nn.Identity()

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        if self.kind == "batch":
            return self.norm(x.reshape(-1, x.shape[-1])).reshape(x.shape)
        if self.kind == "group":  # statistics per sample: move channels to dim 1
            perm = (0, x.ndim - 1, *range(1, x.ndim - 1))
            inv = (0, *range(2, x.ndim), 1)
            return self.norm(x.permute(perm)).permute(inv)
        return x


def knn(x: torch.Tensor, k: int) -> torch.Tensor:
    """Indices of the ``k`` nearest neighbours of every point (itself included).

    Parameters
    ----------
    x : (B, N, C) float
        Point features, channels last.
    k : int
        ``k <= N``.

    Returns
    -------
    (B, N, k) int64
        In no particular order.
    """
    sq = (x * x).sum(dim=-1)  # (B, N)
    neg_d2 = 2.0 * torch.matmul(x, x.transpose(1, 2)) - sq.unsqueeze(2) - sq.unsqueeze(1)
    return neg_d2.topk(k, dim=-1, sorted=False).indices


def _gather(x: torch.Tensor, idx: torch.Tensor) -> torch.Tensor:
    """Neighbour features: ``x (B, N, C)``, ``idx (B, N, k)`` -> ``(B, N, k, C)``."""
    b, n, c = x.shape
    k = idx.shape[-1]
    base = torch.arange(b, device=x.device).view(b, 1, 1) * n
    return x.reshape(b * n, c)[(idx + base).reshape(-1)].reshape(b, n, k, c)


class EdgeConv(nn.Module):
    """One EdgeConv layer: ``max_j LeakyReLU(Norm(W [x_j - x_i, x_i]))`` over the k-NN.

    The linear map of the edge feature is split as
    ``W [x_j - x_i, x_i] = A x_j + B x_i`` (``A = W_1``, ``B = W_2 - W_1``), so the per-point
    products are computed once and only the ``C_out`` outputs are gathered over the
    neighbours: the same function as DGCNN's, ``k`` times fewer multiplications.

    Parameters
    ----------
    in_channels, out_channels : int
    k : int
    norm : {"batch", "group", "none"}

    Shapes:
        - input ``x``: ``(B, N, C_in)``; optional ``idx``: ``(B, N, k)`` neighbour indices
          (default: k-NN of ``x`` itself).
        - output: ``(B, N, C_out)``.
    """

    def __init__(self, in_channels: int, out_channels: int, k: int, norm: str = "batch") -> None:
        super().__init__()
        self.k = k
        self.out_channels = out_channels
        self.proj = nn.Linear(in_channels, 2 * out_channels, bias=norm == "none")
        self.norm = _ChannelNorm(norm, out_channels)
        self.act = nn.LeakyReLU(0.2)

    def forward(self, x: torch.Tensor, idx: torch.Tensor | None = None) -> torch.Tensor:
        if idx is None:
            idx = knn(x, min(self.k, x.shape[1]))
        a, b = self.proj(x).split(self.out_channels, dim=-1)  # A x, B x: (B, N, C_out)
        y = _gather(a, idx) + b.unsqueeze(2)  # (B, N, k, C_out)
        return self.act(self.norm(y)).max(dim=2).values


class DGCNNEncoder(nn.Module):
    """DGCNN global-feature encoder of a 4-channel point cloud.

    Parameters
    ----------
    widths : sequence of int
        EdgeConv output channels.
    emb_dim : int
        Per-point embedding width; output width ``2 * emb_dim``.
    k : int
        Neighbours.
    norm : {"batch", "group", "none"}
    dynamic : bool
        Recompute the k-NN graph in feature space for every layer after the first.

    Shapes:
        - input ``points``: ``(B, N, 4)`` float32 (``x, y, z``, moving flag).
        - output: ``(B, 2 * emb_dim)`` float32 (max-pooled and mean-pooled embeddings).
    """

    def __init__(
        self, widths: Sequence[int], emb_dim: int, k: int = 20, norm: str = "batch",
        dynamic: bool = True,
    ) -> None:
        super().__init__()
        self.k = k
        self.dynamic = dynamic
        self.convs = nn.ModuleList()
        c = IN_CHANNELS
        for w in widths:
            self.convs.append(EdgeConv(c, w, k, norm))
            c = w
        self.lift = nn.Sequential(
            nn.Linear(sum(widths), emb_dim, bias=norm == "none"),
            _ChannelNorm(norm, emb_dim),
            nn.LeakyReLU(0.2),
        )
        self.out_dim = 2 * emb_dim

    def forward(self, points: torch.Tensor) -> torch.Tensor:
        if points.ndim != 3 or points.shape[-1] != IN_CHANNELS:
            raise ValueError(f"points must be (B, N, {IN_CHANNELS}), got {tuple(points.shape)}")
        x = points
        idx = knn(x[..., :3].contiguous(), min(self.k, x.shape[1]))  # graph of the coordinates
        feats = []
        for i, conv in enumerate(self.convs):
            x = conv(x, idx if (i == 0 or not self.dynamic) else None)
            feats.append(x)
        h = self.lift(torch.cat(feats, dim=-1))  # (B, N, emb)
        return torch.cat([h.max(dim=1).values, h.mean(dim=1)], dim=1)


class AxisSelectionNet(nn.Module):
    """Siamese DGCNN scoring the feasibility of a candidate motion (Liu et al. 2023, Sec. 3.3).

    Parameters
    ----------
    config : AxisNetConfig, optional

    Shapes:
        - input ``before``: ``(B, N, 4)`` or ``(N, 4)`` float32, the rest state (a single
          cloud is shared by all ``B`` motions and encoded once).
        - input ``after``: ``(B, N, 4)`` float32, the state after each candidate motion.
        - output: ``(B,)`` float32 logits; ``sigmoid`` gives the feasibility in ``[0, 1]``.
    """

    def __init__(self, config: AxisNetConfig | None = None) -> None:
        super().__init__()
        self.config = config or AxisNetConfig()
        cfg = self.config
        self.encoder = DGCNNEncoder(cfg.widths, cfg.emb_dim, cfg.k, cfg.norm, cfg.dynamic)
        layers: list[nn.Module] = []
        d = 2 * self.encoder.out_dim
        for w in cfg.head:
            layers += [nn.Linear(d, w, bias=cfg.norm == "none"), _ChannelNorm(cfg.norm, w),
                       nn.LeakyReLU(0.2), nn.Dropout(cfg.dropout)]
            d = w
        layers.append(nn.Linear(d, 1))
        self.classifier = nn.Sequential(*layers)

    def encode(self, points: torch.Tensor) -> torch.Tensor:
        """Global features ``(B, 2 * emb_dim)`` of clouds ``(B, N, 4)``."""
        return self.encoder(points)

    def head(self, feat_before: torch.Tensor, feat_after: torch.Tensor) -> torch.Tensor:
        """Logits ``(B,)`` from the features of both states (``feat_before`` broadcasts)."""
        if feat_before.shape[0] == 1 and feat_after.shape[0] != 1:
            feat_before = feat_before.expand(feat_after.shape[0], -1)
        return self.classifier(torch.cat([feat_before, feat_after], dim=1)).squeeze(1)

    def forward(self, before: torch.Tensor, after: torch.Tensor) -> torch.Tensor:
        if before.ndim == 2:
            before = before.unsqueeze(0)
        if after.ndim != 3 or before.ndim != 3:
            raise ValueError(
                f"before / after must be (B, N, 4), got {tuple(before.shape)}, {tuple(after.shape)}"
            )
        if before.shape[0] not in (1, after.shape[0]):
            raise ValueError(
                f"before has batch {before.shape[0]}, after {after.shape[0]} (expected equal or 1)"
            )
        return self.head(self.encode(before), self.encode(after))

    @torch.no_grad()
    def feasibility(
        self, before: torch.Tensor, after: torch.Tensor, chunk: int = 16
    ) -> torch.Tensor:
        """Feasibility ``sigmoid(logit)`` of ``M`` motions of one rest state, in eval mode.

        Parameters
        ----------
        before : (N, 4) float32
        after : (M, N, 4) float32
        chunk : int
            Moved clouds encoded at a time (bounds memory: ``chunk * N * k * C`` floats).

        Returns
        -------
        (M,) float32 in ``[0, 1]``.
        """
        was_training = self.training
        self.eval()
        try:
            fb = self.encode(before.reshape(1, *before.shape[-2:]))
            out = [self.head(fb, self.encode(a)) for a in after.split(max(chunk, 1))]
            return torch.sigmoid(torch.cat(out)) if out else after.new_zeros(0)
        finally:
            self.train(was_training)

    def feasibility_batch(
        self, before: torch.Tensor, after: torch.Tensor, owner: torch.Tensor, chunk: int = 256
    ) -> torch.Tensor:
        """Feasibility of ``M`` motions of ``R`` rest states in as few encoder calls as memory allows.

        Every rest state is encoded once (one call for all ``R``), the moved clouds in chunks
        of ``chunk``; the classifier runs once on all ``M`` pairs. Eval mode and
        ``torch.inference_mode``; the same values as :meth:`feasibility` per rest state (up
        to float rounding of batched matrix products).

        Parameters
        ----------
        before : (R, N, 4) float32
        after : (M, N, 4) float32
        owner : (M,) int64
            Rest state of each motion, in ``[0, R)``.
        chunk : int
            Moved clouds encoded per call (memory ``~ chunk * N * (N + k * C)`` floats).

        Returns
        -------
        (M,) float32 in ``[0, 1]``.
        """
        if after.shape[0] == 0:
            return after.new_zeros(0)
        was_training = self.training
        self.eval()
        try:
            with torch.inference_mode():
                fb = self.encode(before)
                fa = torch.cat([self.encode(a) for a in after.split(max(chunk, 1))])
                return torch.sigmoid(self.head(fb[owner], fa))
        finally:
            self.train(was_training)
