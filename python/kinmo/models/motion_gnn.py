"""The motion GNN: part encoder + hierarchy encoder + edge GNN (Liu et al. 2023, Sec. 3.2).

Given a batch of part graphs (:class:`kinmo.features.GraphBatch`) it predicts, for every
directed sibling edge ``(i, j)``, the motion type of part ``i`` relative to part ``j``, the
unit axis direction and a point of the axis, in each shape's normalised frame
(:mod:`kinmo.features`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import torch
from pydantic import BaseModel, ConfigDict, Field
from torch import nn

from kinmo.data.model import COARSE_TYPES, FINE_TYPES
from kinmo.features import EDGE_DIM, NODE_DIM, GraphBatch
from kinmo.models.edge_gnn import EdgeGNN
from kinmo.models.hierarchy import HierarchyEncoder, mlp
from kinmo.models.point_encoder import make_point_encoder

__all__ = ["ModelConfig", "MotionGNN", "MotionGNNOutput"]


class ModelConfig(BaseModel):
    """Architecture of :class:`MotionGNN` (saved with every checkpoint).

    Attributes
    ----------
    types : {"fine", "coarse"}
        10 fine or 5 coarse motion types (:data:`~kinmo.data.model.FINE_TYPES`).
    point_encoder : {"pointnet", "dgcnn"}
    point_widths : list of int
        Hidden widths of the point encoder.
    geo_dim : int
        Part geometry feature width.
    node_dim : int
        Node feature width of the hierarchy encoder and edge GNN.
    edge_dim : int
        Edge feature width of the edge GNN.
    semantic_dim : int
        Width of the semantic-name embedding (0: do not use part names).
    vocab_size : int
        Number of semantic indices (set from the training vocabulary).
    hier_iterations : int
        Sibling message-passing rounds inside the hierarchy encoder.
    top_down : bool
        Top-down context pass of the hierarchy encoder.
    gnn_layers : int
        Message-passing rounds of the edge GNN.
    axis_frame : {"obb", "shape"}
        Frame of the axis outputs (:mod:`kinmo.models.edge_gnn`).
    axis_mode : {"candidates", "regress"}
        Choose the axis direction among candidates (default) or regress it
        (:mod:`kinmo.models.edge_gnn`).
    dgcnn_k : int
        Neighbours of DGCNN.
    """

    model_config = ConfigDict(extra="forbid")

    types: Literal["fine", "coarse"] = "fine"
    point_encoder: Literal["pointnet", "dgcnn"] = "pointnet"
    point_widths: list[int] = Field(default_factory=lambda: [64, 128])
    geo_dim: int = 128
    node_dim: int = 128
    edge_dim: int = 128
    semantic_dim: int = 32
    vocab_size: int = 1
    hier_iterations: int = 2
    top_down: bool = True
    gnn_layers: int = 3
    axis_frame: Literal["obb", "shape"] = "obb"
    axis_mode: Literal["candidates", "regress"] = "candidates"
    dgcnn_k: int = 20

    @property
    def type_names(self) -> tuple[str, ...]:
        """Names of the predicted types, in logit order."""
        return FINE_TYPES if self.types == "fine" else COARSE_TYPES


@dataclass
class MotionGNNOutput:
    """Per-edge predictions of a batch (normalised frames).

    Attributes
    ----------
    logits : (E, K) float32
        Type logits, ``K`` = 10 (fine) or 5 (coarse).
    direction : (E, 3) float32
        Unit axis directions.
    origin : (E, 3) float32
        Axis points.
    direction_free : (E, 3) float32 or None
        The regressed unit direction (equal to ``direction`` with ``axis_mode="regress"``).
    axis_logits : (E, 10) float32 or None
        Scores of the candidate directions (``axis_mode="candidates"``).
    axis_candidates : (E, 10, 3) float32 or None
        The candidate directions (:func:`kinmo.models.edge_gnn.axis_candidates`).
    """

    logits: torch.Tensor
    direction: torch.Tensor
    origin: torch.Tensor
    direction_free: torch.Tensor | None = None
    axis_logits: torch.Tensor | None = None
    axis_candidates: torch.Tensor | None = None


class MotionGNN(nn.Module):
    """Motion prediction network on pre-segmented part hierarchies.

    Parameters
    ----------
    config : ModelConfig

    Shapes:
        - input: a :class:`~kinmo.features.GraphBatch` with ``V`` nodes of ``P`` points and
          ``E`` sibling edges.
        - output: :class:`MotionGNNOutput` with ``logits (E, K)``, ``direction (E, 3)``,
          ``origin (E, 3)``.
    """

    def __init__(self, config: ModelConfig) -> None:
        super().__init__()
        self.config = config
        c = config
        self.point_encoder = make_point_encoder(c.point_encoder, c.point_widths, c.geo_dim,
                                                k=c.dgcnn_k)
        self.semantic = nn.Embedding(c.vocab_size, c.semantic_dim) if c.semantic_dim > 0 else None
        self.node_in = mlp([c.geo_dim + NODE_DIM + c.semantic_dim, c.node_dim, c.node_dim])
        self.edge_in = mlp([EDGE_DIM, c.edge_dim, c.edge_dim], final_act=True)
        self.hierarchy = HierarchyEncoder(c.node_dim, c.edge_dim, c.hier_iterations, c.top_down)
        self.edge_gnn = EdgeGNN(c.node_dim, EDGE_DIM, c.edge_dim, c.gnn_layers,
                                len(c.type_names), c.axis_frame, c.axis_mode)

    def forward(self, batch: GraphBatch) -> MotionGNNOutput:
        parts = [self.point_encoder(batch.points), batch.node_feat]
        if self.semantic is not None:
            sem = batch.semantic.clamp(0, self.semantic.num_embeddings - 1)
            parts.append(self.semantic(sem))
        x = self.node_in(torch.cat(parts, dim=1))
        ef = self.edge_in(batch.edge_feat)
        h = self.hierarchy(x, batch.parent, batch.depth, batch.edges, ef)
        o = self.edge_gnn(
            h, batch.edges, batch.edge_feat, batch.obb_center, batch.obb_axes, batch.obb_size
        )
        return MotionGNNOutput(o.logits, o.direction, o.origin, o.direction_free,
                               o.axis_logits, o.axis_candidates)
