"""Trained ANCSH runs and inference on partial scans (apart from training).

What evaluation (:mod:`kinmo.ancsh.evaluate`) and the semi-supervised self-training
(:mod:`kinmo.ancsh.semi`) need of a trained model, without the trainer
(:mod:`kinmo.ancsh.train`):

- :func:`save_checkpoint` / :func:`load_run`: the run's ``model.pt`` (``format`` ``kinmo-ancsh``:
  state dict, :class:`~kinmo.ancsh.config.ANCSHConfig`, kinematic structure, epoch), written
  atomically and read safely (:mod:`kinmo.train.loop`);
- :func:`build_model`: the network of a configuration and structure;
- :func:`predict_scans`: the network on camera-frame scans, subsampled and normalised as in
  training (:func:`kinmo.ancsh.dataset.subsample_indices`, :func:`normalize_points`);
- :func:`quiet_estimate`: the post-processing (:func:`kinmo.ancsh.postprocess.estimate`)
  without the overflow warnings of an undertrained network's predictions.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch

from kinmo.ancsh.config import ANCSHConfig
from kinmo.ancsh.dataset import normalize_points, subsample_indices
from kinmo.ancsh.model import ANCSH
from kinmo.ancsh.postprocess import estimate
from kinmo.ancsh.structure import KinematicStructure
from kinmo.train.loop import (
    build_or_refuse,
    load_checkpoint,
    resolve_device,
    save_checkpoint as _save,
)

__all__ = [
    "CHECKPOINT_FORMAT",
    "ANCSHRun",
    "build_model",
    "load_run",
    "predict_scans",
    "quiet_estimate",
    "save_checkpoint",
]

#: ``format`` tag of ANCSH checkpoints.
CHECKPOINT_FORMAT = "kinmo-ancsh"


@dataclass
class ANCSHRun:
    """A trained ANCSH model loaded from a run folder.

    Attributes
    ----------
    model : ANCSH
        In eval mode, on ``device``.
    config : ANCSHConfig
    structure : KinematicStructure
    device : torch.device
    path : Path
        The run folder.
    """

    model: ANCSH
    config: ANCSHConfig
    structure: KinematicStructure
    device: torch.device
    path: Path

    @property
    def category(self) -> str:
        """The category the run was trained on."""
        return self.config.category

    @property
    def setting(self) -> str:
        """``"supervised"``, ``"semi"`` or ``"semi-weakly"``."""
        return self.config.setting


def build_model(config: ANCSHConfig, structure: KinematicStructure) -> ANCSH:
    """An untrained :class:`~kinmo.ancsh.model.ANCSH` of ``config``'s size for ``structure``."""
    return ANCSH(structure.n_parts, structure.n_joints, config.width, tuple(config.n_centers),
                 tuple(config.radii))


def save_checkpoint(path: str | Path, model: ANCSH, config: ANCSHConfig, structure: KinematicStructure,
                    epoch: int) -> None:
    """Write ``model.pt`` atomically: state dict, config, structure, epoch."""
    _save(path, CHECKPOINT_FORMAT, model, config=config.model_dump(mode="json"),
          structure={"parents": list(structure.parents), "joint_types": list(structure.joint_types)},
          epoch=int(epoch))


def load_run(run: str | Path, device: str = "auto") -> ANCSHRun:
    """Load a trained ANCSH from a run folder (or its ``model.pt``).

    Parameters
    ----------
    run : str or Path
    device : str
        ``"auto"``, ``"cpu"``, ``"cuda"`` ... (:func:`kinmo.train.loop.resolve_device`).

    Returns
    -------
    ANCSHRun

    Raises
    ------
    KinmoDataError
        Missing or unreadable checkpoint, or not a kinmo ANCSH checkpoint.
    """
    payload, ckpt = load_checkpoint(run, CHECKPOINT_FORMAT, "ANCSH", "kinmo train ancsh")

    def build() -> tuple[ANCSHConfig, KinematicStructure, ANCSH]:
        config = ANCSHConfig.model_validate(payload["config"])
        st = payload["structure"]
        structure = KinematicStructure(tuple(st["parents"]), tuple(st["joint_types"]))
        model = build_model(config, structure)
        model.load_state_dict(payload["state_dict"])
        return config, structure, model

    config, structure, model = build_or_refuse(ckpt, build)
    dev = resolve_device(device)
    model.to(dev).eval()
    return ANCSHRun(model, config, structure, dev, ckpt.parent)


@torch.no_grad()
def predict_scans(
    model: ANCSH,
    scans: Sequence[np.ndarray],
    n_points: int,
    device: torch.device | str = "cpu",
    seeds: Sequence[int] | None = None,
    batch_size: int = 16,
) -> list[tuple[np.ndarray, dict[str, np.ndarray]]]:
    """Run ANCSH on partial scans.

    Each scan is subsampled to ``n_points`` (:func:`kinmo.ancsh.dataset.subsample_indices`,
    generator seeded by ``seeds[i]``) and normalised (:func:`normalize_points`) as in training.

    Parameters
    ----------
    model : ANCSH
    scans : sequence of (M_i, 3) float
        Camera-frame points.
    n_points : int
    device : torch.device or str
    seeds : sequence of int, optional
        Per scan (default ``0, 1, ...``).
    batch_size : int

    Returns
    -------
    list of (points, pred)
        ``points`` (n_points, 3) float64: the camera-frame points the network saw; ``pred``:
        numpy arrays of :class:`~kinmo.ancsh.model.ANCSH` output without the batch dimension
        (the input of :func:`kinmo.ancsh.postprocess.estimate`).
    """
    was_training = model.training
    model.eval()
    seeds = list(range(len(scans))) if seeds is None else list(seeds)
    out: list[tuple[np.ndarray, dict[str, np.ndarray]]] = []
    try:
        for b0 in range(0, len(scans), batch_size):
            pts, xyz = [], []
            for s, seed in zip(scans[b0:b0 + batch_size], seeds[b0:b0 + batch_size]):
                s = np.asarray(s, dtype=np.float64)
                p = s[subsample_indices(len(s), n_points, np.random.default_rng(seed))]
                pts.append(p)
                xyz.append(normalize_points(p)[0])
            pred = model(torch.from_numpy(np.stack(xyz)).to(device))
            pred = {k: v.detach().cpu().numpy() for k, v in pred.items()}
            for i, p in enumerate(pts):
                out.append((p, {k: v[i] for k, v in pred.items()}))
    finally:
        model.train(was_training)
    return out


def quiet_estimate(points: np.ndarray, pred: dict[str, np.ndarray], structure: KinematicStructure,
                   **kwargs: Any) -> Any:
    """:func:`kinmo.ancsh.postprocess.estimate` without numpy / scipy overflow warnings
    (expected for the wild predictions of an undertrained network)."""
    import warnings

    with warnings.catch_warnings(), np.errstate(all="ignore"):
        warnings.simplefilter("ignore", RuntimeWarning)
        return estimate(points, pred, structure, **kwargs)
