"""Candidate scores and selection (kinmo.refine.scoring)."""

from __future__ import annotations

import numpy as np
import pytest

from kinmo.refine.scoring import (
    ScoringConfig,
    combine_scores,
    direction_agreement,
    line_feasibility,
    position_agreement,
    score_candidates,
)


def test_weighted_sum_with_paper_weights_and_custom_weights():
    s_f, s_d, s_p = np.array([0.9, 0.2]), np.array([0.5, 1.0]), np.array([0.1, 1.0])
    np.testing.assert_allclose(combine_scores(s_f, s_d, s_p),
                               [0.5 * 0.9 + 0.3 * 0.5 + 0.2 * 0.1, 0.5 * 0.2 + 0.3 + 0.2])
    cfg = ScoringConfig(w_feasibility=2.0, w_direction=1.0, w_position=1.0)
    np.testing.assert_allclose(combine_scores(s_f, s_d, s_p, cfg),
                               [(1.8 + 0.5 + 0.1) / 4, (0.4 + 1.0 + 1.0) / 4])
    only = ScoringConfig(feasibility_only=True)
    np.testing.assert_allclose(combine_scores(s_f, s_d, s_p, only), s_f)
    with pytest.raises(ValueError, match="weight"):
        ScoringConfig(w_feasibility=0, w_direction=0, w_position=0)
    with pytest.raises(ValueError):
        ScoringConfig(w_direction=-1)


def test_direction_and_position_agreement():
    d = np.array([[0, 1, 0], [0, -2, 0], [1, 0, 0], [1, 1, 0]], float)
    np.testing.assert_allclose(direction_agreement(d, [0, 3, 0]), [1, 1, 0, np.sqrt(0.5)])
    o = np.array([[0, 0, 0], [1, 0, 0], [3, 5, 0]], float)
    u = np.tile([0.0, 1.0, 0.0], (3, 1))
    # distances of (0, 7, 0) to the vertical lines: 0, 1, 3; L = 2, sigma = 0.5 -> d / 1
    np.testing.assert_allclose(position_agreement(o, u, [0, 7, 0], 2.0, 0.5, "exp"),
                               np.exp(-np.array([0.0, 1.0, 3.0])))
    np.testing.assert_allclose(position_agreement(o, u, [0, 7, 0], 4.0, 0.5, "linear"),
                               [1.0, 0.5, 0.0])
    with pytest.raises(ValueError, match="mode"):
        position_agreement(o, u, [0, 0, 0], 1.0, 0.5, "cubic")
    with pytest.raises(ValueError, match="directions"):
        direction_agreement(np.zeros((1, 3)), [0, 1, 0])


def test_line_feasibility_takes_the_better_direction_and_averages_amounts():
    # 2 lines x 2 signs x 2 amounts, ordered by line, sign (+1 first), amount
    scores = np.array([0.2, 0.4, 0.9, 0.7, 0.6, 0.6, 0.1, 0.3])
    line = np.repeat([0, 1], 4)
    sign = np.tile([1, 1, -1, -1], 2)
    f, s = line_feasibility(scores, line, sign, 3)
    np.testing.assert_allclose(f, [0.8, 0.6, 0.0])
    np.testing.assert_array_equal(s, [-1, 1, 1])


def test_selection_feasibility_vs_weighted_and_prismatic_position():
    # candidate 0: feasible but off the GNN axis; candidate 1: on the GNN axis, less feasible
    o = np.array([[1.0, 0, 0], [0.0, 0, 0]])
    d = np.array([[0.0, 1, 0], [0.0, 1, 0]])
    feas = np.array([0.8, 0.6])
    weighted = score_candidates(o, d, feas, [0, 1, 0], [0, 0.5, 0], 1.0, True)
    assert weighted.best == 1
    np.testing.assert_allclose(weighted.position, [np.exp(-4.0), 1.0])
    assert weighted.confidence == pytest.approx(0.5 * 0.6 + 0.3 + 0.2)
    only = score_candidates(o, d, feas, [0, 1, 0], [0, 0.5, 0], 1.0, True,
                            ScoringConfig(feasibility_only=True), sign=np.array([-1, 1]))
    assert only.best == 0 and only.confidence == pytest.approx(0.8) and only.sign[0] == -1
    pris = score_candidates(o, d, feas, [0, 1, 0], None, 1.0, False)
    np.testing.assert_allclose(pris.position, [1.0, 1.0])
    assert pris.best == 0
    with pytest.raises(ValueError, match="gnn_point"):
        score_candidates(o, d, feas, [0, 1, 0], None, 1.0, True)
    empty = score_candidates(np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0), [0, 1, 0],
                             None, 1.0, False)
    assert empty.best == -1 and np.isnan(empty.confidence)
