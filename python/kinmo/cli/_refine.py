"""Refinement options shared by ``kinmo predict``, ``kinmo pseudo-label`` and ``kinmo eval
pre-segmented`` (:class:`kinmo.refine.refine.RefineConfig`, Liu et al. 2023, Sec. 3.3).

A command declares one parameter ``refine: RefineOptions = REFINE`` and is decorated with
:func:`with_refine_options`: the parameter becomes the six options below on the command line
(in its place in ``--help``), and the command receives them as one :class:`RefineOptions`.
"""

from __future__ import annotations

import functools
import inspect
from collections.abc import Callable
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any, Optional

import typer

import kinmo.cli._values as _values

FEASIBILITY_ONLY = typer.Option(
    False, "--feasibility-only",
    help="Select candidate axes by the axis network alone (the paper's released code) instead of "
         "0.5 feasibility + 0.3 direction + 0.2 position (implies --paper-selector).")
KEEP_GNN = typer.Option(
    False, "--keep-gnn", help="The GNN's own axis competes as a candidate (kinmo extension; "
                              "implies --paper-selector; the learned selector always has it).")
SNAP_ANGLE: Any = typer.Option(
    None, "--snap-angle", min=0.0, max=90.0,
    help="Only candidates within this angle (deg) of the GNN's axis compete; none left: the GNN's "
         "axis, with no score (kinmo extension; implies --paper-selector).")
BOX_FRAMES = typer.Option(
    "moving", "--box-frames",
    help="Comma-separated boxes giving the candidates: moving (the part's OBB, the paper), "
         "reference (the part boxed in its reference part's OBB axes), shape (boxed in the "
         "shape frame) (kinmo extension; other than 'moving' implies --paper-selector; the "
         "learned selector always uses all three).")
PAPER_SELECTOR = typer.Option(
    False, "--paper-selector",
    help="Score candidates of the predicted type by the paper's 0.5 / 0.3 / 0.2 weights even when "
         "a learned ranker is available (ablation).")
RANKER: Any = typer.Option(
    None, "--ranker", callback=_values.ranker_file,
    help="Ranker file of the learned selector [default: AXIS_MODEL/ranker.json when present]: "
         "candidates of every orientation scored from soft GNN priors and geometric terms.")


def refine_config(feasibility_only: bool, keep_gnn: bool, snap_angle: Optional[float],  # noqa: UP007
                  box_frames: str, axis_model: Any = None, paper_selector: bool = False,
                  ranker: Any = None) -> Any:
    """The :class:`~kinmo.refine.refine.RefineConfig` of the options above.

    The learned selector (``selector="ranker"``) is used when a ranker file is given or
    ``axis_model/ranker.json`` exists, unless ``paper_selector`` or an option of the paper's
    scoring (``feasibility_only``, ``keep_gnn``, ``snap_angle``, other box frames) is set.

    Raises
    ------
    typer.Exit
        Code 2 after printing the problem, for invalid values (an unknown box frame).
    """
    from kinmo.cli._errors import fail
    from kinmo.refine.refine import RefineConfig
    from kinmo.refine.scoring import ScoringConfig

    from pathlib import Path

    frames = tuple(f.strip() for f in box_frames.split(",") if f.strip())
    paper = (paper_selector or feasibility_only or keep_gnn or bool(snap_angle)
             or frames != ("moving",))
    if ranker is None and axis_model is not None and (Path(axis_model) / "ranker.json").is_file():
        ranker = Path(axis_model) / "ranker.json"
    extra: dict[str, Any] = {}
    if ranker is not None and not paper:
        extra = {"selector": "ranker", "ranker": str(ranker)}
    try:
        return RefineConfig(scoring=ScoringConfig(feasibility_only=feasibility_only),
                            keep_gnn=keep_gnn, snap_angle_deg=snap_angle or None, box_frames=frames,
                            **extra)
    except ValueError as e:
        fail(f"invalid refinement option: {e}", 2)


@dataclass(frozen=True)
class RefineOptions:
    """The refinement options of a command, as given on its command line."""

    feasibility_only: bool = False
    keep_gnn: bool = False
    snap_angle: Optional[float] = None  # noqa: UP007
    box_frames: str = "moving"
    paper_selector: bool = False
    ranker: Optional[Path] = None  # noqa: UP007

    def resolve(self, model: Any, axis_model: Any = None) -> tuple[Any, Any, Any]:
        """What ``--model`` / ``--axis-model`` / ``--ranker`` name, resolved once
        (:func:`kinmo.inference.bundle.resolve_bundle`: a bundle folder, or a GNN run with
        the ranker found in or beside the axis folder).

        Returns
        -------
        (Path, Path or None, RefineConfig)
            The GNN run, the axis folder (None when there is neither an axis network nor a
            ranker; the ranker's folder when there is only a ranker) and the
            refinement configuration (the learned selector when a ranker was found, unless an
            option of the paper's scoring is set; the bundle's range prior when it has one).

        Raises
        ------
        KinmoDataError
            ``model`` is missing or a malformed bundle.
        """
        b, axis, rc = self.resolve_bundle(model, axis_model)
        return b.gnn, axis, rc

    def resolve_bundle(self, model: Any, axis_model: Any = None) -> tuple[Any, Any, Any]:
        """:meth:`resolve` with the whole :class:`~kinmo.inference.bundle.ModelBundle` in
        place of its GNN run (``kinmo pseudo-label`` also takes its ``check`` model)."""
        from dataclasses import replace

        from kinmo.inference.bundle import resolve_bundle

        b = resolve_bundle(model, axis_model, self.ranker)
        rc = replace(self, ranker=b.ranker).config(b.axis)
        if b.ranges is not None:  # the bundle's range prior (issue 35)
            rc = rc.model_copy(update={"ranges": str(b.ranges)})
        # the learned selector needs no network (then the folder of its ranker.json stands for
        # it); the paper's does (the Predictor names a folder without one)
        axis = b.axis if b.has_axis_network or rc.selector != "ranker" else Path(rc.ranker).parent
        return b, axis, rc

    def config(self, axis_model: Any = None) -> Any:
        """:func:`refine_config` of these options (``axis_model`` may hold a ranker.json)."""
        return refine_config(self.feasibility_only, self.keep_gnn, self.snap_angle,
                             self.box_frames, axis_model, self.paper_selector, self.ranker)


def model_or_pretrained(model: Path | None) -> Path:
    """``--model`` as given, or (None) the packaged pretrained bundle
    (:func:`kinmo.pretrained.default_model`), its licence notice printed once on stderr:
    what ``kinmo predict`` and ``kinmo pseudo-label`` use without ``--model``."""
    if model is not None:
        return model
    from kinmo.pretrained import default_model, license_notice
    from kinmo.progress import console

    model = default_model()
    console(stderr=True).print(license_notice(model), markup=False, highlight=False, soft_wrap=True)
    return model


#: Default of a command's ``refine`` parameter (replaced by :func:`with_refine_options`).
REFINE = RefineOptions()

_OPTIONS: dict[str, tuple[Any, Any]] = {
    "feasibility_only": (bool, FEASIBILITY_ONLY),
    "keep_gnn": (bool, KEEP_GNN),
    "snap_angle": (Optional[float], SNAP_ANGLE),  # noqa: UP007
    "box_frames": (str, BOX_FRAMES),
    "paper_selector": (bool, PAPER_SELECTOR),
    "ranker": (Optional[Path], RANKER),  # noqa: UP007
}
assert tuple(_OPTIONS) == tuple(f.name for f in fields(RefineOptions))


def with_refine_options(command: Callable[..., Any]) -> Callable[..., Any]:
    """Give a command the refinement options in place of its parameter ``refine``.

    Typer reads the returned function's signature: the command's own parameters, with
    ``refine`` replaced by the six options of this module; when called, the six values are
    passed to the command as ``refine=RefineOptions(...)``.

    Raises
    ------
    TypeError
        The command has no parameter ``refine``.
    """
    sig = inspect.signature(command)  # string annotations: typer resolves them (get_type_hints)
    if "refine" not in sig.parameters:
        raise TypeError(f"{command.__name__} has no parameter 'refine'")
    params: list[inspect.Parameter] = []
    for p in sig.parameters.values():
        if p.name != "refine":
            params.append(p)
            continue
        params += [inspect.Parameter(name, inspect.Parameter.POSITIONAL_OR_KEYWORD,
                                     default=option, annotation=ann)
                   for name, (ann, option) in _OPTIONS.items()]

    @functools.wraps(command)
    def run(**kwargs: Any) -> Any:
        refine = RefineOptions(**{name: kwargs.pop(name) for name in _OPTIONS})
        return command(**kwargs, refine=refine)

    run.__signature__ = sig.replace(parameters=params)  # type: ignore[attr-defined]
    run.__annotations__ = {p.name: p.annotation for p in params
                           if p.annotation is not inspect.Parameter.empty}
    return run
