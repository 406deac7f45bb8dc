"""Option values checked before a command starts (issue 21, finding 8).

Each function is a Typer ``callback=``: it returns the value when it is valid, and otherwise
prints one line ``error: --option VALUE: problem`` on stderr and exits with code 2 (via
:func:`kinmo.cli._errors.fail`), before any data is read or any model is built:

- :func:`device`: ``auto``, ``cpu``, ``cuda``, ``cuda:N`` (a GPU that exists), ``mps``;
- :func:`learning_rate`: a finite number in (0, 1];
- :func:`finite` / :func:`angle_deg`: finite numbers (``nan``, ``inf`` refused);
- :func:`ranker_file`: a file :func:`kinmo.refine.ranker.load_ranker` reads;
- :func:`collision`: a collision geometry method (:mod:`kinmo.export.collision`);
- :func:`turn_policy`: when the motion GNN averages quarter turns (:mod:`kinmo.inference.gnn`).
"""

from __future__ import annotations

import math
from typing import Any

import typer

__all__ = ["angle_deg", "collision", "device", "finite", "learning_rate", "ranker_file", "turn_policy",
           "up_axis"]

#: Largest learning rate accepted on the command line (every preset uses <= 1e-2).
MAX_LR = 1.0


def _name(ctx: typer.Context | None, param: Any) -> str:
    opts = getattr(param, "opts", None) or []
    long = [o for o in opts if o.startswith("--")]
    return (long or opts or [getattr(param, "name", "value")])[0]


def _fail(param: Any, value: Any, problem: str) -> None:
    from kinmo.cli._errors import fail

    fail(f"{_name(None, param)} {value}: {problem}", 2)


def device(ctx: typer.Context, param: Any, value: str | None) -> str | None:
    """A torch device name that exists on this machine (``None`` and ``auto`` pass)."""
    if value is None or ctx.resilient_parsing:
        return value
    v = value.strip().lower()
    if v in ("auto", "cpu"):
        return v
    kind, _, index = v.partition(":")
    if kind not in ("cuda", "mps") or (index and not index.isdigit()) or (kind == "mps" and index):
        _fail(param, value, "expected auto, cpu, cuda, cuda:N or mps")
    import torch

    if kind == "mps":
        if not (getattr(torch.backends, "mps", None) and torch.backends.mps.is_available()):
            _fail(param, value, "no MPS device on this machine")
        return v
    if not torch.cuda.is_available():
        _fail(param, value, "no CUDA GPU on this machine (use --device cpu or auto)")
    if index and int(index) >= torch.cuda.device_count():
        _fail(param, value, f"this machine has {torch.cuda.device_count()} CUDA GPU(s)")
    return v


def finite(ctx: typer.Context, param: Any, value: float | None) -> float | None:
    """A finite float (``nan`` and ``inf`` refused); ``None`` passes."""
    if value is not None and not math.isfinite(value):
        _fail(param, value, "expected a finite number")
    return value


def learning_rate(ctx: typer.Context, param: Any, value: float | None) -> float | None:
    """A finite learning rate in (0, :data:`MAX_LR`]; ``None`` (the preset's) passes."""
    if value is not None and not (math.isfinite(value) and 0.0 < value <= MAX_LR):
        _fail(param, value, f"expected a learning rate in (0, {MAX_LR:g}]")
    return value


def angle_deg(ctx: typer.Context, param: Any, value: float | None) -> float | None:
    """A finite angle in (0, 360] degrees; ``None`` passes."""
    if value is not None and not (math.isfinite(value) and 0.0 < value <= 360.0):
        _fail(param, value, "expected an angle in (0, 360] degrees")
    return value


def ranker_file(ctx: typer.Context, param: Any, value: Any) -> Any:
    """A ranker file (``ranker.json`` of ``kinmo train ranker``) that loads; ``None`` passes."""
    if value is None or ctx.resilient_parsing:
        return value
    from kinmo.errors import KinmoError
    from kinmo.refine.ranker import load_ranker

    try:
        load_ranker(value)
    except KinmoError as e:
        from kinmo.cli._errors import error_line

        _fail(param, value, error_line(e).replace(str(value) + ": ", "", 1))
    return value


def collision(ctx: typer.Context, param: Any, value: str | None) -> str | None:
    """``--collision``: a method of :mod:`kinmo.export.collision` (``coacd`` only with its
    package installed)."""
    if value is None or ctx.resilient_parsing:
        return value
    from kinmo.errors import KinmoUsageError
    from kinmo.export.collision import check_collision_method

    try:
        check_collision_method(value)
    except KinmoUsageError as e:
        _fail(param, value, e.problem)
    return value


def turn_policy(ctx: typer.Context, param: Any, value: str | None) -> str | None:
    """``--turns``: one of :data:`kinmo.inference.gnn.TURNS`."""
    if value is None or ctx.resilient_parsing:
        return value
    from kinmo.inference.gnn import TURNS

    if value not in TURNS:
        _fail(param, value, f"must be one of {', '.join(TURNS)}")
    return value


def up_axis(ctx: typer.Context, param: Any, value: str | None) -> str | None:
    """``--up``: ``y`` or ``z`` (:data:`kinmo.data.frames.UP_AXES`), any case."""
    if value is None:
        return None
    v = value.strip().lower()
    if v not in ("y", "z"):
        _fail(param, value, "must be y or z")
    return v
