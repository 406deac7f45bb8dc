"""When the learned selector defers to its priors (kinmo extension of Liu et al. 2023, Sec. 3.3).

The learned selector (:func:`kinmo.refine.edge.select_edge`) ranks candidate lines by geometry
and priors together. Two rules, applied to its choice before the sweep vetoes, let the priors
win where the ranker's geometric terms overrule them against the evidence:

- a **sure GNN** (:func:`sure_prior`): when the selector's choice gets almost none of the
  GNN's axis-candidate mass (below :data:`PRIOR_AGAINST`), the GNN puts nearly all of it on
  another direction (at least :data:`PRIOR_SURE`), and the selector's own calibrated
  confidence is below :data:`UNSURE_CONFIDENCE`, the likeliest line of the GNN's direction
  wins. An oven's knobs typed ``R_H_S`` by the type head, whose axis head was sure of the
  vertical, had been turned horizontal by the type's orientation prior. Only rankers that
  weigh that prior (``orient_prior``: the fine one) defer; out of fold, the coarse ranker's
  deferrals turned one right dishwasher joint 90° off (docs/results/table1_four_settings.md).
  Where the part-name prior (``sem_prior``) also puts at least :data:`PRIORS_AGREE_NAMES` on
  the GNN's direction, two witnesses stand against the choice, and it gives way below the
  higher confidence :data:`NAMED_UNSURE_CONFIDENCE`: out of fold (fold seed 1) the fine
  selector had turned the sure, named doors of Door 8877 and StorageFurniture 46456 and 46490
  horizontal at confidences 0.19 to 0.39, while the named choices it makes against a sure GNN
  and is right about (Knife 101108's blades, both fold seeds) sit at 0.38 to 0.54; the bar
  lies below the lowest of those (docs/results/table1_four_settings.md, session 34).
- **the priors agree** (:func:`agreeing_priors`), for a ranker that does not weigh the fine
  type's orientation prior (``orient_prior``: the coarse one): the GNN puts at least
  :data:`PRIORS_AGREE_GNN` of its mass on one direction, the part-name prior (``sem_prior``,
  :mod:`kinmo.refine.semantic_prior`) at least :data:`PRIORS_AGREE_NAMES` on it, and the
  choice lies on a direction the GNN gives at most ``1 - PRIORS_AGREE_GNN``. The coarse
  selector's geometric terms (a line on the OBB edge across a door, the handle's side) had
  turned sure, named cabinet doors horizontal; the coarse types carry no orientation at all
  (out of fold, both fold seeds: docs/results/table1_four_settings.md). Parts with names the
  prior does not know get its motion-level share only, so the rule can fire for them too.
  The fine ranker weighs the orientation prior with the GNN's mass and the names itself, and
  the rule's overrides of it went both ways: out of fold it fixed cabinet and room doors on
  one fold seed and, with session 28's GNNs, fired on three joints, all of them right before
  and 90° off after (Knife 101108's blades, Fan 101450; session 32), so it no longer applies
  to the fine ranker.

A third rule, for both rankers, defers to the GNN's direction where the *type* is unsure:

- **an unsure type** (:func:`unsure_type`, session 51): when the type head gives both the
  sliding and the turning types at least :data:`TYPE_UNSURE`, the likeliest candidate line
  along the GNN's axis direction wins over a choice across it. The candidate lines are made
  for the predicted type, so a hinge typed a slider is offered slides (and a slider typed a
  hinge, hinge lines), and the ranker picks the freest of the wrong kind; the axis head is
  not tied to the type's guess. Out of fold on the 235 labelled objects (fold seeds 0–2),
  6 fine joints came to the right axis (Switch 102872's lever 90° → 0°; Toaster 103555,
  twice, and 103482; Safe 101611; WashingMachine 103508) and none left it, while TrashCan
  102181 gained an unmatched link on fold seed 2. Of the coarse joints, 3 came right
  (TrashCan 102181, CoffeeMachine 103069, Keyboard 7619) and FoldingChair 100568's seat went
  0° → 90° on fold seed 2. Per-category mean OBB_fine error: 13.32° → 12.82°, 11.50° →
  11.35°, 10.47° → 9.99°; OBB_coarse: 11.99° → 11.53°, unchanged, 10.84° → 12.78° (that
  seat alone is a category); pooled, both settings fell or stayed on every seed
  (docs/results/table1_four_settings.md).

All three mark the edge deferred (:attr:`kinmo.refine.edge.EdgeRefinement.deferred`), so the
repeated-parts vote (:mod:`kinmo.refine.repeated`) leaves it alone.
"""

from __future__ import annotations

import numpy as np

from kinmo.refine.features import FEATURES
from kinmo.refine.ranker import DIRECTION_TOL_DEG

__all__ = ["NAMED_UNSURE_CONFIDENCE", "PRIOR_AGAINST", "PRIOR_SURE", "PRIORS_AGREE_GNN", "PRIORS_AGREE_NAMES",
           "TYPE_UNSURE", "UNSURE_CONFIDENCE", "agreeing_priors", "likeliest", "sure_prior", "unsure_type"]

#: :func:`sure_prior`: the GNN's axis head holds at least this mass on one direction ...
PRIOR_SURE = 0.95
#: ... the selector's choice at most this much ...
PRIOR_AGAINST = 0.05
#: ... and the selector's calibrated confidence in its choice is below this ...
UNSURE_CONFIDENCE = 0.1
#: ... or below this one, where the part-name prior also holds at least
#: :data:`PRIORS_AGREE_NAMES` on the GNN's direction (two witnesses against the choice).
NAMED_UNSURE_CONFIDENCE = 0.3
#: :func:`agreeing_priors`: the GNN's axis head holds at least this mass on one direction ...
PRIORS_AGREE_GNN = 0.9
#: ... and the part-name prior (``sem_prior``) at least this share on it.
PRIORS_AGREE_NAMES = 0.5
#: :func:`unsure_type`: the type head gives both the sliding types and the turning types at
#: least this much probability. Out of fold (fold seeds 0–2, fine networks, session 51), of
#: the 14, 20 and 13 matched joints so unsure, the GNN's own direction beat the selector's
#: choice by more than 5° on 2, 3 and 1 and lost on none; at 0.2 one Suitcase hinge (seed 0)
#: lost.
TYPE_UNSURE = 0.25


def likeliest(scores: np.ndarray, mask: np.ndarray) -> int:
    """Index of the highest of ``scores`` among the candidates ``mask`` keeps (the first on a
    tie): the choice every deferral and veto here and in :mod:`kinmo.refine.edge` falls back
    to.

    Parameters
    ----------
    scores : (C,) float
        The ranker's probabilities or the candidates' total scores.
    mask : (C,) bool
        The candidates allowed; at least one.

    Raises
    ------
    ValueError
        ``mask`` keeps no candidate.
    """
    idx = np.flatnonzero(mask)
    return int(idx[np.argmax(np.asarray(scores, dtype=np.float64)[idx])])


def sure_prior(ranker, features: np.ndarray, prob: np.ndarray, best: int) -> int:
    """The learned selector's choice, or the GNN's direction where the GNN is sure and the
    selector is not (module docstring).

    Parameters
    ----------
    ranker : kinmo.refine.ranker.Ranker
        Its ``features`` and calibrated confidence (:meth:`~kinmo.refine.ranker.Ranker.confidence`).
    features : (C, len(FEATURES)) float64
        The candidates' features; ``dir_prior`` is the GNN's axis-candidate mass on each
        candidate's direction.
    prob : (C,) float64
        The ranker's probabilities.
    best : int
        The selector's choice.

    Returns
    -------
    int
        ``best``, unless the ranker weighs the fine type's orientation prior
        (``orient_prior``: only such a ranker can overrule a sure axis head), the ``dir_prior``
        of ``best`` is below :data:`PRIOR_AGAINST`, some candidate's is at least
        :data:`PRIOR_SURE` and the calibrated confidence of ``best`` is below
        :data:`UNSURE_CONFIDENCE`: then the most probable of the candidates the GNN is sure
        of. Below :data:`NAMED_UNSURE_CONFIDENCE` the same holds for the candidates the GNN
        is sure of whose ``sem_prior`` (the part-name prior's share) is at least
        :data:`PRIORS_AGREE_NAMES`.
    """
    if best < 0 or "orient_prior" not in ranker.features:
        return best
    prior = np.asarray(features[:, FEATURES.index("dir_prior")], dtype=np.float64)
    if prior[best] >= PRIOR_AGAINST or prior.max() < PRIOR_SURE:
        return best
    conf = ranker.confidence(float(prob[best]), float(prior[best]))
    ok = prior >= PRIOR_SURE
    if conf >= UNSURE_CONFIDENCE:  # only a GNN the part names back may still win
        ok &= np.asarray(features[:, FEATURES.index("sem_prior")]) >= PRIORS_AGREE_NAMES
        if conf >= NAMED_UNSURE_CONFIDENCE or not ok.any():
            return best
    return likeliest(prob, ok)


def unsure_type(motion: tuple[float, float], features: np.ndarray, prob: np.ndarray, best: int) -> int:
    """The learned selector's choice, or the likeliest line along the GNN's direction where
    the type head cannot tell a slider from a hinge (module docstring).

    The candidate lines are made for the predicted type (:mod:`kinmo.refine.candidates`): a
    slider's lines are the directions it may slide along, a hinge's the lines it may turn
    about. When the type is a near guess between the two, the candidates answer the wrong
    question as often as the right one, while the GNN's axis head, trained on the true axis
    of either type, is not tied to the guess: a lever switch typed a slider (P 0.72, R 0.27)
    had its hinge line turned into a free slide 90° off.

    Parameters
    ----------
    motion : (float, float)
        The edge's sliding and turning type masses
        (:meth:`kinmo.refine.selector.GNNPriors.motion`).
    features : (C, len(FEATURES)) float64
        The candidates' features; ``cos_gnn`` is each line's ``|cos|`` with the GNN's axis,
        and a line within :data:`~kinmo.refine.ranker.DIRECTION_TOL_DEG` of it lies along it.
    prob : (C,) float64
        The ranker's probabilities.
    best : int
        The selector's choice.

    Returns
    -------
    int
        ``best``, unless both masses are at least :data:`TYPE_UNSURE`, ``best`` is not along
        the GNN's direction and some candidate is: then the most probable of those.
    """
    if best < 0 or min(motion) < TYPE_UNSURE:
        return best
    along = np.asarray(features[:, FEATURES.index("cos_gnn")]) >= np.cos(np.radians(DIRECTION_TOL_DEG))
    if along[best] or not along.any():
        return best
    return likeliest(prob, along)


def agreeing_priors(ranker, features: np.ndarray, prob: np.ndarray, best: int) -> int:
    """The learned selector's choice, or the direction that the GNN, the part-name prior and
    (for a ranker that weighs it) the fine type's orientation prior agree on (module
    docstring).

    Parameters
    ----------
    ranker, features, prob, best
        As :func:`sure_prior`; ``features`` also gives each candidate's ``sem_prior`` (the
        part-name prior's share).

    Returns
    -------
    int
        ``best`` for a ranker that weighs ``orient_prior`` (the fine one: module docstring).
        Otherwise ``best``, unless some candidates hold at least :data:`PRIORS_AGREE_GNN` of
        the GNN's mass and :data:`PRIORS_AGREE_NAMES` of the part-name prior while ``best``
        holds at most ``1 - PRIORS_AGREE_GNN`` of the GNN's: then the most probable of those
        candidates. kinmo extension of Liu et al. 2023, Sec. 3.3 (issue 34).
    """
    if best < 0 or "orient_prior" in ranker.features:
        return best
    prior = np.asarray(features[:, FEATURES.index("dir_prior")], dtype=np.float64)
    names = np.asarray(features[:, FEATURES.index("sem_prior")], dtype=np.float64)
    if prior[best] > 1.0 - PRIORS_AGREE_GNN:
        return best
    ok = (prior >= PRIORS_AGREE_GNN) & (names >= PRIORS_AGREE_NAMES)
    if not ok.any():
        return best
    return likeliest(prob, ok)
