"""ANCSH: Articulation-aware Normalized Coordinate Space Hierarchy (Li et al. CVPR 2020).

Per point of a single-view partial point cloud, the network predicts: the part segmentation,
the NPCS coordinates of the point in its part's normalised space, the NAOCS coordinates in
the object's normalised articulated space, and for joint parameters a joint-association
heatmap, unit vectors pointing to the joint axis, the axis orientation, and which joint the
point is associated with (Sec. 4.2). Losses follow Sec. 4.2 / the reference implementation:
cross-entropy for segmentation and joint association, L2 for the regressions.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import torch
import torch.nn.functional as F
from torch import nn

from kinmo.ancsh.plan import GeometryPlan
from kinmo.ancsh.pointnet2 import PointNet2Backbone, pointwise


@dataclass
class ANCSHLossWeights:
    """Weights of the ANCSH loss terms (the reference implementation weights them equally
    except the NPCS/NAOCS terms)."""

    seg: float = 1.0
    npcs: float = 10.0
    naocs: float = 10.0
    heatmap: float = 1.0
    unitvec: float = 1.0
    axis: float = 1.0
    joint_cls: float = 1.0


class ANCSH(nn.Module):
    """The ANCSH network: a PointNet++ backbone and per-point heads.

    Parameters
    ----------
    n_parts : int
        K rigid parts of the category's kinematic structure (part 0 is the base).
    n_joints : int
        J joints (joint j connects part j+1 to its parent).
    width : int
        Backbone base width.
    n_centers, radii : see :class:`~kinmo.ancsh.pointnet2.PointNet2Backbone`.

    Shapes:
        xyz (B, N, 3), centred and scaled to about unit size, and optionally its
        :class:`~kinmo.ancsh.plan.GeometryPlan` (``model.backbone.plan(xyz)``; built by
        the backbone when not given) ->
        ``seg_logits`` (B, N, K), ``npcs`` (B, N, K, 3) (one NPCS per part hypothesis, in
        [0, 1]), ``naocs`` (B, N, 3), ``heatmap`` (B, N) in [0, 1], ``unitvec`` (B, N, 3),
        ``axis`` (B, N, 3) unit, ``joint_logits`` (B, N, J + 1) (class 0: no joint).
    """

    def __init__(
        self,
        n_parts: int,
        n_joints: int,
        width: int = 64,
        n_centers: tuple[int, int, int] = (512, 128, 32),
        radii: tuple[float, float, float] = (0.1, 0.2, 0.4),
    ) -> None:
        super().__init__()
        if n_parts < 2 or n_joints < 1:
            raise ValueError(f"ANCSH needs >= 2 parts and >= 1 joint, got {n_parts} parts, {n_joints} joints")
        self.n_parts, self.n_joints = n_parts, n_joints
        self.backbone = PointNet2Backbone(width, n_centers, radii)
        c = self.backbone.out_channels

        def head(out: int) -> nn.Sequential:
            return nn.Sequential(nn.Conv1d(c, c, 1), nn.BatchNorm1d(c), nn.ReLU(inplace=True), nn.Conv1d(c, out, 1))

        self.seg_head = head(n_parts)
        self.npcs_head = head(3 * n_parts)
        self.naocs_head = head(3)
        self.heatmap_head = head(1)
        self.unitvec_head = head(3)
        self.axis_head = head(3)
        self.joint_head = head(n_joints + 1)

    def forward(self, xyz: torch.Tensor, plan: GeometryPlan | None = None) -> dict[str, torch.Tensor]:
        f = self.backbone(xyz, plan)  # (B, N, C), channels-last
        # the 1x1 convolutions as matrix products
        return self._outputs(lambda layers: pointwise(layers, f), *f.shape[:2])

    def forward_reference(self, xyz: torch.Tensor) -> dict[str, torch.Tensor]:
        """The computation before geometry plans (``PointNet2Backbone.forward_reference``,
        channels-first heads): the reference of tests and ``bench/bench_ancsh.py``; same
        parameters and outputs as :meth:`forward` up to float rounding and the plan's rule."""
        f = self.backbone.forward_reference(xyz).transpose(1, 2)  # (B, C, N)
        return self._outputs(lambda layers: layers(f).transpose(1, 2), f.shape[0], f.shape[2])

    def _outputs(self, head: Callable[[nn.Sequential], torch.Tensor], b: int, n: int
                 ) -> dict[str, torch.Tensor]:
        """The outputs, with ``head(layers)`` giving one head's raw ``(B, N, C_out)``."""
        return {
            "seg_logits": head(self.seg_head),
            "npcs": torch.sigmoid(head(self.npcs_head)).reshape(b, n, self.n_parts, 3),
            "naocs": torch.sigmoid(head(self.naocs_head)),
            "heatmap": torch.sigmoid(head(self.heatmap_head)).squeeze(-1),
            "unitvec": F.normalize(head(self.unitvec_head), dim=-1),
            "axis": F.normalize(head(self.axis_head), dim=-1),
            "joint_logits": head(self.joint_head),
        }


def ancsh_loss(
    pred: dict[str, torch.Tensor], target: dict[str, torch.Tensor], weights: ANCSHLossWeights | None = None
) -> dict[str, torch.Tensor]:
    """ANCSH training loss (Li et al. 2020, Sec. 4.2).

    Parameters
    ----------
    pred : dict
        Output of :class:`ANCSH`.
    target : dict
        ``seg`` (B, N) int64 part labels; ``npcs`` (B, N, 3) NPCS of each point in its own
        part; ``naocs`` (B, N, 3); ``heatmap`` (B, N); ``unitvec`` (B, N, 3);
        ``axis`` (B, N, 3); ``joint`` (B, N) int64 (0: not associated with any joint);
        optional ``position_mask`` (B, N) bool: points whose heatmap and unit vector are
        supervised (those associated with a revolute joint; prismatic joints have no axis
        position). Defaults to ``joint > 0``.
    weights : ANCSHLossWeights, optional

    Returns
    -------
    dict of scalar tensors: each term and ``total``. The NPCS term uses the prediction of the
    true part; joint terms use only points associated with a joint.
    """
    w = weights or ANCSHLossWeights()
    seg = target["seg"]
    k = pred["seg_logits"].shape[-1]
    terms: dict[str, torch.Tensor] = {}
    terms["seg"] = F.cross_entropy(pred["seg_logits"].reshape(-1, k), seg.reshape(-1))
    npcs_own = torch.gather(pred["npcs"], 2, seg[..., None, None].expand(-1, -1, 1, 3)).squeeze(2)
    terms["npcs"] = (npcs_own - target["npcs"]).norm(dim=-1).mean()
    terms["naocs"] = (pred["naocs"] - target["naocs"]).norm(dim=-1).mean()
    assoc = (target["joint"] > 0).float()
    denom = assoc.sum().clamp_min(1.0)
    pos = target.get("position_mask")
    pos = assoc if pos is None else pos.float()
    pdenom = pos.sum().clamp_min(1.0)
    terms["heatmap"] = ((pred["heatmap"] - target["heatmap"]) ** 2 * pos).sum() / pdenom
    terms["unitvec"] = ((pred["unitvec"] - target["unitvec"]).norm(dim=-1) * pos).sum() / pdenom
    # axis orientation is a line direction: sign-invariant
    cos = (pred["axis"] * target["axis"]).sum(-1).abs()
    terms["axis"] = ((1.0 - cos) * assoc).sum() / denom
    j = pred["joint_logits"].shape[-1]
    terms["joint_cls"] = F.cross_entropy(pred["joint_logits"].reshape(-1, j), target["joint"].reshape(-1))
    total = sum(getattr(w, name) * value for name, value in terms.items())
    terms["total"] = total
    return terms
