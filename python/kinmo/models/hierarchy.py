"""StructureNet-style hierarchy encoder (Mo et al. 2019, Sec. 3.1; Liu et al. 2023, Sec. 3.2).

Each node starts from its own feature (part geometry + OBB + semantics). Features are then
propagated **bottom-up** through the parent-child tree, one depth level at a time from the
deepest: the children of a node exchange messages over their directed sibling edges
(edge-conditioned: ``m_ij = MLP([c_i, c_j, e_ij])``, averaged over each child's outgoing
edges), the children's features of every iteration are max-pooled (StructureNet's
"GIN-like" concatenation over iterations) and the result is combined with the node's own
feature. An optional **top-down** pass then gives every node its ancestors' context
(``t_v = t_v + MLP([t_v, t_parent])``, from the root down).

All graphs of a batch are processed together: one step per depth level, vectorised over all
nodes of that level.
"""

from __future__ import annotations

import torch
from torch import nn

from kinmo.models.scatter import scatter_max, scatter_mean

__all__ = ["HierarchyEncoder", "mlp"]


def mlp(dims: list[int], final_act: bool = False) -> nn.Sequential:
    """Fully connected network ``dims[0] -> ... -> dims[-1]`` with ReLU between layers."""
    layers: list[nn.Module] = []
    for k in range(len(dims) - 1):
        layers.append(nn.Linear(dims[k], dims[k + 1]))
        if k < len(dims) - 2 or final_act:
            layers.append(nn.ReLU())
    return nn.Sequential(*layers)


class HierarchyEncoder(nn.Module):
    """Bottom-up (and optionally top-down) encoder of a batch of part hierarchies.

    Parameters
    ----------
    dim : int
        Node feature width ``H`` (input and output).
    edge_dim : int
        Width of the sibling-edge features.
    iterations : int
        Rounds of message passing among the children of each node (StructureNet: 2).
    top_down : bool
        Run the top-down context pass.

    Shapes:
        - ``x``: ``(V, H)`` float32, each node's own feature.
        - ``parent``: ``(V,)`` int64, -1 for roots; ``depth``: ``(V,)`` int64.
        - ``edges``: ``(E, 2)`` int64 directed sibling edges; ``edge_feat``: ``(E, edge_dim)``.
        - output: ``(V, H)`` float32.
    """

    def __init__(self, dim: int, edge_dim: int, iterations: int = 2, top_down: bool = True) -> None:
        super().__init__()
        self.child_op = mlp([dim, dim], final_act=True)
        self.edge_ops = nn.ModuleList(
            [mlp([2 * dim + edge_dim, dim], final_act=True) for _ in range(iterations)]
        )
        self.parent_op = mlp([dim * (iterations + 1), dim], final_act=True)
        self.combine = mlp([2 * dim, dim, dim])
        self.top_down = mlp([2 * dim, dim, dim]) if top_down else None

    def forward(
        self,
        x: torch.Tensor,
        parent: torch.Tensor,
        depth: torch.Tensor,
        edges: torch.Tensor,
        edge_feat: torch.Tensor,
    ) -> torch.Tensor:
        v = x.shape[0]
        if v == 0:
            return x
        h = x
        max_depth = int(depth.max())
        edge_depth = depth[edges[:, 0]] if edges.numel() else depth.new_zeros(0)
        local = torch.full((v,), -1, dtype=torch.int64, device=x.device)
        for d in range(max_depth, 0, -1):
            kids = torch.nonzero(depth == d).flatten()
            par = parent[kids]
            local[kids] = torch.arange(kids.numel(), device=x.device)
            c = self.child_op(h[kids])
            em = edge_depth == d
            ei, ej = local[edges[em, 0]], local[edges[em, 1]]
            ef = edge_feat[em]
            pooled = [scatter_max(c, par, v)]
            for op in self.edge_ops:
                if ei.numel():
                    m = op(torch.cat([c[ei], c[ej], ef], dim=1))
                    c = c + scatter_mean(m, ei, kids.numel())
                pooled.append(scatter_max(c, par, v))
            parents = torch.unique(par)
            pf = self.parent_op(torch.cat(pooled, dim=1)[parents])
            h = h.index_copy(0, parents, h[parents] + self.combine(torch.cat([h[parents], pf], 1)))
        if self.top_down is None:
            return h
        t = h
        for d in range(1, max_depth + 1):
            kids = torch.nonzero(depth == d).flatten()
            upd = self.top_down(torch.cat([t[kids], t[parent[kids]]], dim=1))
            t = t.index_copy(0, kids, t[kids] + upd)
        return t
