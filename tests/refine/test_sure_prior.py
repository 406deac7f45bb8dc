"""The learned selector defers to a sure GNN (kinmo.refine.defer.sure_prior)."""

from __future__ import annotations

import numpy as np

from kinmo.refine.defer import (
    NAMED_UNSURE_CONFIDENCE,
    PRIOR_AGAINST,
    PRIOR_SURE,
    PRIORS_AGREE_NAMES,
    UNSURE_CONFIDENCE,
    sure_prior,
)
from kinmo.refine.features import FEATURES

_PRIOR = FEATURES.index("dir_prior")
_NAMES = FEATURES.index("sem_prior")


class _Ranker:
    """A stand-in whose calibrated confidence is the winner's probability times 0.2."""

    features = ("dir_prior", "orient_prior")

    def confidence(self, p_max: float, dir_prior: float = 1.0) -> float:
        return 0.2 * p_max


def _x(prior, names=None):
    x = np.zeros((len(prior), len(FEATURES)))
    x[:, _PRIOR] = prior
    if names is not None:
        x[:, _NAMES] = names
    return x


def test_an_unsure_choice_against_a_sure_gnn_gives_way_to_the_gnns_likeliest_line():
    # an oven knob: the type head says horizontal, the axis head is sure of the vertical
    x = _x([0.0, 0.0, 1.0, 1.0])
    p = np.array([0.2, 0.1, 0.05, 0.15])
    assert sure_prior(_Ranker(), x, p, 0) == 3


def test_otherwise_the_choice_stands():
    p = np.array([0.2, 0.1, 0.05, 0.15])
    # the GNN is not sure enough of any direction
    assert sure_prior(_Ranker(), _x([0.0, 0.0, PRIOR_SURE - 0.01, 0.0]), p, 0) == 0
    # the choice has some of the GNN's mass
    assert sure_prior(_Ranker(), _x([PRIOR_AGAINST, 0.0, 1.0, 1.0]), p, 0) == 0
    # the selector is confident (0.2 x 0.6 >= UNSURE_CONFIDENCE)
    assert 0.2 * 0.6 >= UNSURE_CONFIDENCE
    assert sure_prior(_Ranker(), _x([0.0, 0.0, 1.0, 1.0]), np.array([0.6, 0.1, 0.1, 0.2]), 0) == 0
    # no candidate
    assert sure_prior(_Ranker(), _x([0.0]), np.array([1.0]), -1) == -1
    # a ranker without the fine type's orientation prior (the coarse one) never defers
    coarse = _Ranker()
    coarse.features = ("dir_prior",)
    assert sure_prior(coarse, _x([0.0, 0.0, 1.0, 1.0]), p, 0) == 0


def test_a_choice_against_a_sure_gnn_and_the_part_names_gives_way_below_the_higher_bar():
    # a door the GNN is sure is hinged vertically, and the name prior agrees; the selector
    # turned it horizontal with a calibrated confidence between the two bars
    p = np.array([1.5, 0.1, 0.05, 0.15]) / 1.8  # confidence 0.2 x 0.83 = 0.17
    conf = 0.2 * p[0]
    assert UNSURE_CONFIDENCE <= conf < NAMED_UNSURE_CONFIDENCE
    x = _x([0.0, 0.0, 1.0, 1.0], names=[0.1, 0.1, PRIORS_AGREE_NAMES, PRIORS_AGREE_NAMES])
    assert sure_prior(_Ranker(), x, p, 0) == 3
    # only the named candidates of the GNN's direction are eligible
    x = _x([0.0, 0.0, 1.0, 1.0], names=[0.1, 0.1, 0.9, 0.0])
    assert sure_prior(_Ranker(), x, p, 0) == 2
    # without the names' agreement the lower bar holds, and the choice stands
    x = _x([0.0, 0.0, 1.0, 1.0], names=[0.9, 0.9, PRIORS_AGREE_NAMES - 0.01, 0.0])
    assert sure_prior(_Ranker(), x, p, 0) == 0
    # a selector at or above the higher bar keeps its choice against both witnesses
    p_sure = np.array([0.95, 0.01, 0.01, 0.03])
    assert 0.2 * p_sure[0] < NAMED_UNSURE_CONFIDENCE  # the stand-in's scale: raise it
    r = _Ranker()
    r.confidence = lambda p_max, dir_prior=1.0: NAMED_UNSURE_CONFIDENCE
    x = _x([0.0, 0.0, 1.0, 1.0], names=[0.0, 0.0, 1.0, 1.0])
    assert sure_prior(r, x, p_sure, 0) == 0
