"""Edge GNN over the directed sibling edges and the per-edge motion heads (Liu et al. 2023,
Sec. 3.2, "motion prediction network").

Message passing (edge-conditioned, as SWMP's graph-triple convolution):

- initial edge feature ``e_ij = MLP(g_ij)`` from the geometric edge features ``g_ij``
  (:func:`kinmo.features.edge_features`);
- each round: ``m_ij = MLP([h_i, h_j, e_ij])``, ``e_ij <- e_ij + m_ij``, and every node is
  updated from the mean of its outgoing and of its incoming messages,
  ``h_i <- h_i + MLP([h_i, mean_j m_ij, mean_j m_ji])``.

Heads on ``z_ij = [h_i, h_j, e_ij]`` (edge ``(i, j)``: part ``i`` moves relative to ``j``):

- **type**: logits over the 10 fine or 5 coarse motion types;
- **axis direction**, regressed: a 3-vector normalised to unit length. With
  ``axis_frame="obb"`` it is predicted in the moving part's OBB frame
  (``d = normalise(sum_k r_k a_k)`` with ``a_k`` the OBB axes of part ``i``); with ``"shape"``
  directly in the normalised shape frame;
- **axis direction**, selected (``axis_mode="candidates"``, the default): man-made objects
  move along their parts' edges and the object's own axes. Of the 611 joints of the shared
  PartNet-Mobility objects, 99.8% lie within 1° of one of 9 **candidate directions**: the
  three OBB axes of the moving part, the three of the reference part, and the shape frame's
  ``x``, ``y``, ``z``. The head scores these 9 candidates plus the regressed direction (a
  10th, "free" candidate for the rest) and the predicted direction is the best-scoring one,
  exact when the right candidate is chosen. The loss
  (:class:`kinmo.models.losses.MotionLoss`) trains the choice by cross-entropy and the
  regressed direction by the paper's ``1 - |cos|``;
- **axis position**: a point of the axis, predicted as an offset from part ``i``'s OBB centre.
  With ``axis_frame="obb"`` the offset is ``sum_k r_k (s_k / 2 + 0.02) a_k`` (``s_k`` the OBB
  side lengths), i.e. measured in half-extents of the part; with ``"shape"`` it is ``r``.
  Normalised-frame units in both cases.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import torch
import torch.nn.functional as F
from torch import nn

from kinmo.models.hierarchy import mlp
from kinmo.models.scatter import scatter_mean

__all__ = ["N_CANDIDATES", "OFFSET_FLOOR", "EdgeGNN", "EdgeHeads", "axis_candidates"]

#: Added to the half-extents that scale OBB-frame offsets (flat parts have zero extent).
OFFSET_FLOOR = 0.02
#: Candidate axis directions of ``axis_mode="candidates"``, the regressed one included.
N_CANDIDATES = 10
#: Edges per chunk of the heads at inference (no autograd): the candidate head's input is
#: ``(chunk, 10, 2H + D + 10)`` float32, about 130 MB at 8192 edges and H = D = 128.
EDGE_CHUNK = 8192


def axis_candidates(axes_i: torch.Tensor, axes_j: torch.Tensor, free: torch.Tensor) -> torch.Tensor:
    """The candidate axis directions of edges ``(i, j)``, ``(E, 10, 3)``.

    Parameters
    ----------
    axes_i, axes_j : (E, 3, 3) float
        OBB axes (rows) of the moving and of the reference part.
    free : (E, 3) float
        The regressed unit direction.

    Returns
    -------
    (E, 10, 3) float
        ``[a_i1, a_i2, a_i3, a_j1, a_j2, a_j3, x, y, z, free]``.
    """
    e = free.shape[0]
    eye = torch.eye(3, dtype=free.dtype, device=free.device).expand(e, 3, 3)
    return torch.cat([axes_i, axes_j, eye, free[:, None, :]], dim=1)


@dataclass
class EdgeHeads:
    """Raw outputs of :class:`EdgeGNN` for ``E`` edges.

    Attributes
    ----------
    logits : (E, K) float
        Motion type logits.
    direction : (E, 3) float
        Predicted unit axis direction (the selected candidate, or the regressed one).
    origin : (E, 3) float
        Predicted axis point.
    direction_free : (E, 3) float
        The regressed unit direction.
    axis_logits : (E, 10) float or None
        Candidate scores (``axis_mode="candidates"``).
    axis_candidates : (E, 10, 3) float or None
    """

    logits: torch.Tensor
    direction: torch.Tensor
    origin: torch.Tensor
    direction_free: torch.Tensor
    axis_logits: torch.Tensor | None = None
    axis_candidates: torch.Tensor | None = None


class EdgeGNN(nn.Module):
    """Edge-conditioned message passing and per-edge heads.

    Parameters
    ----------
    node_dim : int
        Node feature width ``H``.
    edge_in : int
        Width of the geometric edge features.
    edge_dim : int
        Hidden edge feature width.
    layers : int
        Message-passing rounds.
    n_types : int
        10 (fine) or 5 (coarse).
    axis_frame : {"obb", "shape"}
        Frame of the raw direction and offset outputs (module docstring).
    axis_mode : {"candidates", "regress"}
        Select the direction among candidates, or use the regressed one.

    Shapes:
        - ``h``: ``(V, H)`` float32 node features.
        - ``edges``: ``(E, 2)`` int64; ``edge_feat``: ``(E, edge_in)`` float32.
        - ``obb_center``: ``(V, 3)``; ``obb_axes``: ``(V, 3, 3)`` rows; ``obb_size``: ``(V, 3)``.
        - output: :class:`EdgeHeads` with ``logits (E, n_types)``, ``direction (E, 3)`` unit,
          ``origin (E, 3)`` (normalised frame), ``axis_logits (E, 10)``.
    """

    def __init__(self, node_dim: int, edge_in: int, edge_dim: int, layers: int, n_types: int,
                 axis_frame: str = "obb", axis_mode: str = "candidates") -> None:
        super().__init__()
        if axis_frame not in ("obb", "shape"):
            raise ValueError(f"axis_frame must be 'obb' or 'shape', got {axis_frame!r}")
        if axis_mode not in ("candidates", "regress"):
            raise ValueError(f"axis_mode must be 'candidates' or 'regress', got {axis_mode!r}")
        self.axis_frame = axis_frame
        self.axis_mode = axis_mode
        self.edge_init = mlp([edge_in, edge_dim, edge_dim])
        self.msg = nn.ModuleList(
            [mlp([2 * node_dim + edge_dim, edge_dim, edge_dim]) for _ in range(layers)]
        )
        self.upd = nn.ModuleList(
            [mlp([node_dim + 2 * edge_dim, node_dim, node_dim]) for _ in range(layers)]
        )
        z = 2 * node_dim + edge_dim
        self.type_head = mlp([z, edge_dim, n_types])
        self.axis_head = mlp([z, edge_dim, 6])
        # candidate scores see the candidates themselves (in the shape frame and relative to
        # the two parts' box axes), so the choice can depend on geometry, not only on slots
        self.cand_head = (
            mlp([z + 10, edge_dim, 1]) if axis_mode == "candidates" else None
        )

    def forward(
        self,
        h: torch.Tensor,
        edges: torch.Tensor,
        edge_feat: torch.Tensor,
        obb_center: torch.Tensor,
        obb_axes: torch.Tensor,
        obb_size: torch.Tensor,
    ) -> EdgeHeads:
        v = h.shape[0]
        i, j = edges[:, 0], edges[:, 1]
        e = self.edge_init(edge_feat)
        for msg, upd in zip(self.msg, self.upd):
            m = msg(torch.cat([h[i], h[j], e], dim=1))
            e = e + m
            out_m = scatter_mean(m, i, v)
            in_m = scatter_mean(m, j, v)
            h = h + upd(torch.cat([h, out_m, in_m], dim=1))
        n_e = i.shape[0]
        if torch.is_grad_enabled() or n_e <= EDGE_CHUNK:
            return self._heads(h, e, i, j, obb_center, obb_axes, obb_size)
        # inference on a graph with many sibling edges (a flat 500-part asset has 249,500):
        # the heads one chunk of edges at a time, the same numbers in bounded memory
        parts = [self._heads(h, e[k:k + EDGE_CHUNK], i[k:k + EDGE_CHUNK], j[k:k + EDGE_CHUNK],
                             obb_center, obb_axes, obb_size) for k in range(0, n_e, EDGE_CHUNK)]
        return EdgeHeads(*(None if getattr(parts[0], f.name) is None
                           else torch.cat([getattr(p, f.name) for p in parts])
                           for f in dataclasses.fields(EdgeHeads)))

    def _heads(self, h: torch.Tensor, e: torch.Tensor, i: torch.Tensor, j: torch.Tensor,
               obb_center: torch.Tensor, obb_axes: torch.Tensor, obb_size: torch.Tensor) -> EdgeHeads:
        """The per-edge heads of edges ``(i, j)`` with hidden features ``e`` (``forward``)."""
        z = torch.cat([h[i], h[j], e], dim=1)
        logits = self.type_head(z)
        raw = self.axis_head(z)
        rd, ro = raw[:, :3], raw[:, 3:6]
        if self.axis_frame == "obb":
            a = obb_axes[i]  # (E, 3, 3) rows
            d = torch.einsum("ek,ekc->ec", rd, a)
            off = torch.einsum("ek,ekc->ec", ro * (obb_size[i] / 2 + OFFSET_FLOOR), a)
        else:
            d, off = rd, ro
        free = F.normalize(d, dim=1, eps=1e-8)
        origin = obb_center[i] + off
        if self.cand_head is None:
            return EdgeHeads(logits, free, origin, free)
        cand = axis_candidates(obb_axes[i], obb_axes[j], free)  # (E, 10, 3)
        n_e = cand.shape[0]
        # descriptors: the candidate (sign-canonical: |.|), |cos| with both parts' axes, and
        # a flag for the regressed one
        rel_i = torch.einsum("enc,ekc->enk", cand, obb_axes[i]).abs()
        rel_j = torch.einsum("enc,ekc->enk", cand, obb_axes[j]).abs()
        is_free = torch.zeros(n_e, N_CANDIDATES, 1, dtype=cand.dtype, device=cand.device)
        is_free[:, -1] = 1.0
        desc = torch.cat([cand.abs(), rel_i, rel_j, is_free], dim=2)  # (E, 10, 10)
        zz = torch.cat([z[:, None, :].expand(n_e, N_CANDIDATES, z.shape[1]), desc], dim=2)
        axis_logits = self.cand_head(zz).squeeze(-1)  # (E, 10)
        best = axis_logits.argmax(dim=1)
        direction = cand[torch.arange(n_e, device=cand.device), best]
        return EdgeHeads(logits, direction, origin, free, axis_logits, cand)
