"""Refinement options shared by ``kinmo predict``, ``kinmo pseudo-label`` and ``kinmo eval
pre-segmented`` (:class:`kinmo.refine.refine.RefineConfig`, Liu et al. 2023, Sec. 3.3)."""

from __future__ import annotations

from typing import Any, Optional

import typer

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
    None, "--ranker",
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
