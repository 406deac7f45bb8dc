"""Options of the refinement (Liu et al. 2023, Sec. 3.3; kinmo extensions marked).

:class:`RefineConfig` is read by the per-edge refinement (:mod:`kinmo.refine.edge`), by the
dispatch over a shape's edges (:mod:`kinmo.refine.refine`) and by the CLI options
(:mod:`kinmo.cli._refine`); it lives apart so that those modules share it without importing
each other.
"""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, model_validator

from kinmo.refine.motions import MotionAmounts
from kinmo.refine.scoring import ScoringConfig

__all__ = ["RefineConfig"]


class RefineConfig(BaseModel):
    """Options of the refinement.

    Attributes
    ----------
    scoring : ScoringConfig
        Weights (paper: 0.5 / 0.3 / 0.2) or ``feasibility_only``.
    angles_deg : tuple of float
        Rotation angles of the candidate motions (degrees).
    translation_fraction : float
        Translation of the candidate motions, fraction of the part's OBB extent.
    interaction_radius : float
        Interaction-region radius, fraction of the moving part's OBB diagonal.
    n_points : int or None
        Network input points (default: the network's ``n_points``).
    seed : int
        Point subsampling seed (results are reproducible).
    chunk : int
        Moved clouds per network call.
    min_agreement : float or None
        kinmo extension (None: off, the paper's behaviour): when the chosen candidate's
        direction agreement ``|cos|`` with the GNN's axis is below this value, the refinement
        abstains and keeps the GNN's axis (kind ``"gnn"``; the confidence stays the
        candidate's low score). A wrong orientation in the predicted type (a door predicted
        ``P_H`` whose regressed axis is vertical) then costs the GNN's error, not 90°.
    snap_angle_deg : float or None
        kinmo extension (None: off, the paper's behaviour): only candidates whose line is
        within this angle (degrees) of the GNN's axis direction compete, so the refinement
        fixes the axis position and the sign of motion but keeps the GNN's orientation. When
        no candidate is that close the refinement abstains (kind ``"gnn"``, the GNN's axis,
        confidence NaN, which no pseudo-label threshold accepts).
    keep_gnn : bool
        kinmo extension (False: off, the paper's behaviour): the GNN's own axis line joins the
        candidates (kind ``"gnn"``), judged by the network like the others; its agreement
        terms are 1 by construction, so a geometric candidate replaces it only when it scores
        better overall.
    box_frames : tuple of {"moving", "reference", "shape"}
        Boxes whose edges, centre lines and axes give the candidates. ``("moving",)`` (the
        paper): the moving part's OBB. kinmo extension: ``"reference"`` adds the moving part's
        bounding box in its reference part's OBB axes, ``"shape"`` its box in the shape frame
        (:func:`kinmo.refine.candidates.frame_box`), so a part whose own OBB is tilted from
        its hinge (an opened laptop lid, a faucet handle) still gets the hinge as a candidate;
        lines within ``merge_angle_deg`` and ``merge_distance`` (fraction of the moving OBB's
        diagonal) of an earlier box's line are merged into it.
    merge_angle_deg, merge_distance : float
        Tolerances of that merge.
    selector : {"paper", "ranker"}
        ``"paper"``: the weighted score of :mod:`kinmo.refine.scoring` over the candidates of
        the predicted type (the options above apply). ``"ranker"`` (kinmo extension,
        :mod:`kinmo.refine.selector`): candidates of every orientation in all three box
        frames plus the GNN's line, scored by the learned ranker at ``ranker`` from soft GNN
        priors and geometric terms; the confidence is the ranker's calibrated probability
        that the selected line is right. ``scoring``, ``snap_angle_deg``, ``keep_gnn``,
        ``box_frames`` and ``min_agreement`` do not apply to it.
    ranker : str or None
        Path of the ranker file (``ranker.json``, :func:`kinmo.refine.ranker.load_ranker`);
        required by ``selector="ranker"``.
    vote_repeated : bool
        kinmo extension (issue 34): with the learned selector, copies of a part attached to
        the same reference part with the same predicted type (three or more: keys, buttons,
        a column of drawers) take the direction most of them chose
        (:mod:`kinmo.refine.repeated`).
    pair_doors : bool
        kinmo extension (issue 35): with the learned selector, two mirror parts side by side
        (a cabinet's two doors), each with one such neighbour, turn about their outer edges:
        a hinge line chosen at the seam moves to the part's parallel line on the other side
        (:mod:`kinmo.refine.paired`).
    sweep_vetoes : bool
        kinmo extension (issue 36): with the learned selector and meshes, a slider line
        (horizontal or vertical) blocked both ways by the swept test gives way to a
        horizontal line free one way
        (:func:`kinmo.refine.edge.blocked_slide_veto`), and a revolute edge none of whose
        lines can turn becomes a slider when one of its slider lines is free
        (:func:`kinmo.refine.edge.hinge_blocked`, :func:`kinmo.refine.refine.as_slider`), as
        does a continuous one whose chosen horizontal line cannot turn it, when it slides
        along that line (:func:`kinmo.refine.edge.spin_blocked`); a slider blocked every way
        by the whole object is judged again against the parts predicted not to move (a drawer
        behind a closed door, :func:`kinmo.refine.edge.fixed_parts_slide_veto`); and a
        button slid across the face it sits on is pressed along the face's normal, in an
        unnamed object or when named a button or a key
        (:func:`kinmo.refine.edge.pressed_into_face`, with or without meshes).
    ranges : str or None
        kinmo extension (issue 35): path of the range-of-motion prior (``ranges.json``,
        :class:`kinmo.ranges.RangePrior`); after the selector, every moving joint gets its
        learned range clipped by a sweep (:func:`kinmo.ranges.predict_ranges`). None: the
        mobility tree's default ranges.
    """

    model_config = ConfigDict(extra="forbid")

    scoring: ScoringConfig = Field(default_factory=ScoringConfig)
    angles_deg: tuple[float, ...] = (60.0,)
    translation_fraction: float = Field(0.5, gt=0)
    interaction_radius: float = Field(0.1, gt=0)
    n_points: int | None = Field(None, ge=2)
    seed: int = 0
    chunk: int = Field(16, ge=1)
    min_agreement: float | None = Field(None, ge=0, le=1)
    snap_angle_deg: float | None = Field(None, gt=0, le=90)
    keep_gnn: bool = False
    box_frames: tuple[Literal["moving", "reference", "shape"], ...] = Field(("moving",), min_length=1)
    merge_angle_deg: float = Field(2.0, ge=0, le=90)
    merge_distance: float = Field(0.02, ge=0)
    selector: Literal["paper", "ranker"] = "paper"
    ranker: str | None = None
    vote_repeated: bool = True
    pair_doors: bool = True
    sweep_vetoes: bool = True
    ranges: str | None = None

    @model_validator(mode="after")
    def _ranker_path(self) -> RefineConfig:
        if self.selector == "ranker" and not self.ranker:
            raise ValueError("refine: selector 'ranker' needs a ranker file (ranker=...)")
        return self

    @property
    def amounts(self) -> MotionAmounts:
        """The candidate motion amounts."""
        return MotionAmounts(tuple(self.angles_deg), self.translation_fraction)
