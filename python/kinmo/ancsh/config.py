"""Configuration of ANCSH training on rendered partial scans, with its presets.

Liu et al. CVPR 2023 (Sec. 3.4, 4.3, Table 2) train ANCSH (Li et al. CVPR 2020) on single-view
partial scans of one category in three settings (:data:`SETTINGS`):

- ``supervised``: rendered scans of the labelled PartNet-Mobility training objects;
- ``semi``: the semi-supervised baseline: the supervised model labels scans of the unlabelled
  PartNet shapes (rendered at rest, as their motion is unknown), its confident predictions
  become pseudo-targets, and training continues on labelled + pseudo-targeted scans;
- ``semi-weakly``: the paper's method: the PartNet shapes pseudo-labelled by the motion GNN
  and refinement (``kinmo pseudo-label``) are rendered at random articulations of their
  predicted joints and added to the labelled data.

Three presets (:data:`PRESETS`; ``tiny`` is ``quick`` for one epoch of two batches on one
render per object, a check that a run goes through, as ``KINMO_PRESET=tiny``):

- ``quick``: CPU-sized, about a minute per setting on one core: 512 input points, a
  PointNet++ of base width 16 with (128, 32, 8) centres, 16 scans of 160 x 160 pixels per
  object, 40 epochs of 35 batches of 8 (1,400 steps; ``semi``: 20 more epochs), Adam at 2e-3
  with a cosine schedule, one torch thread. It was 25 batches per epoch until issue 38 made
  the step about 2x faster and spent 1.4x of that on more steps (item 4).
- ``paper``: the sizes of ANCSH (1024 points, PointNet++ of width 64 with (512, 128, 32)
  centres, batches of 16, Adam at 1e-3) with 100 renders per object and 100 full passes,
  meant for a GPU.

Training length is ``epochs x steps_per_epoch`` batches whatever the amount of data, so the
three settings of a preset get the same optimisation budget (``steps_per_epoch = None``: one
pass over the training scans per epoch, the usual definition). Every run is seeded and its
full configuration is written next to the checkpoint (``config.json``).
"""

from __future__ import annotations

from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, field_validator
from kinmo.train.loop import override, preset_values

__all__ = ["PRESETS", "SETTINGS", "SYNTH_FIELDS", "ANCSHConfig", "preset"]

#: The training settings of Table 2, in the paper's row order.
SETTINGS: tuple[str, ...] = ("supervised", "semi", "semi-weakly")


#: The fields of generated training objects (issue 38): left out of a configuration's stage key
#: while ``synth_objects`` is 0 (:meth:`ANCSHConfig.key`), so runs made before them stay up to
#: date.
SYNTH_FIELDS: frozenset[str] = frozenset({"synth_objects", "synth_as", "synth_share"})


class ANCSHConfig(BaseModel):
    """Everything a ``kinmo train ancsh`` run depends on.

    Attributes
    ----------
    preset : str
        Name of the preset the configuration started from.
    category : str
        The object category (PartNet-Mobility ``model_cat``, e.g. ``"Laptop"``); filled in by
        the run.
    setting : {"supervised", "semi", "semi-weakly"}
    n_points : int
        Points per scan fed to the network (random subset; repeated points pad small scans).
    cache_points : int
        Points kept in memory per scan (a fixed random subset; each step draws ``n_points``
        of them).
    width : int
        PointNet++ base width.
    n_centers : (int, int, int)
        Centres of the three set-abstraction levels.
    radii : (float, float, float)
        Ball radii, in units of the scan's radius (inputs are centred and scaled to the unit
        ball).
    theta : float
        Joint association distance in NAOCS units (:func:`kinmo.ancsh.targets.joint_targets`).
    frames_per_object : int
        Rendered training scans per labelled or pseudo-labelled object.
    unlabeled_frames_per_object : int
        Scans per unlabelled PartNet shape (``semi``).
    test_frames_per_object : int
        Scans per test object (``kinmo eval``).
    image_size : int
        Width and height of the rendered depth images, pixels.
    epochs : int
    steps_per_epoch : int or None
        Batches per epoch; ``None``: one pass over the training scans.
    semi_epochs : int
        ``semi``: epochs of training on labelled + pseudo-targeted scans after the supervised
        stage (which runs ``epochs``), continuing from the supervised weights.
    batch_size : int
    lr : float
        Adam learning rate.
    weight_decay : float
    schedule : {"cosine", "step", "constant"}
    step_size, step_gamma : int, float
        Step schedule: multiply the rate by ``step_gamma`` every ``step_size`` epochs.
    grad_clip : float
        Gradient norm clip (0: off).
    jitter : float
        Standard deviation of Gaussian noise added to the normalised training points.
    min_seg_confidence : float
        ``semi``: keep a pseudo-targeted scan when its mean per-point segmentation
        probability is at least this.
    min_inlier_ratio : float
        ``semi``: ... and every part's fitted pose explains at least this share of its points
        (RANSAC inlier ratio after post-processing, :func:`kinmo.ancsh.semi.scan_confidence`).
    pseudo_keep_fraction : float
        ``semi``: of the scans passing both thresholds, keep this share with the highest
        inlier ratio (a ranking transfers across models of different quality, where absolute
        inlier ratios do not).
    labeled_fraction : float
        Share of the category's labelled training objects used (seeded subset, at least one).
    test_fraction : float
        Share of each category's objects held out when the run makes the split
        (:func:`kinmo.train.split.make_split`; the GNN's default, so the splits agree).
    seed : int
        Seeds the split, the renders, torch and the sampling.
    device : str
        ``"auto"`` (CUDA when available), ``"cpu"``, ``"cuda"``, ``"cuda:1"``...
    threads : int
        CPU threads of torch (0: torch's default).
    render_workers : int
        Rendering processes (0: one per CPU, 1: in this process).
    synth_objects : int
        Generated objects (``kinmo synth --structure``) of the trained structure added to the
        labelled training data, each rendered ``frames_per_object`` times
        (:mod:`kinmo.ancsh.generated`); 0: none. Categories or structures that ``kinmo
        synth`` does not make train without them (``data.json`` says why). Test objects are
        always real.
    synth_as : {"mix", "pretrain"}
        How the generated scans are used: ``mix``: in the same batches as the real ones, a
        ``synth_share`` of the draws on average; ``pretrain``: the first
        ``round(synth_share * epochs)`` epochs on generated scans alone, then the remaining
        epochs on the real ones (fine-tuning, its own cosine schedule). Either way the run
        takes the same ``epochs x steps_per_epoch`` steps as without them.
    synth_share : float
        In (0, 1): the share of the draws (``mix``) or of the epochs (``pretrain``) given to
        generated scans.
    """

    model_config = ConfigDict(extra="forbid")

    preset: str = "quick"
    category: str = ""
    setting: Literal["supervised", "semi", "semi-weakly"] = "supervised"
    n_points: int = Field(512, ge=16)
    cache_points: int = Field(4096, ge=16)
    width: int = Field(16, ge=4)
    n_centers: tuple[int, int, int] = (128, 32, 8)
    radii: tuple[float, float, float] = (0.2, 0.4, 0.8)
    theta: float = Field(0.2, gt=0)
    frames_per_object: int = Field(16, ge=1)
    unlabeled_frames_per_object: int = Field(8, ge=1)
    test_frames_per_object: int = Field(24, ge=1)
    image_size: int = Field(160, ge=16, le=4096)
    epochs: int = Field(40, ge=1)
    steps_per_epoch: int | None = Field(35, ge=1)
    semi_epochs: int = Field(20, ge=1)
    batch_size: int = Field(8, ge=2)
    lr: float = Field(2e-3, gt=0)
    weight_decay: float = Field(0.0, ge=0)
    schedule: Literal["cosine", "step", "constant"] = "cosine"
    step_size: int = Field(20, ge=1)
    step_gamma: float = Field(0.7, gt=0)
    grad_clip: float = Field(5.0, ge=0)
    jitter: float = Field(0.005, ge=0)
    min_seg_confidence: float = Field(0.9, ge=0, le=1)
    min_inlier_ratio: float = Field(0.1, ge=0, le=1)
    pseudo_keep_fraction: float = Field(0.5, gt=0, le=1)
    labeled_fraction: float = Field(1.0, gt=0, le=1)
    test_fraction: float = Field(0.25, ge=0, lt=1)
    seed: int = 0
    device: str = "auto"
    threads: int = Field(1, ge=0)
    render_workers: int = Field(0, ge=0)
    synth_objects: int = Field(0, ge=0, le=100000)
    synth_as: Literal["mix", "pretrain"] = "mix"
    synth_share: float = Field(0.5, gt=0, lt=1)

    def key(self) -> dict[str, Any]:
        """The configuration as a stage key of ``kinmo train all``: :meth:`model_dump`
        without :data:`SYNTH_FIELDS` while ``synth_objects`` is 0."""
        return self.model_dump(exclude=set(SYNTH_FIELDS) if self.synth_objects == 0 else None)

    @field_validator("n_centers")
    @classmethod
    def _centers(cls, v: tuple[int, int, int]) -> tuple[int, int, int]:
        if any(c < 1 for c in v):
            raise ValueError(f"n_centers must be positive, got {v}")
        return v

    @field_validator("radii")
    @classmethod
    def _radii(cls, v: tuple[float, float, float]) -> tuple[float, float, float]:
        if any(r <= 0 for r in v):
            raise ValueError(f"radii must be positive, got {v}")
        return v


def _quick() -> ANCSHConfig:
    return ANCSHConfig(preset="quick")


def _paper() -> ANCSHConfig:
    return ANCSHConfig(
        preset="paper",
        n_points=1024,
        cache_points=8192,
        width=64,
        n_centers=(512, 128, 32),
        radii=(0.2, 0.4, 0.8),
        frames_per_object=100,
        unlabeled_frames_per_object=100,
        test_frames_per_object=20,
        image_size=256,
        epochs=100,
        steps_per_epoch=None,
        semi_epochs=50,
        batch_size=16,
        lr=1e-3,
        weight_decay=1e-5,
        schedule="step",
        step_size=20,
        step_gamma=0.7,
        threads=0,
    )


def _tiny() -> ANCSHConfig:
    return ANCSHConfig(preset="tiny", epochs=1, semi_epochs=1, steps_per_epoch=2, frames_per_object=1)


#: Preset factories by name (``tiny``: ``quick`` for one epoch of two batches on one render per
#: object, a check that a run goes through in seconds, not results).
PRESETS = {"quick": _quick, "paper": _paper, "tiny": _tiny}


def preset(name: str, **overrides: Any) -> ANCSHConfig:
    """A preset configuration with fields overridden.

    Parameters
    ----------
    name : {"quick", "paper", "tiny"}
    **overrides
        :class:`ANCSHConfig` fields; ``None`` values are ignored (convenient for CLI options).

    Returns
    -------
    ANCSHConfig

    Raises
    ------
    ValueError
        Unknown preset or field, or an invalid value.
    """

    return ANCSHConfig.model_validate(override(preset_values(PRESETS, name), overrides, "ANCSH training"))
