"""Refine one moving edge: the paper's candidate scoring or the learned selector.

Liu et al. 2023, Sec. 3.3, for one sibling edge ``(moving, reference)`` the GNN predicts
moving:

- :func:`refine_edge` (the paper, ``selector="paper"``): the candidate lines of the
  predicted type (:func:`kinmo.refine.candidates.candidate_axes`, in the boxes of
  :attr:`~kinmo.refine.config.RefineConfig.box_frames`), each judged by the axis-selection
  network on the part moved about / along it (:func:`kinmo.refine.motions.candidate_motions`,
  :class:`~kinmo.refine.axis_net.AxisSelectionNet`) and scored ``0.5 feasibility +
  0.3 direction + 0.2 position`` (:func:`kinmo.refine.scoring.score_candidates`);
- :func:`select_edge` (kinmo extension, ``selector="ranker"``): candidates of every
  orientation ranked by the learned selector (:mod:`kinmo.refine.selector`,
  :mod:`kinmo.refine.ranker`); a hinge line's position re-chosen among the winner's parallel
  lines by the ranker's position stage (:mod:`kinmo.refine.position`).

With meshes, the learned selector vetoes motions the object's own geometry rules out
(:attr:`RefineConfig.sweep_vetoes`, kinmo extension, issue 36), by the swept test of its
features (the part against the rest of the object, contact at rest not counted):

- a **blocked slide** (:func:`blocked_slide_veto`): a slider line along which the part
  cannot move either way (the sweep frees less than :data:`BLOCKED_FREE`) gives way to the
  likeliest horizontal line free one way (at least :data:`OPEN_FREE`). The ranker's
  direction priors (the GNN's, the semantic prior's) hold in PartNet's frame, front +z; a
  drawer of a cabinet that faces +x (the ROS convention) is pulled to z, into the carcass's
  side walls, and a drawer typed a vertical slider (a lid, a button) is pushed into the
  carcass's floor and top. A blocked line of either orientation is replaced by a horizontal
  one only: a vertical line never replaces another (a drawer's own rails free its lift);
- a **slide blocked by the fixed parts** (:func:`fixed_parts_slide_veto`): the same veto,
  when every horizontal line is blocked against the rest of the object, judged against the
  parts predicted not to move, with its own bar (:data:`FIXED_PARTS_BLOCKED_FREE`). A drawer
  behind a closed door cannot slide out in the swept test (the door is in the way along its
  real line too), so the blocked-slide veto cannot act; against the carcass alone its front
  line is free and a sideways line still blocked (a ROS cabinet facing +x, issue 36);
- a **blocked hinge** (:func:`hinge_blocked`): when no candidate line of a revolute edge
  lets the part turn either way, :func:`kinmo.refine.refine.refine_predictions` tries the
  edge as a slider and keeps it when the chosen line is free one way (a drawer named
  or shaped like a flap);
- a **blocked spin** (:func:`spin_blocked`): a continuous revolute edge (``R_*_C``, a knob's
  or a wheel's free turn) whose chosen line is horizontal and cannot turn the part 18° either
  way (:data:`SPIN_BLOCKED_FREE`) is tried as a slider too, and kept when the chosen slider line runs along the blocked
  one (within :data:`SLIDE_ALONG_DEG`) and is free one way:
  the GNN found the line a drawer pulls out along and took it for a spin about it (ROS
  cabinets, issue 36). Hinges that are not continuous are left alone: PartNet meshes hold
  lids, doors and stapler arms interlocked, and a slide along their line would make them
  sliders (tried: out of fold, staplers, a safe door and a toilet lid became sliders);
- a **button slid across its face** (:func:`pressed_into_face`), in an object without known
  part names (the GNN's answer averaged over quarter turns, :attr:`GNNPriors.turned
  <kinmo.refine.selector.GNNPriors.turned>`) or for a part named a button or a key
  (:func:`pressable`; a name tells a button from a slider or a lever): a small part (at most
  :data:`PRESS_VOLUME_RATIO` of its reference's OBB volume) in contact with a reference
  predicted not to move, touching no part predicted to move, its centre beyond one face of
  the reference's OBB, its section along that face a cap's (:data:`PRESS_SECTION_RATIO`),
  typed a slider along a line across the face (at least :data:`PRESS_ACROSS_DEG` from its
  normal), is pressed along the normal instead, when a candidate line runs there (within
  :data:`PRESS_ALONG_DEG`) and is free one way. Of the labelled slider joints of such parts,
  246 of 247 run along the face's normal (remote and keyboard keys, camera, phone, oven and
  safe buttons); the one across is a slide switch. A toaster's lever, a long narrow tab
  sliding across the face, is what the section ratio leaves alone. Robot-learning button
  boxes and nail blocks were typed vertical sliders across the face they stick out of (issue
  36). A PartNet toaster whose lever (named ``slider``) has a button's square section is why
  other names keep the rule off. The rule needs no meshes.

Before the vetoes, the selector may defer to its priors (:mod:`kinmo.refine.defer`: the fine
ranker to a sure GNN, :func:`~kinmo.refine.defer.sure_prior`; the coarse ranker to the GNN and
the part names where they agree, :func:`~kinmo.refine.defer.agreeing_priors`; both rankers to
the GNN's direction where the type head cannot tell a slider from a hinge,
:func:`~kinmo.refine.defer.unsure_type`).

Both return an :class:`EdgeRefinement`: the chosen line (origin moved to the point nearest
the centre of the moving part's OBB, like the labels of :mod:`kinmo.data.labels`), its
feasible direction, and its confidence.

Frames and units: mesh frame (y-up), mesh units.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, replace

import numpy as np

from kinmo.data.graph import PartGraph
from kinmo.mobility_tree import obb_face
from kinmo.refine.candidates import (
    Candidates,
    candidate_axes,
    canonical_direction,
    frame_box,
    merge_candidates,
)
from kinmo.refine.config import RefineConfig
from kinmo.refine.defer import agreeing_priors, likeliest, sure_prior, unsure_type
from kinmo.refine.features import FEATURE_GROUPS, FEATURES
from kinmo.refine.position import freer_line, reposition
from kinmo.refine.motions import (
    candidate_motions,
    network_inputs,
    pair_cloud,
    shape_context,
)
from kinmo.refine.scoring import (
    CandidateScores,
    line_feasibility,
    score_candidates,
)
from kinmo.refine.selector import candidate_features, edge_candidates, freer_sign, line_sweeps

__all__ = ["BLOCKED_FREE", "FIXED_PARTS_BLOCKED_FREE", "OPEN_FREE", "PRESS_ACROSS_DEG",
           "PRESS_ALONG_DEG", "PRESS_NAMES", "PRESS_SECTION_RATIO", "PRESS_VOLUME_RATIO",
           "SLIDE_ALONG_DEG", "SPIN_BLOCKED_FREE", "EdgeRefinement", "blocked_slide_veto",
           "chosen_line", "fixed_parts_slide_veto",
           "hinge_blocked", "pressable", "pressed_into_face", "refine_edge", "select_edge",
           "spin_blocked", "switched_line", "vetoed_slides"]

#: A slider line is blocked when the swept test (``sweep_free_max``: the larger free fraction
#: of the two directions, :func:`kinmo.refine.selector.candidate_features`) is below this ...
BLOCKED_FREE = 0.1
#: ... and a line replacing it must be free for at least this fraction one way.
OPEN_FREE = 0.9
#: A blocked spin (:func:`spin_blocked`) becomes a slider only along its own line: the chosen
#: slider line at most this many degrees from it (and free one way, :data:`OPEN_FREE`).
SLIDE_ALONG_DEG = 20.0
#: A continuous turn (fine type ``R_*_C``: a knob, a wheel) is blocked (:func:`spin_blocked`)
#: when its chosen line frees less than this fraction of the swept test's quarter turn either
#: way: a part that cannot turn 18° either way is no free spin.
SPIN_BLOCKED_FREE = 0.2
#: The fixed-parts slide veto (:func:`fixed_parts_slide_veto`) judges a chosen line blocked,
#: against the whole object and against the fixed parts, below this fraction: IAI cabinet 2's
#: second drawer frees 0.108 along the side line it was given (the spin test's bar; the other
#: vetoes keep :data:`BLOCKED_FREE`).
FIXED_PARTS_BLOCKED_FREE = 0.2
#: A button (:func:`pressed_into_face`) has at most this fraction of its reference's OBB
#: volume ...
PRESS_VOLUME_RATIO = 0.1
#: ... its section along the face at least this ratio of its narrower to its wider side (a
#: button's cap, round or square; a toaster's lever or a slide switch's tab is a long, narrow
#: section that slides across the face in its slot) ...
PRESS_SECTION_RATIO = 0.5
#: ... in an object without known part names, or named as one of these words (every
#: labelled slider the rule's count holds is a ``button`` or a ``key``; the one across is a
#: ``switch``) ...
PRESS_NAMES = frozenset({"button", "key"})
#: ... a slide across its face is at least this many degrees from the face's normal ...
PRESS_ACROSS_DEG = 60.0
#: ... and the line it is pressed along instead at most this many.
PRESS_ALONG_DEG = 10.0
#: Largest ``|y|`` of a unit direction counted as horizontal (y-up; 60° from vertical).
_HORIZONTAL_Y = 0.5


@dataclass(frozen=True)
class EdgeRefinement:
    """The refinement of one moving edge.

    Attributes
    ----------
    candidates : Candidates
    scores : CandidateScores
    origin : (3,) float64
        Point of the chosen line nearest to the moving part's OBB centre.
    direction : (3,) float64
        Unit direction of the chosen line, signed by the feasible direction of motion.
    abstained : bool
        The best candidate disagreed with the GNN's direction
        (:attr:`RefineConfig.min_agreement`): ``origin`` and ``direction`` are the GNN's.
    calibrated : float or None
        The learned selector's calibrated confidence of the chosen line.
    dir_prior : (C,) float64 or None
        The learned selector's direction prior of every candidate (the GNN's mass on its
        direction), an input of the calibrated confidence.
    voted : bool
        The choice was changed by the repeated-parts vote (:mod:`kinmo.refine.repeated`).
    free : (C,) float64 or None
        The learned selector's swept test of every candidate (``sweep_free_max``: the larger
        free fraction of the two directions); None without meshes.
    deferred : bool
        The selector deferred to its priors (:mod:`kinmo.refine.defer`); the repeated-parts
        vote leaves such an edge alone.
    """

    candidates: Candidates
    scores: CandidateScores
    origin: np.ndarray
    direction: np.ndarray
    abstained: bool = False
    calibrated: float | None = None
    dir_prior: np.ndarray | None = None
    voted: bool = False
    free: np.ndarray | None = None
    deferred: bool = False

    @property
    def confidence(self) -> float:
        """Score of the chosen candidate (NaN without candidates).

        With the learned selector (:attr:`RefineConfig.selector` ``"ranker"``), the
        calibrated probability that the chosen line is right (``calibrated``).

        When the GNN's own line won (:attr:`RefineConfig.keep_gnn`), the best score of the
        geometric candidates instead: the line's agreement with itself is 1 by construction
        and says nothing, so the confidence keeps the paper's meaning (a feasible geometric
        axis agrees with the GNN) and keeping the GNN's axis never changes which joints pass
        a pseudo-label threshold.
        """
        if self.calibrated is not None:
            return float(self.calibrated)
        b = self.scores.best
        if b < 0 or self.candidates.kinds[b] != "gnn":
            return self.scores.confidence
        geo = [k for k, kind in enumerate(self.candidates.kinds) if kind != "gnn"]
        return float(np.max(self.scores.total[geo])) if geo else float("nan")

    @property
    def kind(self) -> str:
        """Kind of the chosen candidate (``"edge"``, ``"center"``, ``"interaction"``,
        ``"axis"``), ``"gnn"`` when the refinement abstained or the GNN's own line won
        (:attr:`RefineConfig.keep_gnn`)."""
        return "gnn" if self.abstained else self.candidates.kinds[self.scores.best]


def refine_edge(
    graph: PartGraph,
    moving: int,
    reference: int,
    motion_type: str,
    gnn_direction: np.ndarray,
    gnn_origin: np.ndarray,
    axis_model,
    config: RefineConfig | None = None,
    rng: np.random.Generator | int | None = None,
) -> EdgeRefinement:
    """Refine the axis of one edge ``(moving, reference)``.

    Parameters
    ----------
    graph : PartGraph
    moving, reference : int
        Node indices.
    motion_type : str
        Predicted fine or coarse type with an axis.
    gnn_direction, gnn_origin : (3,) float
        The GNN's axis (mesh frame).
    axis_model : AxisSelectionNet
    config : RefineConfig, optional
    rng : numpy Generator or int, optional
        Point subsampling (default: ``config.seed``).

    Returns
    -------
    EdgeRefinement
    """
    cfg = config or RefineConfig()
    rng = np.random.default_rng(cfg.seed if rng is None else rng)
    obb = (graph.obb_center[moving], graph.obb_axes[moving], graph.obb_half_extents[moving])
    diag = max(2.0 * float(np.linalg.norm(graph.obb_half_extents[moving])), 1e-12)
    cands = None
    for frame in dict.fromkeys(cfg.box_frames):  # in order, once each
        if frame == "moving":
            box = obb
        else:
            axes = graph.obb_axes[reference] if frame == "reference" else np.eye(3)
            box = frame_box(graph.points[moving], axes)
        c = candidate_axes(box, motion_type, graph.points[moving], graph.points[reference],
                           interaction_radius=cfg.interaction_radius)
        cands = c if cands is None else merge_candidates(
            cands, c, angle_deg=cfg.merge_angle_deg, distance=cfg.merge_distance * diag)
    assert cands is not None  # box_frames has at least one frame (RefineConfig)
    g = np.asarray(gnn_direction, dtype=np.float64)
    g = g / np.linalg.norm(g)
    if cfg.snap_angle_deg is not None:
        close = np.abs(cands.directions @ g) >= np.cos(np.radians(cfg.snap_angle_deg)) - 1e-12
        cands = cands.subset(close)
    if cfg.keep_gnn:
        cands = Candidates(np.vstack([cands.origins, np.asarray(gnn_origin, float)[None]]),
                           np.vstack([cands.directions, canonical_direction(g)[None]]),
                           (*cands.kinds, "gnn"), cands.motion_type)
    if len(cands) == 0:  # snap_angle_deg left nothing: keep the GNN's axis, no confidence
        z = np.zeros(0)
        empty = CandidateScores(z, z, z, z, np.zeros(0, dtype=np.int64), -1)
        return EdgeRefinement(cands, empty, np.asarray(gnn_origin, dtype=np.float64).copy(), g,
                              abstained=True)
    feas, sign = _network_feasibility(graph, moving, reference, cands, axis_model, cfg, rng)
    scores = score_candidates(cands.origins, cands.directions, feas, gnn_direction, gnn_origin,
                              diag, cands.motion != "P", cfg.scoring, sign)
    b = scores.best
    if cfg.min_agreement is not None and scores.direction[b] < cfg.min_agreement:
        return EdgeRefinement(cands, scores, np.asarray(gnn_origin, dtype=np.float64).copy(),
                              g, abstained=True)
    return EdgeRefinement(cands, scores, *chosen_line(graph, moving, cands, b, scores.sign[b]))


def chosen_line(graph: PartGraph, moving: int, cands: Candidates, b: int, sign: int
                ) -> tuple[np.ndarray, np.ndarray]:
    """Origin (nearest the moving OBB's centre, (3,) float64) and signed unit direction
    ((3,) float64) of candidate ``b`` of the moving part ``moving``, mesh frame."""
    d = cands.directions[b] * sign
    c = graph.obb_center[moving]
    return cands.origins[b] + float(np.dot(c - cands.origins[b], d)) * d, d


def _network_feasibility(graph: PartGraph, moving: int, reference: int, cands: Candidates,
                         axis_model, cfg: RefineConfig, rng: np.random.Generator
                         ) -> tuple[np.ndarray, np.ndarray]:
    """Axis-network feasibility ``(C,)`` and better sign ``(C,)`` of each candidate line."""
    import torch

    obb = (graph.obb_center[moving], graph.obb_axes[moving], graph.obb_half_extents[moving])
    mot = candidate_motions(cands, obb, cfg.amounts)
    n = cfg.n_points or axis_model.config.n_points
    frac = axis_model.config.context_fraction
    ctx = shape_context(graph.points[0], graph.points[moving]) if frac > 0 else None
    pair = pair_cloud(graph.points[moving], graph.points[reference], n, rng, ctx, frac,
                      axis_model.config.crop)
    rest, moved = network_inputs(pair, mot.origins, mot.directions, mot.angles, mot.translations)
    device = next(axis_model.parameters()).device
    s = axis_model.feasibility(torch.from_numpy(rest).to(device),
                               torch.from_numpy(moved).to(device), chunk=cfg.chunk).cpu().numpy()
    return line_feasibility(s, mot.line, mot.sign, len(cands))


def hinge_blocked(refinement: EdgeRefinement) -> bool:
    """True when no candidate line of a revolute edge lets the part turn: every line's swept
    test frees less than :data:`BLOCKED_FREE` either way (False without the sweep)."""
    f = refinement.free
    return f is not None and f.size > 0 and float(np.max(f)) < BLOCKED_FREE


def spin_blocked(refinement: EdgeRefinement, fine_type: str) -> bool:
    """True for a continuous revolute edge (fine type ``R_*_C``: a knob, a wheel) whose chosen
    line is horizontal and does not let the part turn: its swept test frees less than
    :data:`SPIN_BLOCKED_FREE` either way (False without the sweep or a choice)."""
    f, best = refinement.free, refinement.scores.best
    return fine_type.startswith("R_") and fine_type.endswith("_C") and f is not None and \
        0 <= best < len(f) and float(f[best]) < SPIN_BLOCKED_FREE and \
        abs(float(refinement.direction[1])) < _HORIZONTAL_Y


def vetoed_slides(cands: Candidates, free: np.ndarray | None) -> np.ndarray:
    """The lines the slide veto rules out (module docs): for a prismatic edge (``"P"``) with
    some horizontal line free one way (``>=`` :data:`OPEN_FREE`), its blocked lines
    (``<`` :data:`BLOCKED_FREE`).

    Parameters
    ----------
    cands : Candidates
        The edge's candidates (mesh frame, y-up).
    free : (C,) float64 or None
        Each line's ``sweep_free_max``; None (no meshes): nothing is ruled out.

    Returns
    -------
    (C,) bool
        True for a line the veto rules out; all False for other edges.
    """
    n = len(cands.directions)
    if cands.motion != "P" or free is None or not n:
        return np.zeros(n, dtype=bool)
    free = np.asarray(free, dtype=np.float64)
    if not _free_horizontal(cands, free).any():
        return np.zeros(n, dtype=bool)
    return free < BLOCKED_FREE


def _free_horizontal(cands: Candidates, free: np.ndarray) -> np.ndarray:
    """``(C,) bool``: horizontal lines (``|d_y| <`` ``_HORIZONTAL_Y``) free one way for at
    least :data:`OPEN_FREE`, the lines a vetoed slide may take instead."""
    return (np.abs(np.asarray(cands.directions)[:, 1]) < _HORIZONTAL_Y) & (free >= OPEN_FREE)


def blocked_slide_veto(cands: Candidates, features: np.ndarray, prob: np.ndarray, best: int) -> int:
    """The learned selector's choice for a slider, with a blocked slide replaced (module docs).

    Parameters
    ----------
    cands : Candidates
        The edge's candidates (mesh frame, y-up).
    features : (C, len(FEATURES)) float64
        Their features (:func:`kinmo.refine.selector.candidate_features`); without meshes
        ``sweep_free_max`` is 1 for every line and nothing changes.
    prob : (C,) float64
        The ranker's probabilities.
    best : int
        The ranker's choice.

    Returns
    -------
    int
        ``best``, unless the edge is prismatic (``"P"``; cylindrical and revolute edges are
        left alone), ``best`` is blocked (``sweep_free_max <`` :data:`BLOCKED_FREE`; horizontal
        or vertical) and some horizontal line is free one way (``>=`` :data:`OPEN_FREE`):
        then the most probable of those (:func:`vetoed_slides`).
    """
    if cands.motion != "P" or best < 0:
        return best
    free = np.asarray(features[:, FEATURES.index("sweep_free_max")], dtype=np.float64)
    if not vetoed_slides(cands, free)[best]:
        return best
    return likeliest(prob, _free_horizontal(cands, free))


def fixed_parts_slide_veto(graph: PartGraph, edge: int, refinement: EdgeRefinement, meshes,
                           fixed_leaves: np.ndarray, confidence=None) -> EdgeRefinement:
    """A slider's choice with a slide the fixed parts block replaced (module docs).

    The blocked-slide veto (:func:`blocked_slide_veto`) sweeps the part against everything
    outside its subtree, so a drawer behind a closed door finds no free line and keeps the
    ranker's choice, even one into the carcass's walls. Here the lines are swept again
    against ``fixed_leaves`` alone (the parts predicted not to move), and the veto's rule
    applies to that test with its own bar: a chosen line blocked (``<``
    :data:`FIXED_PARTS_BLOCKED_FREE`) gives way to the most probable horizontal line free one
    way (``>=`` :data:`OPEN_FREE`).

    Parameters
    ----------
    graph : PartGraph
    edge : int
        Row of ``graph.sibling_edges``; its first node is the moving part.
    refinement : EdgeRefinement
        The learned selector's choice (:func:`select_edge`) for a prismatic edge.
    meshes : kinmo.refine.selector.ShapeMeshes
        The shape's leaf meshes.
    fixed_leaves : (L,) int
        Graph leaves of the parts predicted not to move (outside every moving part's subtree).
    confidence : callable, optional
        ``(p, dir_prior) -> float``, the ranker's calibration
        (:meth:`kinmo.refine.ranker.Ranker.confidence`), for the new line's confidence.

    Returns
    -------
    EdgeRefinement
        ``refinement`` itself unless the veto acts: it acts only on a prismatic edge
        (``"P"``) whose chosen line frees less than :data:`FIXED_PARTS_BLOCKED_FREE` against
        the whole object, whose every horizontal line is blocked or not free enough against
        it (else :func:`blocked_slide_veto` has decided), whose chosen line frees less than
        :data:`FIXED_PARTS_BLOCKED_FREE` against the fixed parts, and that has a horizontal
        line free one way against them.
        Then the new line, signed by the freer side of the new sweep, with ``free`` the new
        sweep's (so :func:`vetoed_slides` judges it by the test that chose it).
    """
    r = refinement
    cands, b = r.candidates, r.scores.best
    if cands.motion != "P" or r.free is None or b < 0 or float(r.free[b]) >= FIXED_PARTS_BLOCKED_FREE \
            or _free_horizontal(cands, r.free).any():
        return r
    moving = int(graph.sibling_edges[edge][0])
    free, coll = line_sweeps(graph, moving, cands, meshes, np.asarray(fixed_leaves, np.int64))
    fmax = free.max(axis=1)
    ok = _free_horizontal(cands, fmax)
    if float(fmax[b]) >= FIXED_PARTS_BLOCKED_FREE or not ok.any():
        return r
    nb = likeliest(r.scores.total, ok)
    return switched_line(graph, moving, r, nb, confidence, sign=freer_sign(free, coll), free=fmax)


def switched_line(graph: PartGraph, moving: int, refinement: EdgeRefinement, best: int,
                  confidence=None, sign: np.ndarray | None = None, **changes) -> EdgeRefinement:
    """``refinement`` with candidate ``best`` chosen instead: its line (:func:`chosen_line`,
    signed by ``sign`` ``(C,) int64``, default the refinement's own), ``scores.best`` (and
    ``scores.sign``), and the calibrated confidence of the new line when ``confidence``
    (``(p, dir_prior) -> float``, :meth:`kinmo.refine.ranker.Ranker.confidence`) is given
    (its direction prior 1 when the refinement has none); ``changes`` are further fields.
    The vetoes and the repeated-parts vote (:mod:`kinmo.refine.repeated`) move a choice
    this way."""
    r = refinement
    sign = r.scores.sign if sign is None else sign
    o, d = chosen_line(graph, moving, r.candidates, best, int(sign[best]))
    calibrated = r.calibrated
    if confidence is not None:
        prior = 1.0 if r.dir_prior is None else float(r.dir_prior[best])
        calibrated = confidence(float(r.scores.total[best]), prior)
    return replace(r, scores=replace(r.scores, sign=sign, best=best), origin=o, direction=d,
                   calibrated=calibrated, **changes)


def pressable(name: str, unnamed: bool) -> bool:
    """Whether :func:`pressed_into_face` may judge a part named ``name``: in an object
    without known part names (``unnamed``: :attr:`GNNPriors.turned
    <kinmo.refine.selector.GNNPriors.turned>`), or when a word of its name (lower case,
    split at anything but letters) is one of :data:`PRESS_NAMES`. A ``slider``, a ``lever``
    or a ``switch`` is left to the model."""
    return unnamed or bool(set(re.split(r"[^a-z]+", name.lower())) & PRESS_NAMES)


def pressed_into_face(graph: PartGraph, edge: int, refinement: EdgeRefinement,
                      confidence=None) -> EdgeRefinement:
    """A small slider's choice with a slide across the face it sits on replaced by a press
    along that face's normal (module docs).

    The face is the one of the reference's OBB whose axis holds the largest share of the
    moving part's centre offset (offset over half extent, as the mobility tree's rule 2b,
    :func:`kinmo.mobility_tree.build_mobility_tree`); the part sits on it when that share is
    at least 1 (its centre beyond the face; a drawer inside its carcass is left alone).

    Parameters
    ----------
    graph : PartGraph
        Mesh frame (y-up), mesh units.
    edge : int
        Row of ``graph.sibling_edges``: ``(moving, reference)``. The caller checks that the
        part may be judged (:func:`pressable`), that the reference is predicted not to move and
        that the moving part touches no part predicted to move: a handle sliding across its
        moving drawer is the mobility tree's to fix to the drawer, and a handle on a drawer
        slides across the body's face with it.
    refinement : EdgeRefinement
        The learned selector's choice for the edge (:func:`select_edge`).
    confidence : callable, optional
        ``(p, dir_prior) -> float``, the ranker's calibration, for the new line's confidence.

    Returns
    -------
    EdgeRefinement
        ``refinement`` itself unless the rule acts: a prismatic edge (``"P"``; cylindrical
        ones are left alone) in contact (``sibling_contact``), the moving part at most
        :data:`PRESS_VOLUME_RATIO` of the reference's OBB volume and on one of its faces,
        its half widths along the face's other two axes (its OBB's support) within
        :data:`PRESS_SECTION_RATIO` of each other, the chosen line at least
        :data:`PRESS_ACROSS_DEG` from that face's normal, and a candidate within
        :data:`PRESS_ALONG_DEG` of the normal that is free one way (``free`` at least
        :data:`OPEN_FREE`; every line counts as free without meshes). Then the most probable
        such candidate, with the sign the selector found freer.
    """
    r = refinement
    cands, b = r.candidates, r.scores.best
    if cands.motion != "P" or b < 0 or not bool(np.asarray(graph.sibling_contact)[edge]):
        return r
    i, j = (int(x) for x in graph.sibling_edges[edge])
    half = np.asarray(graph.obb_half_extents, dtype=np.float64)
    vol = np.prod(2.0 * half[[i, j]], axis=1)
    if not (vol[1] > 0.0 and vol[0] <= PRESS_VOLUME_RATIO * vol[1]):
        return r
    axes = np.asarray(graph.obb_axes[j], dtype=np.float64)
    face, share = obb_face(graph.obb_center[i], graph.obb_center[j], axes, half[j])
    if share < 1.0:
        return r
    # the part's half widths (its OBB's support) along the face's two other axes: a cap, not
    # a lever's tab
    other = axes[[a for a in range(3) if a != face]]
    widths = np.sort(np.abs(other @ np.asarray(graph.obb_axes[i], dtype=np.float64).T) @ half[i])
    if not (widths[1] > 0.0 and widths[0] >= PRESS_SECTION_RATIO * widths[1]):
        return r
    dirs = np.asarray(cands.directions, dtype=np.float64)
    cos = np.abs(dirs @ axes[face]) / np.maximum(np.linalg.norm(dirs, axis=1), 1e-12)
    if float(cos[b]) > np.cos(np.radians(PRESS_ACROSS_DEG)):
        return r
    along = cos >= np.cos(np.radians(PRESS_ALONG_DEG))
    if r.free is not None:
        along &= np.asarray(r.free, dtype=np.float64) >= OPEN_FREE
    if not along.any():
        return r
    nb = likeliest(r.scores.total, along)
    return switched_line(graph, i, r, nb, confidence)


def select_edge(
    graph: PartGraph,
    edge: int,
    motion_type: str,
    gnn_direction: np.ndarray,
    gnn_origin: np.ndarray,
    priors,
    ranker,
    axis_model=None,
    config: RefineConfig | None = None,
    rng: np.random.Generator | int | None = None,
    meshes=None,
) -> EdgeRefinement:
    """Refine one edge with the learned selector (:mod:`kinmo.refine.selector`).

    Parameters
    ----------
    graph : PartGraph
    edge : int
        Row of ``graph.sibling_edges``.
    motion_type : str
        Predicted type (its coarse motion decides the candidates).
    gnn_direction, gnn_origin : (3,) float
        The GNN's axis (mesh frame).
    priors : kinmo.refine.selector.GNNPriors
    ranker : kinmo.refine.ranker.Ranker
    axis_model : AxisSelectionNet, optional
        Queried only when the ranker uses the ``feasibility`` feature.
    config : RefineConfig, optional
    rng : numpy Generator or int, optional
    meshes : kinmo.refine.selector.ShapeMeshes, optional
        The shape's leaf meshes (swept-collision terms); see
        :func:`kinmo.refine.selector.shape_meshes`.

    Returns
    -------
    EdgeRefinement
        ``scores.total`` holds the ranker's probabilities, ``scores.direction`` the ``|cos|``
        with the GNN's axis, ``scores.position`` the position prior, ``calibrated`` the
        confidence; the direction's sign is the one the collision proxy (or the network)
        finds freer.
    """
    cfg = config or RefineConfig()
    rng = np.random.default_rng(cfg.seed if rng is None else rng)
    i, j = (int(x) for x in graph.sibling_edges[edge])
    cands, frames = edge_candidates(graph, i, j, motion_type, gnn_direction, gnn_origin,
                                    interaction_radius=cfg.interaction_radius,
                                    merge_angle_deg=cfg.merge_angle_deg,
                                    merge_distance=cfg.merge_distance)
    feas = None
    net_sign = None
    if "feasibility" in ranker.features and axis_model is not None:
        feas, net_sign = _network_feasibility(graph, i, j, cands, axis_model, cfg, rng)
    proxy = net_sign is not None or any(f in ranker.features for f in FEATURE_GROUPS["collision"])
    x, sign = candidate_features(graph, i, j, edge, cands, frames, priors, gnn_direction,
                                 gnn_origin, feas, meshes, seed=cfg.seed, semantic=ranker.semantic,
                                 proxy=proxy)
    p = ranker.probabilities(x)
    chosen = ranker.choose(p, cands.directions)
    b = b0 = agreeing_priors(ranker, x, p, sure_prior(ranker, x, p, chosen))
    b = b0 = unsure_type(priors.motion(edge), x, p, b)
    deferred = b != chosen
    if cfg.sweep_vetoes:
        b = b0 = blocked_slide_veto(cands, x, p, b)
    if cands.motion != "P":
        b = reposition(ranker.position, x, cands.directions, b, np.log(np.maximum(p, 1e-12)))
        b = freer_line(x, p, cands.directions, b)
    sg = sign if net_sign is None else np.where(x[:, FEATURES.index("collide_max")] > 0,
                                                sign, net_sign)
    scores = CandidateScores(x[:, FEATURES.index("feasibility")], x[:, FEATURES.index("cos_gnn")],
                             x[:, FEATURES.index("pos_prior")], p, np.asarray(sg, np.int64), b)
    o, d = chosen_line(graph, i, cands, b, int(sg[b]))
    # the confidence is the first stage's (its calibration's meaning: the direction's winner;
    # the position stage moves the line, not the direction)
    conf = ranker.confidence(float(p[b0]), float(x[b0, FEATURES.index("dir_prior")]))
    return EdgeRefinement(cands, scores, o, d, calibrated=conf,
                          dir_prior=x[:, FEATURES.index("dir_prior")].copy(),
                          free=x[:, FEATURES.index("sweep_free_max")].copy() if meshes is not None else None,
                          deferred=deferred)
