"""Checkpoints of the axis-selection network: one global network and optional per-category ones.

A run folder of ``kinmo train axis`` holds ``model.pt`` (the global network, chosen by
validation selection accuracy) and, when per-category networks were trained and kept,
``categories.json`` (category -> checkpoint file under ``categories/``, with the validation
accuracies that justified keeping it). :func:`load_axis_model` returns one network (the
category's when asked for one that has its own, else the global one);
:func:`load_axis_models` returns an :class:`AxisModelSet` that picks per shape category and
falls back to the global network. Both are accepted by
:func:`kinmo.refine.feasibility.score_lines`.

Checkpoints are ``torch.save`` dicts with ``format = "kinmo-axis-selection"``, the state dict
and the network configuration (:class:`~kinmo.refine.axis_net.AxisNetConfig`), written
atomically and read safely (``weights_only=True``) by :func:`kinmo.train.loop.save_checkpoint`
and :func:`kinmo.train.loop.load_checkpoint`.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from kinmo.errors import KinmoDataError
from kinmo.refine.axis_net import AxisNetConfig, AxisSelectionNet
from kinmo.train.loop import build_or_refuse, load_checkpoint, save_checkpoint

__all__ = ["AxisModelSet", "category_files", "load_axis_model", "load_axis_models", "save_axis_model"]

#: ``format`` tag of the checkpoints.
CHECKPOINT_FORMAT = "kinmo-axis-selection"

#: Index of the per-category networks inside a run folder.
CATEGORIES_FILE = "categories.json"


def save_axis_model(path: str | Path, model: AxisSelectionNet, **extra: Any) -> Path:
    """Write an axis-selection checkpoint atomically (read by :func:`load_axis_model`).

    Parameters
    ----------
    path : str or Path
        The ``.pt`` file (parent folders are created).
    model : AxisSelectionNet
    **extra
        JSON-like items stored with it (epoch, metrics, training configuration).

    Returns
    -------
    Path
    """

    return save_checkpoint(path, CHECKPOINT_FORMAT, model, net=model.config.model_dump(), **extra)


def _read_checkpoint(p: Path, device: str) -> AxisSelectionNet:
    blob, p = load_checkpoint(p, CHECKPOINT_FORMAT, "axis-selection", "kinmo train axis")

    def build() -> AxisSelectionNet:
        model = AxisSelectionNet(AxisNetConfig(**blob["net"]))
        model.load_state_dict(blob["state_dict"])
        return model

    return build_or_refuse(p, build).to(device).eval()


def category_files(run: str | Path) -> dict[str, str]:
    """The per-category networks a run kept: category -> file relative to ``run``.

    Read from ``categories.json`` (empty without one). The file names come from the file, so
    each must be ``categories/<name>.pt`` with a plain name (no folder, no ``..``): the index
    never points outside its run.

    Raises
    ------
    KinmoDataError
        Unreadable index, or a file name of another form (one line naming the index).
    """
    f = Path(run) / CATEGORIES_FILE
    if not f.is_file():
        return {}
    try:
        data = json.loads(f.read_text())
        files = {str(c): str(v["file"]) for c, v in data.get("categories", {}).items()}
    except (ValueError, KeyError, TypeError, AttributeError) as e:
        raise KinmoDataError(f, f"cannot read the per-category index: {e}") from None
    for rel in files.values():
        parts = rel.split("/")
        if (len(parts) != 2 or parts[0] != "categories" or not parts[1].endswith(".pt")
                or parts[1] in (".pt", "..") or "\\" in rel or parts[1].startswith(".")):
            raise KinmoDataError(f, f"per-category network {rel[:80]!r} is not categories/<name>.pt")
    return files


def load_axis_model(path: str | Path, device: str = "cpu", category: str | None = None
                    ) -> AxisSelectionNet:
    """Load a trained axis-selection network.

    Parameters
    ----------
    path : str or Path
        A run folder of ``kinmo train axis`` (its ``model.pt``) or a checkpoint file.
    device : str
    category : str, optional
        With a run folder: the category's own network when the run kept one
        (``categories.json``), else the global one.

    Returns
    -------
    AxisSelectionNet
        In eval mode.

    Raises
    ------
    KinmoDataError
        Missing or unreadable checkpoint (message names the file).
    """
    p = Path(path)
    if p.is_dir():
        files = category_files(p) if category is not None else {}
        p = p / files[category] if category in files else p / "model.pt"
    return _read_checkpoint(p, device)


@dataclass
class AxisModelSet:
    """A global axis-selection network and per-category ones that replace it.

    Attributes
    ----------
    global_model : AxisSelectionNet
    categories : dict of str to AxisSelectionNet
        Category name (``PartGraph.category``) -> its network.
    """

    global_model: AxisSelectionNet
    categories: dict[str, AxisSelectionNet] = field(default_factory=dict)

    def for_category(self, category: str | None) -> AxisSelectionNet:
        """The category's network, or the global one."""
        return self.categories.get(category or "", self.global_model)

    @property
    def config(self) -> AxisNetConfig:
        """The global network's configuration (all networks of a run share the input format)."""
        return self.global_model.config


def load_axis_models(path: str | Path, device: str = "cpu") -> AxisModelSet:
    """Load the global and every per-category network of a run (a checkpoint: global only).

    Raises
    ------
    KinmoDataError
        Missing or unreadable checkpoint or index (message names the file).
    """
    p = Path(path)
    if not p.is_dir():
        return AxisModelSet(_read_checkpoint(p, device))
    cats = {c: _read_checkpoint(p / f, device) for c, f in sorted(category_files(p).items())}
    return AxisModelSet(_read_checkpoint(p / "model.pt", device), cats)
