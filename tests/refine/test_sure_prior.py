"""The learned selector defers to a sure GNN (kinmo.refine.defer.sure_prior)."""

from __future__ import annotations

import numpy as np

from kinmo.refine.defer import PRIOR_AGAINST, PRIOR_SURE, UNSURE_CONFIDENCE, sure_prior
from kinmo.refine.features import FEATURES

_PRIOR = FEATURES.index("dir_prior")


class _Ranker:
    """A stand-in whose calibrated confidence is the winner's probability times 0.2."""

    features = ("dir_prior", "orient_prior")

    def confidence(self, p_max: float, dir_prior: float = 1.0) -> float:
        return 0.2 * p_max


def _x(prior):
    x = np.zeros((len(prior), len(FEATURES)))
    x[:, _PRIOR] = prior
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
