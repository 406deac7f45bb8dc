"""Neural networks of kinmo's motion GNN (Liu et al. CVPR 2023, Sec. 3.2).

- :mod:`kinmo.models.point_encoder`: per-part point-cloud encoders (PointNet, DGCNN).
- :mod:`kinmo.models.hierarchy`: StructureNet-style bottom-up / top-down hierarchy encoder.
- :mod:`kinmo.models.edge_gnn`: edge-conditioned message passing over sibling edges and the
  per-edge heads (motion type, axis direction, axis position).
- :mod:`kinmo.models.motion_gnn`: the full model.
- :mod:`kinmo.models.losses`: the training loss (paper Eq. 1-4).

Importing this package imports torch.
"""

from kinmo.models.motion_gnn import MotionGNN, MotionGNNOutput, ModelConfig

__all__ = ["ModelConfig", "MotionGNN", "MotionGNNOutput"]
