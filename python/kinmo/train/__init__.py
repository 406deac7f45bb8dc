"""Training of kinmo's models.

- :mod:`kinmo.train.config`: :class:`TrainConfig` and its presets (``quick``, ``paper``, ``tiny``).
- :mod:`kinmo.train.split`: deterministic category-stratified train/test splits.
- :mod:`kinmo.train.gnn`: the motion GNN training loop (``kinmo train gnn``).
- :mod:`kinmo.train.gnn_metrics`: its edge-level metrics (type accuracy, recall, axis errors).
- :mod:`kinmo.train.loop`: the run plumbing shared by the three trainers (presets, device,
  seeding and threads, optimisation step, progress bar, metrics CSV, checkpoints).
- :mod:`kinmo.train.distributed`: data-parallel training under ``torchrun``.
"""

from kinmo.train.config import PRESETS, TrainConfig, preset
from kinmo.train.split import Split, make_split

__all__ = ["PRESETS", "Split", "TrainConfig", "make_split", "preset"]
