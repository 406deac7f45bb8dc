"""Refinement options shared by ``kinmo predict``, ``kinmo pseudo-label`` and ``kinmo eval
pre-segmented`` (:class:`kinmo.refine.refine.RefineConfig`, Liu et al. 2023, Sec. 3.3)."""

from __future__ import annotations

from typing import Any, Optional

import typer

FEASIBILITY_ONLY = typer.Option(
    False, "--feasibility-only",
    help="Select candidate axes by the axis network alone (the paper's released code) instead of "
         "0.5 feasibility + 0.3 direction + 0.2 position.")
KEEP_GNN = typer.Option(
    False, "--keep-gnn", help="The GNN's own axis competes as a candidate (kinmo extension).")
SNAP_ANGLE: Any = typer.Option(
    None, "--snap-angle", min=0.0, max=90.0,
    help="Only candidates within this angle (deg) of the GNN's axis compete; none left: the GNN's "
         "axis, with no score (kinmo extension).")
BOX_FRAMES = typer.Option(
    "moving", "--box-frames",
    help="Comma-separated boxes giving the candidates: moving (the part's OBB, the paper), "
         "reference (the part boxed in its reference part's OBB axes), shape (boxed in the "
         "shape frame) (kinmo extension).")


def refine_config(feasibility_only: bool, keep_gnn: bool, snap_angle: Optional[float],  # noqa: UP007
                  box_frames: str) -> Any:
    """The :class:`~kinmo.refine.refine.RefineConfig` of the options above.

    Raises
    ------
    typer.Exit
        Code 2 after printing the problem, for invalid values (an unknown box frame).
    """
    from kinmo.cli._errors import fail
    from kinmo.refine.refine import RefineConfig
    from kinmo.refine.scoring import ScoringConfig

    frames = tuple(f.strip() for f in box_frames.split(",") if f.strip())
    try:
        return RefineConfig(scoring=ScoringConfig(feasibility_only=feasibility_only),
                            keep_gnn=keep_gnn, snap_angle_deg=snap_angle or None, box_frames=frames)
    except ValueError as e:
        fail(f"invalid refinement option: {e}", 2)
