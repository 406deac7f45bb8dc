"""Scatter reductions over index groups (the message aggregation of the graph networks).

Pure torch (no ``torch_scatter``), deterministic on CPU, differentiable.
"""

from __future__ import annotations

import torch

__all__ = ["scatter_max", "scatter_mean", "scatter_sum"]


def _check(src: torch.Tensor, index: torch.Tensor) -> None:
    if src.ndim != 2 or index.ndim != 1 or index.shape[0] != src.shape[0]:
        raise ValueError(
            f"expected src (N, C) and index (N,), got {tuple(src.shape)} and {tuple(index.shape)}"
        )


def scatter_sum(src: torch.Tensor, index: torch.Tensor, size: int) -> torch.Tensor:
    """Row sums per group: ``out[g] = sum_{n: index[n] = g} src[n]``.

    Parameters
    ----------
    src : (N, C) float
    index : (N,) int64
        Group of each row, in ``[0, size)``.
    size : int
        Number of groups ``G``.

    Returns
    -------
    (G, C) float
        Zeros for empty groups.
    """
    _check(src, index)
    return src.new_zeros(size, src.shape[1]).index_add(0, index, src)


def scatter_mean(src: torch.Tensor, index: torch.Tensor, size: int) -> torch.Tensor:
    """Row means per group, ``(G, C)``; zeros for empty groups (see :func:`scatter_sum`)."""
    s = scatter_sum(src, index, size)
    cnt = torch.zeros(size, dtype=src.dtype, device=src.device).index_add(
        0, index, torch.ones_like(index, dtype=src.dtype)
    )
    return s / cnt.clamp(min=1.0)[:, None]


def scatter_max(src: torch.Tensor, index: torch.Tensor, size: int) -> torch.Tensor:
    """Element-wise row maxima per group, ``(G, C)``; zeros for empty groups.

    Gradients flow to the maximal rows (split evenly between ties).
    """
    _check(src, index)
    out = src.new_zeros(size, src.shape[1])
    if src.shape[0] == 0:
        return out
    idx = index[:, None].expand_as(src)
    return out.scatter_reduce(0, idx, src, reduce="amax", include_self=False)
