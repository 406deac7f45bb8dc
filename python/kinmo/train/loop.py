"""Training-run plumbing shared by kinmo's three trainers.

The motion GNN (:mod:`kinmo.train.gnn`), the axis-selection network
(:mod:`kinmo.refine.train`) and ANCSH (:mod:`kinmo.ancsh.train`) differ in their data and
losses, not in how a run is set up and written. This module holds that common part:

- **presets**: :func:`preset_values` (a named preset's values, a clear error for an unknown
  name) and :func:`override` (CLI-style overrides, ``None`` ignored, unknown options refused);
- **device**: :func:`resolve_device` (``"auto"`` -> CUDA when available, else CPU);
- **session**: :func:`training_session` joins ``torch.distributed`` when run under
  ``torchrun`` (:func:`kinmo.train.distributed.setup`), sets torch's CPU threads
  (:func:`kinmo.parallel.torch_threads`), optionally switches on deterministic algorithms,
  seeds torch, ``random`` and numpy's global generator, and restores the previous settings
  afterwards;
- **optimisation step**: :func:`optimizer_step` (zero the gradients, back-propagate the
  rank-weighted loss, average gradients over ranks when asked, clip, step);
- **progress**: :func:`training_bar`, the one rich bar of the epoch loops
  (:class:`kinmo.progress.TrainingBar`), shown on rank 0 only;
- **metrics**: :func:`rows_csv` formats ``metrics.csv`` (and the other per-row tables of
  the runs), written atomically with :func:`kinmo.io.write_text`;
- **checkpoints**: :func:`save_checkpoint` writes a ``torch.save`` dict with its
  ``format`` tag atomically (:func:`kinmo.io.atomic_path`); :func:`load_checkpoint` finds a
  run's ``model.pt`` and reads it safely (:func:`kinmo.io.read_checkpoint`), and
  :func:`build_or_refuse` turns a model that does not match its checkpoint into one error
  line naming the file.

Runs stay reproducible: the same seed and thread count give the same weights and metrics.
"""

from __future__ import annotations

import copy
import csv
import io
import math
import random
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
import torch

from kinmo.errors import KinmoDataError, KinmoTrainingError
from kinmo.io import atomic_path, read_checkpoint
from kinmo.parallel import torch_threads
from kinmo.progress import TrainingBar
import kinmo.train.distributed as distributed

__all__ = [
    "build_or_refuse",
    "load_checkpoint",
    "optimizer_step",
    "override",
    "preset_values",
    "resolve_device",
    "rows_csv",
    "save_checkpoint",
    "training_bar",
    "training_session",
]


# ------------------------------------------------------------------------------ presets


def preset_values(presets: Mapping[str, Any], name: str) -> dict[str, Any]:
    """The values of a named preset as a fresh (deep-copied) dict.

    Parameters
    ----------
    presets : mapping of str to (callable or pydantic model or dict)
        Name -> factory returning a pydantic model, a model, or a dict of values.
    name : str

    Returns
    -------
    dict
        ``model_dump()`` of the preset (or a deep copy of its dict); free to modify.

    Raises
    ------
    ValueError
        Unknown preset (the message lists the known ones).
    """
    if name not in presets:
        raise ValueError(f"unknown preset {name!r} (choose from {', '.join(presets)})")
    p = presets[name]
    p = p() if callable(p) else p
    if hasattr(p, "model_dump"):
        return p.model_dump()
    return copy.deepcopy(dict(p))


def override(values: dict[str, Any], overrides: Mapping[str, Any], what: str = "training") -> dict[str, Any]:
    """Set top-level ``values`` from ``overrides`` (CLI options), in place.

    Parameters
    ----------
    values : dict
        A preset's values (:func:`preset_values`).
    overrides : mapping
        Option -> value; ``None`` values are ignored (an option the user did not give).
    what : str
        For the error message (``"unknown <what> option 'x'"``).

    Returns
    -------
    dict
        ``values``.

    Raises
    ------
    ValueError
        An option that is not a key of ``values``.
    """
    for key, val in overrides.items():
        if val is None:
            continue
        if key not in values:
            raise ValueError(f"unknown {what} option {key!r}")
        values[key] = val
    return values


# ------------------------------------------------------------------------------ session


def resolve_device(device: str) -> torch.device:
    """``"auto"`` → CUDA when available, else CPU; anything else as given.

    Raises
    ------
    ValueError
        CUDA requested but not available.
    """
    if device == "auto":
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    dev = torch.device(device)
    if dev.type == "cuda" and not torch.cuda.is_available():
        raise ValueError(f"device {device!r} requested but CUDA is not available")
    return dev


@contextmanager
def training_session(
    device: str = "auto", seed: int | None = None, threads: int = 0, deterministic: bool = False,
) -> Iterator[tuple[distributed.DistInfo, torch.device]]:
    """Set up a training run; restore torch's global settings afterwards.

    Parameters
    ----------
    device : str
        ``"auto"``, ``"cpu"``, ``"cuda"``, ``"cuda:1"``... (:func:`resolve_device`). Under
        ``torchrun`` with CUDA each rank gets its local GPU (:func:`kinmo.train.distributed.setup`).
    seed : int, optional
        Seeds torch, ``random`` and numpy's global generator (modulo 2**32) on entry.
    threads : int
        torch CPU threads (0: torch's default).
    deterministic : bool
        Switch on torch's deterministic algorithms (``warn_only``) for the duration.

    Yields
    ------
    info : DistInfo
        Rank and world size (rank 0 of 1 outside ``torchrun``).
    device : torch.device
        This rank's training device.

    Raises
    ------
    ValueError
        CUDA requested but not available.
    """
    prev_det = torch.are_deterministic_algorithms_enabled()
    with torch_threads(threads):
        try:
            if deterministic:
                torch.use_deterministic_algorithms(True, warn_only=True)
            info, dev = distributed.setup(resolve_device(device))
            if seed is not None:
                torch.manual_seed(seed)
                random.seed(seed)
                np.random.seed(seed % (2**32))
            yield info, dev
        finally:
            torch.use_deterministic_algorithms(prev_det)


def optimizer_step(
    opt: torch.optim.Optimizer, loss: torch.Tensor, model: torch.nn.Module, weight: float = 1.0,
    grad_clip: float = 0.0, sync: bool = False,
) -> None:
    """One optimisation step on ``loss * weight``.

    Parameters
    ----------
    opt : torch.optim.Optimizer
    loss : torch.Tensor
        Scalar.
    model : torch.nn.Module
        Its parameters are clipped (and synchronised).
    weight : float
        The rank's loss weight (:func:`kinmo.train.distributed.shard`; 1 in one process).
    grad_clip : float
        Gradient norm clip (0: off).
    sync : bool
        Average the gradients over the ranks (:func:`kinmo.train.distributed.sync_gradients`;
        for models not wrapped in ``DistributedDataParallel``).

    Raises
    ------
    KinmoTrainingError
        The loss or the gradient norm is ``nan`` or ``inf`` (training diverged).
    """
    if not bool(torch.isfinite(loss.detach()).all()):
        raise KinmoTrainingError(type(model).__name__, f"training loss is {float(loss.detach().sum())} "
                                 "(diverged: lower the learning rate); no model saved")
    opt.zero_grad(set_to_none=True)
    (loss * weight).backward()
    if sync:
        distributed.sync_gradients(model)
    norm = torch.nn.utils.clip_grad_norm_(model.parameters(), grad_clip if grad_clip > 0 else float("inf"))
    if not bool(torch.isfinite(norm)):
        raise KinmoTrainingError(type(model).__name__, f"gradient norm is {float(norm)} "
                                 "(diverged: lower the learning rate); no model saved")
    opt.step()


def training_bar(progress: bool, title: str) -> TrainingBar:
    """The epoch loop's progress bar: shown when ``progress`` and on rank 0 only."""
    return TrainingBar(progress and distributed.info().is_main, title)


# ------------------------------------------------------------------------------ metrics


def _cell(v: Any, digits: int | None, nan: str) -> Any:
    if isinstance(v, float):
        if math.isnan(v):
            return nan
        return f"{v:.{digits}g}" if digits is not None else v
    return v


def rows_csv(rows: Sequence[Mapping[str, Any]], columns: Sequence[str], digits: int | None = 6,
             nan: str = "") -> str:
    """Rows as CSV text with the header ``columns`` (missing entries empty, others ignored).

    Parameters
    ----------
    rows : sequence of mapping
    columns : sequence of str
    digits : int or None
        Significant digits of floats (``None``: as Python prints them).
    nan : str
        How NaN floats are written.

    Returns
    -------
    str
        ``\\n`` line ends.
    """
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(columns)
    for r in rows:
        w.writerow([_cell(r.get(c, ""), digits, nan) for c in columns])
    return buf.getvalue()


# ---------------------------------------------------------------------------- checkpoints


def save_checkpoint(path: str | Path, fmt: str, model: torch.nn.Module, **items: Any) -> Path:
    """Write a kinmo checkpoint atomically: ``format``, ``version`` 1, the CPU state dict, ``items``.

    Parameters
    ----------
    path : str or Path
        The ``.pt`` file (parent folders are created).
    fmt : str
        Its ``format`` tag (``"kinmo-motion-gnn"``, ``"kinmo-axis-selection"``,
        ``"kinmo-ancsh"``), checked by :func:`load_checkpoint`.
    model : torch.nn.Module
    **items
        Plain data stored with it (configuration, epoch, vocabulary...): only tensors, dicts,
        lists, strings and numbers, which ``torch.load(weights_only=True)`` reads back.

    Returns
    -------
    Path

    Raises
    ------
    KinmoTrainingError
        A floating-point parameter or buffer is not finite (nothing is written).
    """
    path = Path(path)
    bad = [k for k, v in model.state_dict().items()
           if torch.is_floating_point(v) and not bool(torch.isfinite(v).all())]
    if bad:
        raise KinmoTrainingError(path, f"parameters {', '.join(bad[:3])} are not finite "
                                 "(training diverged: lower the learning rate); not saved")
    path.parent.mkdir(parents=True, exist_ok=True)
    payload = {"format": fmt, "version": 1,
               "state_dict": {k: v.detach().cpu() for k, v in model.state_dict().items()}, **items}
    with atomic_path(path) as tmp:
        torch.save(payload, tmp)
    return path


def load_checkpoint(run: str | Path, fmt: str, what: str, command: str) -> tuple[dict[str, Any], Path]:
    """Read the checkpoint of a run folder (its ``model.pt``) or a checkpoint file.

    Parameters
    ----------
    run : str or Path
    fmt : str
        The ``format`` tag it must carry.
    what : str
        What it is, for messages (``"ANCSH"``).
    command : str
        The command that trains one, for the message of a missing file
        (``"kinmo train ancsh"``).

    Returns
    -------
    payload : dict
        Tensors on the CPU.
    path : Path
        The checkpoint file.

    Raises
    ------
    KinmoDataError
        Missing, unreadable or foreign checkpoint (one line naming the file).
    """
    run = Path(run)
    ckpt = run / "model.pt" if run.is_dir() else run
    if not ckpt.is_file():
        raise KinmoDataError(ckpt, f"{what} checkpoint is missing (train with `{command}`)")
    payload = read_checkpoint(ckpt, fmt, what)
    if payload.get("format") != fmt:
        raise KinmoDataError(ckpt, f"not a kinmo {what} checkpoint")
    return payload, ckpt


def build_or_refuse(ckpt: Path, build: Callable[[], Any]) -> Any:
    """``build()`` (a model from a checkpoint's config and state dict), any failure turned into
    one :class:`KinmoDataError` naming ``ckpt`` ("checkpoint does not match the model")."""
    try:
        return build()
    except Exception as e:  # pydantic, torch and key errors of a foreign or stale checkpoint
        raise KinmoDataError(ckpt, f"checkpoint does not match the model: {e}") from None
