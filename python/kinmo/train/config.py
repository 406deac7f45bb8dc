"""Training configuration of the motion GNN and its presets.

Three presets (:data:`PRESETS`; ``tiny`` is ``quick`` for 25 epochs, a check that a run goes
through, as ``KINMO_PRESET=tiny``):

- ``quick``: CPU-sized. PointNet part encoder over 256 of each part's 1024 points, widths 64,
  2 hierarchy and 3 edge-GNN rounds, 60 epochs of batches of 8 shapes, Adam at 2e-3 with a
  cosine schedule, one torch thread (the matrices are small: more threads mostly add
  synchronisation, and oversubscribe shared machines). Trains on the ~75 training objects of
  the shared PartNet-Mobility set in a few minutes on a CPU.
- ``paper``: the sizes of the paper's code (SWMP ``GnnMotion``: DGCNN part encoder with a
  100-wide geometry feature, 256-wide node and semantic features, 2 StructureNet message
  passing iterations, 5 graph-convolution layers; Adam at 1e-4 with weight decay 1e-4, step
  decay x0.7 every 20 epochs, 400 epochs, batches of 2), meant for a GPU.

Every run is seeded (``seed``) and the full configuration is written next to the checkpoint
(``config.json``), so a run can be reproduced from its folder.
"""

from __future__ import annotations

from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field

from kinmo.models.motion_gnn import ModelConfig
from kinmo.train.loop import override, preset_values, resolve_device

__all__ = ["PRESETS", "TrainConfig", "preset", "resolve_device"]


class TrainConfig(BaseModel):
    """Everything a ``kinmo train gnn`` run depends on.

    Attributes
    ----------
    preset : str
        Name of the preset the configuration started from.
    model : ModelConfig
        Architecture (its ``types`` selects fine or coarse motion types).
    epochs : int
    batch_size : int
        Shapes per optimisation step.
    lr : float
        Adam learning rate.
    weight_decay : float
    schedule : {"cosine", "step", "constant"}
        Learning-rate schedule over the epochs.
    step_size, step_gamma : int, float
        Step schedule: multiply the rate by ``step_gamma`` every ``step_size`` epochs.
    n_points : int or None
        Points per part fed to the part encoder (a random subset each step in training, the
        first ``n_points`` at evaluation); ``None`` for all.
    class_weighting : {"inv_sqrt", "none"}
        Cross-entropy class weights (:func:`kinmo.models.losses.class_weights`).
    focal_gamma : float
        Focal-loss exponent (0: off).
    w_dir, w_pos : float
        Weights of the direction and position loss terms (Eq. 1).
    balance : {"edges", "shapes"}
        Weigh every edge or every shape the same in each loss term
        (:class:`kinmo.models.losses.MotionLoss`).
    augment_yaw : bool
        Rotate every training shape about the vertical axis by a random angle each step.
    augment_turn : float
        Share of training shapes given turned by a random quarter turn (1 to 3) about the
        vertical each step (:meth:`kinmo.features.GraphTensors.turned`: exact, OBB axes
        signed as a fit of the turned shape signs them), so that the GNN does not lean on
        PartNet's facing alone (issue 36). 0 draws nothing.
    grad_clip : float
        Gradient norm clip (0: off).
    seed : int
        Seeds torch, the data order and the split.
    device : str
        ``"auto"`` (CUDA when available, else CPU), ``"cpu"``, ``"cuda"``, ``"cuda:1"``...
    threads : int
        CPU threads of torch (0: leave torch's default).
    test_fraction : float
        Share of each category's objects held out when the split is made by the run.
    flatten_prob : float
        Share of training shapes that also get a flattened variant (a root with one leaf per
        mobility link or per PartNet leaf, :func:`kinmo.data.augment.flat_variants`): a
        user's flat segmentation (issue 22).
    drop_names_prob : float
        Share of training graphs (originals and variants) whose node names are replaced by
        ``"unknown"``/``part_<k>`` (semantic index 0), so that names are a bonus, not needed.
    """

    model_config = ConfigDict(extra="forbid")

    preset: str = "quick"
    model: ModelConfig = Field(default_factory=ModelConfig)
    epochs: int = 60
    batch_size: int = 8
    lr: float = 2e-3
    weight_decay: float = 1e-5
    schedule: Literal["cosine", "step", "constant"] = "cosine"
    step_size: int = 20
    step_gamma: float = 0.7
    n_points: int | None = 256
    class_weighting: Literal["inv_sqrt", "none"] = "inv_sqrt"
    focal_gamma: float = 0.0
    w_dir: float = 1.0
    w_pos: float = 1.0
    balance: Literal["edges", "shapes"] = "shapes"
    augment_yaw: bool = False
    augment_turn: float = Field(0.0, ge=0.0, le=1.0)
    grad_clip: float = 5.0
    seed: int = 0
    device: str = "auto"
    threads: int = 0
    test_fraction: float = 0.25
    flatten_prob: float = Field(0.0, ge=0.0, le=1.0)
    drop_names_prob: float = Field(0.0, ge=0.0, le=1.0)


#: The presets' :attr:`TrainConfig.augment_turn` (issue 36): the share of training shapes seen
#: a quarter turn off PartNet's facing. Measured in docs/results/user_format.md ("Facing").
AUGMENT_TURN = 0.15

#: Overrides that switch every hierarchy, name and facing augmentation of a preset off (the
#: coarse GNNs, ``kinmo train all`` without ``augment_gnn``, and ``tiny``).
NO_AUGMENTATIONS: dict[str, float] = {"flatten_prob": 0.0, "drop_names_prob": 0.0, "augment_turn": 0.0}


def _quick() -> TrainConfig:
    return TrainConfig(
        preset="quick",
        model=ModelConfig(
            point_encoder="pointnet",
            point_widths=[32, 64],
            geo_dim=64,
            node_dim=64,
            edge_dim=64,
            semantic_dim=16,
            hier_iterations=2,
            top_down=True,
            gnn_layers=3,
        ),
        epochs=60,
        batch_size=8,
        lr=2e-3,
        weight_decay=1e-5,
        schedule="cosine",
        n_points=256,
        threads=1,
        flatten_prob=1.0,
        drop_names_prob=0.5,
        augment_turn=AUGMENT_TURN,
    )


def _paper() -> TrainConfig:
    return TrainConfig(
        preset="paper",
        model=ModelConfig(
            point_encoder="dgcnn",
            point_widths=[64, 64, 128],
            geo_dim=100,
            node_dim=256,
            edge_dim=256,
            semantic_dim=256,
            hier_iterations=2,
            top_down=True,
            gnn_layers=5,
            dgcnn_k=20,
        ),
        epochs=400,
        batch_size=2,
        lr=1e-4,
        weight_decay=1e-4,
        schedule="step",
        step_size=20,
        step_gamma=0.7,
        n_points=1024,
        flatten_prob=1.0,
        drop_names_prob=0.5,
        augment_turn=AUGMENT_TURN,
    )


def _tiny() -> TrainConfig:
    return _quick().model_copy(update={"preset": "tiny", "epochs": 25, **NO_AUGMENTATIONS})


#: Preset factories by name (``tiny``: ``quick`` for 25 epochs, a check that a run goes
#: through in seconds, not results).
PRESETS = {"quick": _quick, "paper": _paper, "tiny": _tiny}


def preset(name: str, **overrides: Any) -> TrainConfig:
    """A preset configuration with top-level fields (and ``types``) overridden.

    Parameters
    ----------
    name : {"quick", "paper", "tiny"}
    **overrides
        ``TrainConfig`` fields, plus ``types`` (``"fine"``/``"coarse"``) which goes to the
        model configuration. ``None`` values are ignored (convenient for CLI options).

    Returns
    -------
    TrainConfig

    Raises
    ------
    ValueError
        Unknown preset or field, or an invalid value.
    """
    data = preset_values(PRESETS, name)
    types = overrides.pop("types", None)
    if types is not None:
        data["model"]["types"] = types
    return TrainConfig.model_validate(override(data, overrides))
