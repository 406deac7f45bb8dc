"""The learned selector's second stage for hinge lines: where the axis is, once its direction is.

kinmo extension of the refinement of Liu et al. 2023, Sec. 3.3 (issue 34). The ranker of
:mod:`kinmo.refine.ranker` scores every candidate line of an edge at once. Its features are
mostly about direction (the GNN's axis-candidate mass, the semantic prior), and a door's four
edge lines share all of those: out of fold on the 235 labelled objects of the shared data,
85 of the 432 revolute edges whose winner had the right direction had their line more than
0.07 of the diagonal from the truth (a door hinged on the wrong edge), and 70 of them had a
right line among their candidates (docs/results/ranges.md).

The *position stage* is a second linear listwise ranker (the same
:func:`~kinmo.refine.ranker.fit_ranker`) over the position features
(:data:`POSITION_FEATURES`: the GNN's pivot and position priors, attachment, the swept
collision, the handle side, the candidate's kind and frame), on top of the first stage: a
line's score is the first stage's log-probability plus ``w . x`` (a fixed offset in the
fit), so the stage overrules the first stage only where the position evidence outweighs its
preference. It also moves a line only to a parallel one the part can turn about at least
about as freely by the swept test (:data:`FREE_SLACK`). Fit on its own, the stage learned
the doors' rules (a hinge lies away from the handle) and moved the scissors' pivots to a
blade's edge, about which the blades cannot turn; on top of the first stage it still moved
half of them; with the freeness rule, none. It is fit only on the candidates of a revolute edge that have the right direction (within
:data:`TRAIN_ANGLE_DEG` of the truth), labelled right within 0.05 of the diagonal, with the
first stage's out-of-fold log-probabilities. At inference it re-chooses among the candidates
parallel to the first stage's winner (within :data:`PARALLEL_DEG`), so the direction, and
every axis angle of Table 1, stays the first stage's (up to the 2° of parallel lines).

Out of fold on the 235 labelled objects (``kinmo eval oof``, 5 folds, the same fold GNNs;
docs/results/table1_four_settings.md), the joint line distance of ``OBB_fine`` fell from
0.0431 to 0.0373 of the diagonal pooled (0.0431 to 0.0412 per category), of ``OBB_coarse``
from 0.0372 to 0.0344 (0.0472 to 0.0456); the pooled hinge range IoU of ``OBB_fine`` rose
from 0.622 to 0.631 (docs/results/ranges.md).

It is fit with the first stage (:func:`fit_position`, called by
:func:`kinmo.refine.fit_selector.fit_selector`) and kept only when, on the same inner
cross-validation, it lowers the pooled line distance of the revolute groups' winners.

After both, :func:`freer_line` (no fit, issue 35) moves a hinge line to a nearly as likely
parallel one about which the part turns freer on its more blocked side: the first stage
ranked a laptop screen's two edge lines near its hinge alike and took the one inside the
keyboard, about which the closing screen meets the keyboard after 75-79 degrees. With it,
the position stage's freeness rule (:data:`FREE_SLACK`) now holds on both sides of the
swept test. Out of fold on the 235 labelled objects (the same fold GNNs), the two together
took the joint line distance of ``OBB_fine`` from 0.0352 to 0.0334 pooled (0.0508 to 0.0470
per category), of ``OBB_coarse`` from 0.0365 to 0.0339 (0.0480 to 0.0419), with the same
per-category axis angles (docs/results/table1_four_settings.md).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from kinmo.metrics.axis import axis_angle_deg
from kinmo.refine.features import FEATURE_INDEX
from kinmo.refine.groups import EdgeGroups, joint_means
from kinmo.refine.ranker import Ranker, fit_ranker

__all__ = ["FREER_GAIN", "FREER_PROB", "FREE_SLACK", "PARALLEL_DEG", "POSITION_FEATURES", "POSITION_L2",
           "TRAIN_ANGLE_DEG", "fit_position", "freer_line", "parallel_candidates", "position_groups",
           "reposition"]

#: Features of the position stage: everything about where a line is, nothing about which way
#: it points (the first stage's direction priors are equal on parallel lines anyway).
POSITION_FEATURES: tuple[str, ...] = (
    "pos_prior", "d_gnn", "pivot_prior", "attach_ref", "attach_any", "attach_mesh", "d_child",
    "d_child_edge", "sweep_free_min", "sweep_free_max", "sweep_coll_min", "sweep_coll_max",
    "kind_edge", "kind_center", "kind_interaction", "kind_axis", "kind_gnn", "frame_moving",
    "frame_reference", "frame_shape",
)

#: Lines within this angle (degrees) of the first stage's winner are its parallel candidates.
#: Candidates closer than ``RefineConfig.merge_angle_deg`` (2°) *and* close in position are
#: merged already, so parallel candidates differ in position.
PARALLEL_DEG: float = 2.0

#: The position stage only moves a line to a parallel one that lets the part turn at least
#: about as far (``sweep_free_max``, the free share of the selector's swept test, the
#: better of both ways, and ``sweep_free_min``, the worse; each no more than this below the
#: winner's; 1 for every line without meshes): the true hinge lets its part turn. Without
#: it the stage moved scissors pivots, free to turn, to blade edges the blades cannot turn
#: about (docs/results/ranges.md).
FREE_SLACK: float = 0.05

#: :func:`freer_line` moves a hinge line to a parallel one about which the part turns freer on
#: its more blocked side (``sweep_free_min``) by at least this share of the swept range.
FREER_GAIN: float = 0.15

#: ... and only to a line the first stage finds at least this likely, relative to its winner.
FREER_PROB: float = 0.5

#: Training candidates of the position stage: those within this angle (degrees) of the true
#: direction.
TRAIN_ANGLE_DEG: float = 10.0

#: The position stage's L2 weight (standardised features; the loss a mean over groups).
POSITION_L2: float = 0.1

#: A candidate is right in position within this line distance (fraction of the shape's
#: diagonal), as the first stage's labels (:func:`kinmo.refine.selector.candidate_labels`).
_RIGHT_DIST: float = 0.05


def parallel_candidates(directions: np.ndarray, best: int, max_deg: float = PARALLEL_DEG
                        ) -> np.ndarray:
    """Indices of the candidates parallel to candidate ``best`` (itself included).

    Parameters
    ----------
    directions : (C, 3) float64
        Candidate directions (non-zero; sign ignored).
    best : int
    max_deg : float
        Largest angle between two lines called parallel, degrees.

    Returns
    -------
    (K,) int64, ``K >= 1``
    """
    d = np.asarray(directions, dtype=np.float64).reshape(-1, 3)
    keep = np.atleast_1d(axis_angle_deg(d, d[best])) <= max_deg
    keep[best] = True
    return np.flatnonzero(keep)


def _as_free(x: np.ndarray, same: np.ndarray, best: int, blocked_gain: float) -> np.ndarray:
    """Which of the lines ``same`` let the part turn about them as freely as about ``best``:
    ``sweep_free_max`` (the freer side of the swept test) at least ``best``'s less
    :data:`FREE_SLACK`, and ``sweep_free_min`` (the more blocked side) at least ``best``'s plus
    ``blocked_gain`` (negative: a slack). ``(len(same),) bool``."""
    x = np.asarray(x, np.float64)
    hi, lo = x[:, FEATURE_INDEX["sweep_free_max"]], x[:, FEATURE_INDEX["sweep_free_min"]]
    return (hi[same] >= hi[best] - FREE_SLACK) & (lo[same] >= lo[best] + blocked_gain)


def reposition(position: Ranker | None, x: np.ndarray, directions: np.ndarray, best: int,
               base: np.ndarray | None = None) -> int:
    """The position stage's choice among the lines parallel to ``best``.

    Parameters
    ----------
    position : Ranker or None
        The position stage (:attr:`kinmo.refine.ranker.Ranker.position`); None returns ``best``.
    x : (C, len(FEATURES)) float64
        The edge's candidate features.
    directions : (C, 3) float64
        The candidates' directions.
    best : int
        The first stage's winner (of a revolute or cylindrical edge: callers decide).
    base : (C,) float64, optional
        The first stage's log-probabilities, added to the stage's scores (zeros without).

    Returns
    -------
    int
        A candidate index parallel to ``best`` whose ``sweep_free_max`` and
        ``sweep_free_min`` are each at least the winner's less :data:`FREE_SLACK` (``best``
        itself when it has no such one).
    """
    if position is None or best < 0:
        return best
    same = parallel_candidates(directions, best)
    same = same[_as_free(x, same, best, -FREE_SLACK)]
    if same.size < 2:
        return best
    score = position.scores(np.asarray(x)[same])
    if base is not None:
        score = score + np.asarray(base, np.float64)[same]
    return int(same[int(np.argmax(score))])


def freer_line(x: np.ndarray, prob: np.ndarray, directions: np.ndarray, best: int) -> int:
    """A parallel hinge line about which the part turns freer, where the first stage is unsure.

    The selector's swept test (:func:`kinmo.geometry.sweep_collisions`) turns the moving part
    about every candidate line both ways; ``sweep_free_min`` is the free share of the range on
    the more blocked side. A hinge line a few millimetres off the true one, inside the other
    part, stops a lid that closes onto its base early (a laptop's screen meets the keyboard's
    hull after 75-79 degrees instead of about 100: docs/results/ranges.md, "Which end fails"),
    while the first stage ranks the parallel edge lines of a lid nearly equal. Among the
    lines parallel to ``best`` that the first stage finds at least :data:`FREER_PROB` as
    likely, that are no less free on the freer side (``sweep_free_max``, within
    :data:`FREE_SLACK`) and freer on the more blocked side by at least :data:`FREER_GAIN`,
    the likeliest wins. A door turns into its cabinet about either edge line (both
    ``sweep_free_min`` near 0), so doors keep the first stage's and the position stage's
    choice. kinmo extension of Liu et al. 2023, Sec. 3.3 (issue 35).

    Parameters
    ----------
    x : (C, len(FEATURES)) float64
        The edge's candidate features.
    prob : (C,) float64
        The first stage's probabilities.
    directions : (C, 3) float64
        The candidates' directions.
    best : int
        The chosen line (negative: none, returned as is).

    Returns
    -------
    int
        ``best``, or a parallel candidate as above.
    """
    if best < 0:
        return best
    prob = np.asarray(prob, np.float64)
    same = parallel_candidates(directions, best)
    ok = same[(prob[same] >= FREER_PROB * prob[best]) & _as_free(x, same, best, FREER_GAIN)]
    if ok.size == 0:
        return best
    return int(ok[int(np.argmax(prob[ok]))])


def position_groups(groups: EdgeGroups
                    ) -> tuple[list[tuple[np.ndarray, np.ndarray]], np.ndarray, list[np.ndarray]]:
    """Training groups of the position stage.

    Parameters
    ----------
    groups : EdgeGroups
        Its features ``x`` ``(C, F)``, each candidate's ``angle`` to the truth (degrees) and
        line distance ``dist`` (/ diagonal), and whether the true joint turns (``revolute``).

    Returns
    -------
    (list of (x (K, F), y (K,) bool), (G',) int64, list of (K,) int64)
        One group per revolute edge with at least two candidates of the right direction,
        some but not all of them right in position (the others carry no position
        information); the index of each in the input; and the candidates kept of each.
    """
    out, idx, kept = [], [], []
    for n, (xs, a, d, rv) in enumerate(zip(groups.x, groups.angle, groups.dist, groups.revolute)):
        if not rv:
            continue
        m = np.asarray(a) < TRAIN_ANGLE_DEG
        if m.sum() < 2:
            continue
        y = np.asarray(d)[m] < _RIGHT_DIST
        if not y.any() or y.all():
            continue
        out.append((np.asarray(xs)[m], y))
        idx.append(n)
        kept.append(np.flatnonzero(m))
    return out, np.asarray(idx, np.int64), kept


def fit_position(groups: EdgeGroups, chosen: np.ndarray, base: Sequence[np.ndarray],
                 folds: np.ndarray, weights: np.ndarray, *, seed: int = 0
                 ) -> tuple[Ranker | None, dict[str, float]]:
    """Fit the position stage and decide, by cross-validation, whether to keep it.

    Parameters
    ----------
    groups : EdgeGroups
        The first stage's training groups, with ``directions`` (each group's candidate
        directions, ``(C, 3) float64``); ``category`` serves the per-category numbers only.
    chosen : (G,) int64
        The first stage's out-of-fold winner of every group.
    base : sequence of (C,) float64
        The first stage's out-of-fold log-probabilities of every group's candidates.
    folds : (G,) int64
        The inner cross-validation fold of every group (by shape, as the first stage's).
    weights : (G,) float64
        Per-joint weights of the groups (each moving part counts once,
        :func:`kinmo.refine.groups.joint_weights`).
    seed : int

    Returns
    -------
    (Ranker or None, dict)
        The stage fit on all groups, or None when there is too little data or its
        out-of-fold pooled line distance is not below the first stage's; and the numbers:
        ``position_groups``; ``position_dist_before`` / ``_after`` and
        ``position_cat_dist_before`` / ``_after``, the pooled and per-category mean line
        distance (per joint, revolute groups, / diagonal) of the first stage's winners and,
        out of fold, of the stage's, both moved by :func:`freer_line` as at inference;
        ``position_angle_before`` / ``_after`` the pooled angle; ``position_kept`` (1 or 0).
    """
    pairs, idx, kept = position_groups(groups)
    offsets = [np.asarray(base[n], np.float64)[m] for n, m in zip(idx, kept)]
    stats: dict[str, float] = {"position_groups": float(len(pairs))}
    rv = np.flatnonzero(np.asarray(groups.revolute, bool))
    if len(pairs) < 2 or rv.size == 0:
        return None, stats
    gf = np.asarray(folds)[idx]
    w = np.asarray(weights, np.float64)[rv]
    cat = np.asarray(groups.category)[rv]

    def means(v: Sequence[np.ndarray], c: np.ndarray) -> tuple[float, float]:
        return joint_means(np.array([v[n][c[n]] for n in rv], np.float64), w, cat)

    # both sides as at inference: the freer-line rule after the choice (select_edge); a fold
    # without a stage keeps the first stage's winners with the rule
    first = np.asarray(chosen, np.int64)
    prob = {int(n): np.exp(base[n]) for n in rv}
    chosen = first.copy()
    for n in rv:
        chosen[n] = freer_line(groups.x[n], prob[int(n)], groups.directions[n], int(first[n]))
    after = chosen.copy()
    for f in np.unique(folds):
        tr = np.flatnonzero(gf != f)
        if len(tr) < 2:
            continue
        r = fit_ranker([pairs[n] for n in tr], features=POSITION_FEATURES, l2=POSITION_L2,
                       seed=seed, offsets=[offsets[n] for n in tr])
        for n in rv[np.asarray(folds)[rv] == f]:
            b = reposition(r, groups.x[n], groups.directions[n], int(first[n]), base[n])
            after[n] = freer_line(groups.x[n], prob[int(n)], groups.directions[n], b)
    dist, angle = groups.dist, groups.angle
    (before, cat_before), (pooled, per_cat) = means(dist, chosen), means(dist, after)
    stats.update({"position_dist_before": before, "position_dist_after": pooled,
                  "position_cat_dist_before": cat_before, "position_cat_dist_after": per_cat,
                  "position_angle_before": means(angle, chosen)[0],
                  "position_angle_after": means(angle, after)[0],
                  "position_kept": float(pooled < before)})
    if not pooled < before:
        return None, stats
    ranker = fit_ranker(pairs, features=POSITION_FEATURES, l2=POSITION_L2, seed=seed,
                        offsets=offsets)
    ranker.meta.update({"stage": "position", "parallel_deg": PARALLEL_DEG,
                        "free_slack": FREE_SLACK, "train_angle_deg": TRAIN_ANGLE_DEG,
                        "l2": POSITION_L2, "cv": stats})
    return ranker, stats
