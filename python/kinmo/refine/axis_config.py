"""Configuration of the axis-selection network's training: :class:`AxisTrainConfig` and presets.

Used by :mod:`kinmo.refine.train` (the loop, which re-exports these names) and
:mod:`kinmo.refine.axis_data` (the triples). Every value is saved with a run
(``config.json``), so a run can be reproduced from its folder.
"""

from __future__ import annotations

from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field

from kinmo.refine.axis_net import AxisNetConfig
from kinmo.refine.motions import MotionAmounts
from kinmo.train.loop import preset_values

__all__ = ["PRESETS", "AxisTrainConfig", "preset_config"]


class AxisTrainConfig(BaseModel):
    """Everything that defines an axis-network training run (saved as ``config.json``).

    Attributes
    ----------
    preset : {"quick", "paper", "tiny", "custom"}
        Origin of the values (:data:`PRESETS`).
    seed : int
    net : AxisNetConfig
    epochs, batch_size : int
        ``batch_size`` triples (rest, positive, negative) per step.
    lr, weight_decay : float
        Adam (paper code: 3e-4, 1e-4), step decay ``lr_gamma`` every ``lr_step`` epochs.
    lr_step : int
    lr_gamma : float
    samples_per_shape : int
        Moving edges drawn per shape and epoch.
    amount_range : (float, float)
        Fractions of the joint range of positive / negative amounts.
    max_angle_deg : float
        Cap of a hinge's span on one side (degrees).
    flip_prob : float
        Probability of a reversed-direction negative when the limits forbid that direction.
    mirror_prob : float
        Probability of mirroring a training triple left-right (``x -> -x`` in the pair frame,
        which keeps +y up and the front facing the same way): a left-hinged door becomes a
        right-hinged one, with the same feasibility.
    hard_negative_prob : float
        Probability that a (non-reversed) negative comes from the candidates of the edge's own
        fine type (the choices the refinement faces) rather than from all candidates of its
        motion.
    articulated_prob : float
        Probability that a triple's rest ("before") cloud is itself articulated
        (:mod:`kinmo.refine.axis_data`; the paper's code: 0.5).
    articulated_range : (float, float)
        Share of the positive motion already done in an articulated rest state.
    match_angle_deg, match_distance : float
        Equivalence of a candidate line to the true axis (degrees; fraction of the moving
        part's OBB diagonal).
    test_fraction : float
        Share of each category held out as the motion GNN's test set when no split is given
        (as :func:`kinmo.train.split.make_split`; must match the GNN run's).
    val_fraction : float
        Share of each category's remaining shapes that validate the axis network.
    val_repeats : int
        Validation triples per validation edge (fixed seed).
    val_every : int
        Validate (loss and selection accuracy) every this many epochs and at the last; only
        validated epochs can be saved as ``model.pt``.
    val_edges_per_shape : int
        Validation edges per validation shape (a fixed random subset; 0: all). The selection
        accuracy weighs shapes equally anyway, and it costs a network call per candidate
        motion.
    interaction_radius : float
        Passed to :func:`~kinmo.refine.candidates.candidate_axes`.
    amounts : MotionAmounts fields
        ``angles_deg`` and ``translation_fraction`` of inference motions (selection metric;
        the paper's code averages ``±30/45/60/80°``).
    sign_mode : {"mean", "max"}
        Line score of the selection metric: the mean over both directions (the paper's code)
        or the better direction (kinmo's refinement so far).
    category_min_objects : int
        Per-category networks (0: off): a category with at least this many training objects
        *and* at least one validation object gets a copy of the global network fine-tuned on
        its own training edges for ``category_epochs`` epochs (learning rate
        ``lr * category_lr_scale``); the best epoch by the category's validation selection
        accuracy is kept only if it beats the global network's on the same edges (strictly),
        else the category falls back to the global network.
    category_epochs : int
    category_lr_scale : float
    threads : int
        torch CPU threads (0: leave torch's default).
    device : str
        ``"cpu"``, ``"cuda"`` or ``"auto"``.
    """

    model_config = ConfigDict(extra="forbid")

    preset: Literal["quick", "paper", "tiny", "custom"] = "custom"
    seed: int = 0
    net: AxisNetConfig = Field(default_factory=AxisNetConfig)
    epochs: int = Field(30, ge=1)
    batch_size: int = Field(8, ge=1)
    lr: float = Field(3e-4, gt=0)
    weight_decay: float = Field(1e-4, ge=0)
    lr_step: int = Field(20, ge=1)
    lr_gamma: float = Field(0.7, gt=0, le=1)
    samples_per_shape: int = Field(4, ge=1)
    amount_range: tuple[float, float] = (0.3, 0.9)
    max_angle_deg: float = Field(180.0, gt=0)
    flip_prob: float = Field(0.25, ge=0, le=1)
    hard_negative_prob: float = Field(0.5, ge=0, le=1)
    articulated_prob: float = Field(0.0, ge=0, le=1)
    articulated_range: tuple[float, float] = (0.2, 0.8)
    mirror_prob: float = Field(0.5, ge=0, le=1)
    match_angle_deg: float = Field(10.0, gt=0)
    match_distance: float = Field(0.1, gt=0)
    test_fraction: float = Field(0.25, ge=0, lt=1)
    val_fraction: float = Field(0.2, ge=0, lt=1)
    val_repeats: int = Field(2, ge=1)
    val_every: int = Field(1, ge=1)
    val_edges_per_shape: int = Field(0, ge=0)
    interaction_radius: float = Field(0.1, gt=0)
    angles_deg: tuple[float, ...] = (60.0,)
    translation_fraction: float = Field(0.5, gt=0)
    sign_mode: Literal["mean", "max"] = "max"
    category_min_objects: int = Field(0, ge=0)
    category_epochs: int = Field(4, ge=1)
    category_lr_scale: float = Field(0.3, gt=0)
    threads: int = Field(0, ge=0)
    device: str = "auto"

    @property
    def amounts(self) -> MotionAmounts:
        """The inference motion amounts."""
        return MotionAmounts(tuple(self.angles_deg), self.translation_fraction)


#: Named configurations. ``quick``: a small network that trains on a CPU in minutes; its
#: moving/reference-pair input was chosen over the whole-shape input by validation selection
#: accuracy (docs/results/table1_four_settings.md, "Axis-selection network").
#: ``paper``: the paper code's network and optimiser (DGCNN 64-64-128, 4096 points, k = 20,
#: 128-d embedding, Adam 3e-4 / 1e-4, step decay 0.7 every 20 epochs), meant for a GPU.
PRESETS: dict[str, dict[str, Any]] = {
    "quick": {
        "net": {"n_points": 256, "k": 16, "widths": [32, 32, 64], "emb_dim": 64,
                "head": [64, 32], "dropout": 0.3, "norm": "batch"},
        "epochs": 24, "batch_size": 16, "lr": 1e-3, "lr_step": 10, "samples_per_shape": 4,
        "articulated_prob": 0.5, "angles_deg": (30.0, 45.0, 60.0, 80.0), "sign_mode": "mean",
        "val_every": 3, "val_edges_per_shape": 4,
        "category_min_objects": 5, "category_epochs": 6,
        "threads": 1,  # as the other quick presets: the same weights on any machine
    },
    "paper": {
        "net": {"n_points": 4096, "k": 20, "widths": [64, 64, 128], "emb_dim": 128,
                "head": [256, 128], "dropout": 0.5, "norm": "batch", "input": "shape"},
        "epochs": 200, "batch_size": 8, "lr": 3e-4, "lr_step": 20, "samples_per_shape": 8,
        "articulated_prob": 0.5, "angles_deg": (30.0, 45.0, 60.0, 80.0), "sign_mode": "mean",
        "category_min_objects": 5, "category_epochs": 50,
    },
}
#: ``tiny``: ``quick`` for 2 epochs, a check that a run goes through in seconds, not results.
PRESETS["tiny"] = {**PRESETS["quick"], "epochs": 2}


def preset_config(preset: str = "quick", **overrides: Any) -> AxisTrainConfig:
    """An :class:`AxisTrainConfig` from a preset of :data:`PRESETS` with ``overrides``.

    Raises
    ------
    ValueError
        Unknown preset or invalid values.
    """

    values = preset_values(PRESETS, preset)
    net = dict(values.pop("net"))
    net.update(overrides.pop("net", {}) or {})
    values.update(overrides)
    return AxisTrainConfig(preset=preset, net=AxisNetConfig(**net), **values)
