"""The learned selector keeps the GNN's direction where the type is a near guess between a
slider and a hinge (kinmo.refine.defer.unsure_type, kinmo.refine.selector.GNNPriors.motion)."""

from __future__ import annotations

import numpy as np
import pytest

from kinmo.data.model import COARSE_TYPES, FINE_TYPES
from kinmo.refine.defer import TYPE_UNSURE, unsure_type
from kinmo.refine.features import FEATURES
from kinmo.refine.selector import GNNPriors

# a lever switch typed a slider: its candidates are slides along x, y and z; the GNN's axis is x
_DIRS = np.array([[0.0, 1.0, 0.02], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]])
_DIRS /= np.linalg.norm(_DIRS, axis=1, keepdims=True)  # candidates are unit directions
_P = np.array([0.39, 0.28, 0.23, 0.10])
_GNN = np.array([1.0, 0.0, 0.0])


def _fine(slide: float, turn: float) -> np.ndarray:
    tp = np.zeros(len(FINE_TYPES))
    tp[FINE_TYPES.index("P_H")] = slide
    tp[FINE_TYPES.index("R_H_S")] = turn
    tp[FINE_TYPES.index("Fixed")] = 1.0 - slide - turn
    return tp


def _choose(tp, names, gnn, best):
    """unsure_type on one edge: its type masses and the candidates' ``cos_gnn`` feature, as
    kinmo.refine.selector.candidate_features computes it."""
    x = np.zeros((len(_DIRS), len(FEATURES)))
    g = np.asarray(gnn, dtype=np.float64)
    x[:, FEATURES.index("cos_gnn")] = np.abs(_DIRS @ (g / max(float(np.linalg.norm(g)), 1e-12)))
    return unsure_type(GNNPriors(np.asarray(tp)[None], tuple(names)).motion(0), x, _P, best)


def test_a_near_guess_between_slide_and_turn_takes_the_likeliest_line_along_the_gnns_axis():
    assert _choose(_fine(0.72, 0.27), FINE_TYPES, _GNN, 0) == 1
    # either way round, coarse types too, and the GNN's axis with either sign
    assert _choose(_fine(0.3, 0.65), FINE_TYPES, -_GNN, 0) == 1
    coarse = np.zeros(len(COARSE_TYPES))
    coarse[COARSE_TYPES.index("P")], coarse[COARSE_TYPES.index("R")] = 0.5, 0.5
    assert _choose(coarse, COARSE_TYPES, _GNN, 0) == 1


def test_otherwise_the_choice_stands():
    # a sure type (just below the bar on the turning side)
    assert _choose(_fine(0.75, TYPE_UNSURE - 0.01), FINE_TYPES, _GNN, 0) == 0
    # the choice already lies along the GNN's axis
    assert _choose(_fine(0.72, 0.27), FINE_TYPES, _GNN, 3) == 3
    # no candidate along the GNN's axis
    assert _choose(_fine(0.72, 0.27), FINE_TYPES, np.array([1.0, 1.0, 0.0]), 0) == 0
    # cylindrical types count for neither side
    tp = np.zeros(len(FINE_TYPES))
    tp[FINE_TYPES.index("PR_V")], tp[FINE_TYPES.index("R_V_C")] = 0.6, 0.4
    assert _choose(tp, FINE_TYPES, _GNN, 0) == 0
    # no choice, no GNN axis
    assert _choose(_fine(0.5, 0.5), FINE_TYPES, _GNN, -1) == -1
    assert _choose(_fine(0.5, 0.5), FINE_TYPES, np.zeros(3), 0) == 0


def test_the_learned_selector_keeps_the_gnns_axis_for_an_unsure_type():
    """select_edge applies the rule: a door typed a slider, whose ranker prefers lines across
    the GNN's axis, keeps a line along that axis (its hinge's) when the type head is unsure."""
    from motion_cabinet import cabinet_graph

    from kinmo.refine.edge import select_edge
    from kinmo.refine.ranker import Ranker

    g = cabinet_graph()
    k = [int(e) for e, (i, j) in enumerate(g.sibling_edges) if (int(i), int(j)) == (2, 1)][0]
    w = np.zeros(len(FEATURES))
    w[FEATURES.index("cos_gnn")] = -3.0  # the geometry's stand-in: lines across the GNN's axis win
    ranker = Ranker(FEATURES, w, np.zeros(len(FEATURES)), np.ones(len(FEATURES)))
    gnn = np.array([0.0, 1.0, 0.0])

    def axis(slide, turn):
        tp = np.tile(_fine(0.0, 0.0), (len(g.sibling_edges), 1))
        tp[k] = _fine(slide, turn)
        r = select_edge(g, k, "P_H", gnn, g.obb_center[2], GNNPriors(tp, FINE_TYPES), ranker)
        return abs(float(np.asarray(r.direction) @ gnn)), r.deferred

    assert axis(0.9, 0.05) == (pytest.approx(0.0, abs=1e-6), False)
    assert axis(0.6, 0.35) == (pytest.approx(1.0), True)
