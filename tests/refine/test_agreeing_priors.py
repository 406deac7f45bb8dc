"""The coarse learned selector follows the direction that the GNN and the part-name prior agree
on; the fine one, which weighs the fine type's orientation prior itself, keeps its choice
(kinmo.refine.defer.agreeing_priors)."""

from __future__ import annotations

import numpy as np

from kinmo.refine.defer import PRIORS_AGREE_GNN, PRIORS_AGREE_NAMES, agreeing_priors
from kinmo.refine.features import FEATURES

_PRIOR = FEATURES.index("dir_prior")
_NAMES = FEATURES.index("sem_prior")
_ORIENT = FEATURES.index("orient_prior")


class _Coarse:
    """A stand-in for the coarse ranker: no ``orient_prior``."""

    features = ("dir_prior", "sem_prior", "d_child_edge")


class _Fine:
    features = ("dir_prior", "sem_prior", "orient_prior")


def _x(prior, names, orient=None):
    x = np.zeros((len(prior), len(FEATURES)))
    x[:, _PRIOR] = prior
    x[:, _NAMES] = names
    x[:, _ORIENT] = prior if orient is None else orient
    return x


# a cabinet door: two lines across (horizontal, the ranker's choice by the OBB), three along
# the vertical, which the GNN (0.94) and the door's name (0.83) both give the hinge
_DOOR = _x([0.06, 0.06, 0.94, 0.94, 0.94], [0.17, 0.17, 0.83, 0.83, 0.83])
_P = np.array([0.32, 0.24, 0.15, 0.05, 0.13])


def test_a_choice_against_both_priors_gives_way_to_their_likeliest_line():
    assert agreeing_priors(_Coarse(), _DOOR, _P, 0) == 2


def test_the_fine_ranker_keeps_its_choice_even_where_every_prior_agrees():
    # the fine type's orientation agrees with the GNN and the names (a vertical hinge type):
    # the fine ranker weighs all three itself (Knife 101108's blades, where all three
    # priors point 90° from the annotated axes, and the ranker had them right)
    assert agreeing_priors(_Fine(), _DOOR, _P, 0) == 0
    flap = _x([0.06] * 2 + [0.94] * 3, [0.17] * 2 + [0.83] * 3, [1.0] * 2 + [0.0] * 3)
    assert agreeing_priors(_Fine(), flap, _P, 0) == 0
    assert agreeing_priors(_Coarse(), flap, _P, 0) == 2  # the coarse ranker does not weigh it


def test_otherwise_the_choice_stands():
    # the GNN is not sure enough
    g = PRIORS_AGREE_GNN - 0.02
    assert agreeing_priors(_Coarse(), _x([1 - g] * 2 + [g] * 3, [0.17] * 2 + [0.83] * 3), _P, 0) == 0
    # the names do not agree with the GNN
    n = PRIORS_AGREE_NAMES - 0.01
    assert agreeing_priors(_Coarse(), _x([0.06] * 2 + [0.94] * 3, [1 - n] * 2 + [n] * 3), _P, 0) == 0
    # the choice holds more than the GNN's remainder
    assert agreeing_priors(_Coarse(), _x([0.12, 0.12, 0.94, 0.94, 0.94], [0.17] * 2 + [0.83] * 3),
                           _P, 0) == 0
    # the choice is already the agreed direction
    assert agreeing_priors(_Coarse(), _DOOR, _P, 3) == 3
    # no candidate
    assert agreeing_priors(_Coarse(), _x([0.0], [0.0]), np.array([1.0]), -1) == -1
