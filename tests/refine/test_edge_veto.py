"""The learned selector's sweep vetoes: blocked slides and blocked hinges (kinmo.refine.edge, issue 36)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from kinmo.data.model import COARSE_TYPES, FINE_TYPES
from kinmo.refine.candidates import Candidates
from kinmo.refine.config import RefineConfig
from kinmo.refine.edge import BLOCKED_FREE, OPEN_FREE, EdgeRefinement, blocked_slide_veto, hinge_blocked
from kinmo.refine.features import FEATURES
from kinmo.refine.refine import as_slider
from kinmo.refine.scoring import CandidateScores

_FREE = FEATURES.index("sweep_free_max")
# y-up: +z (PartNet's front), +x (a cabinet facing +x), +y (vertical)
_DIRS = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])


def _case(free, motion_type="P_H"):
    cands = Candidates(np.zeros((3, 3)), _DIRS.copy(), ("axis", "axis", "axis"), motion_type)
    x = np.zeros((3, len(FEATURES)))
    x[:, _FREE] = free
    return cands, x, np.array([0.7, 0.2, 0.1])


def test_a_drawer_pulled_into_the_side_walls_slides_out_the_open_side():
    # the priors chose z, where the carcass blocks both ways; x is free one way
    cands, x, p = _case([0.04, 1.0, 0.38])
    assert blocked_slide_veto(cands, x, p, 0) == 1


def test_a_free_or_vertical_or_turning_choice_is_kept():
    # z free enough: kept
    cands, x, p = _case([BLOCKED_FREE, 1.0, 1.0])
    assert blocked_slide_veto(cands, x, p, 0) == 0
    # no horizontal line free enough (a vertical one is): kept, never turned vertical
    cands, x, p = _case([0.04, OPEN_FREE - 0.01, 1.0])
    assert blocked_slide_veto(cands, x, p, 0) == 0
    # a vertical choice free one way (a button pressed down, a lid lifted) is not vetoed
    cands, x, p = _case([1.0, 1.0, 0.95])
    assert blocked_slide_veto(cands, x, p, 2) == 2
    # hinges and cylindrical joints are left alone
    for t in ("R_H_S", "PR_H"):
        cands, x, p = _case([0.04, 1.0, 1.0], t)
        assert blocked_slide_veto(cands, x, p, 0) == 0
    # without meshes every line is free (sweep_free_max = 1): nothing changes
    cands, x, p = _case([1.0, 1.0, 1.0])
    assert blocked_slide_veto(cands, x, p, 0) == 0


def test_a_drawer_typed_a_vertical_slider_and_blocked_slides_out_the_front():
    # Meta-World's drawer: typed P_V, its vertical line meets the carcass's floor and top;
    # z (out of the open front) is free
    cands, x, p = _case([1.0, 0.02, 0.05], "P_V")
    assert blocked_slide_veto(cands, x, p, 2) == 0
    # no horizontal line free one way: the vertical choice stays
    cands, x, p = _case([0.5, 0.02, 0.05], "P_V")
    assert blocked_slide_veto(cands, x, p, 2) == 2


def test_of_the_free_horizontal_lines_the_likeliest_wins():
    cands = Candidates(np.zeros((4, 3)), np.vstack([_DIRS, [[-0.6, 0.0, 0.8]]]), ("axis",) * 4, "P_H")
    x = np.zeros((4, len(FEATURES)))
    x[:, _FREE] = [0.0, 0.95, 1.0, 1.0]
    assert blocked_slide_veto(cands, x, np.array([0.5, 0.1, 0.3, 0.2]), 0) == 3
    assert blocked_slide_veto(cands, x, np.array([0.5, 0.3, 0.1, 0.1]), 0) == 1


def test_a_hinge_none_of_whose_lines_turns_is_blocked():
    cands, x, p = _case([0.04, 0.09, 0.02], "R_H_S")
    scores = CandidateScores(np.full(3, 0.5), np.zeros(3), np.zeros(3), p, np.ones(3, np.int64), 0)
    r = EdgeRefinement(cands, scores, np.zeros(3), _DIRS[0], free=x[:, _FREE].copy())
    assert hinge_blocked(r)
    assert not hinge_blocked(dataclasses.replace(r, free=np.array([0.04, BLOCKED_FREE, 0.02])))
    assert not hinge_blocked(dataclasses.replace(r, free=None))  # no meshes: no veto


def test_a_switched_edge_moves_its_revolute_mass_to_the_slider_type():
    fine = np.array([[0.05, 0.05, 0.3, 0.4, 0.05, 0.05, 0.02, 0.02, 0.03, 0.03],
                     [0.1] * 10])
    out = as_slider(fine, FINE_TYPES, [0])
    names = list(FINE_TYPES)
    assert out[0, names.index("P_H")] == pytest.approx(0.05 + 0.3 + 0.4 + 0.05 + 0.05)
    assert all(out[0, c] == 0.0 for c, n in enumerate(names) if n.startswith("R_"))
    np.testing.assert_allclose(out.sum(axis=1), fine.sum(axis=1))
    np.testing.assert_array_equal(out[1], fine[1])  # other rows untouched
    np.testing.assert_array_equal(as_slider(fine, FINE_TYPES, []), fine)
    coarse = np.array([[0.1, 0.6, 0.1, 0.1, 0.1]])  # P, R, PR, Fixed, None
    c = as_slider(coarse, COARSE_TYPES, [0])
    np.testing.assert_allclose(c, [[0.7, 0.0, 0.1, 0.1, 0.1]])


def test_the_vetoes_are_on_by_default_and_can_be_turned_off():
    assert RefineConfig().sweep_vetoes is True
    assert RefineConfig(sweep_vetoes=False).sweep_vetoes is False
