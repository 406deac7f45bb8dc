"""The blocked-slide veto of the learned selector (kinmo.refine.edge.blocked_slide_veto, issue 36)."""

from __future__ import annotations

import numpy as np

from kinmo.refine.candidates import Candidates
from kinmo.refine.config import RefineConfig
from kinmo.refine.edge import BLOCKED_FREE, OPEN_FREE, blocked_slide_veto
from kinmo.refine.features import FEATURES

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
    # a vertical choice (a button pressed down) is not vetoed
    cands, x, p = _case([1.0, 1.0, 0.0])
    assert blocked_slide_veto(cands, x, p, 2) == 2
    # hinges and cylindrical joints are left alone
    for t in ("R_H_S", "PR_H"):
        cands, x, p = _case([0.04, 1.0, 1.0], t)
        assert blocked_slide_veto(cands, x, p, 0) == 0
    # without meshes every line is free (sweep_free_max = 1): nothing changes
    cands, x, p = _case([1.0, 1.0, 1.0])
    assert blocked_slide_veto(cands, x, p, 0) == 0


def test_of_the_free_horizontal_lines_the_likeliest_wins():
    cands = Candidates(np.zeros((4, 3)), np.vstack([_DIRS, [[-0.6, 0.0, 0.8]]]), ("axis",) * 4, "P_H")
    x = np.zeros((4, len(FEATURES)))
    x[:, _FREE] = [0.0, 0.95, 1.0, 1.0]
    assert blocked_slide_veto(cands, x, np.array([0.5, 0.1, 0.3, 0.2]), 0) == 3
    assert blocked_slide_veto(cands, x, np.array([0.5, 0.3, 0.1, 0.1]), 0) == 1


def test_the_veto_is_on_by_default_and_can_be_turned_off():
    assert RefineConfig().veto_blocked_slides is True
    assert RefineConfig(veto_blocked_slides=False).veto_blocked_slides is False
