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


def test_a_spin_blocked_on_its_chosen_line_is_flagged_only_for_a_horizontal_continuous_hinge():
    from kinmo.refine.edge import SPIN_BLOCKED_FREE, spin_blocked

    cands, x, p = _case([0.04, 0.5, 0.9], "R_H_C")  # the chosen line (z) is blocked, others turn
    scores = CandidateScores(np.full(3, 0.5), np.zeros(3), np.zeros(3), p, np.ones(3, np.int64), 0)
    r = EdgeRefinement(cands, scores, np.zeros(3), _DIRS[0], free=x[:, _FREE].copy())
    assert not hinge_blocked(r) and spin_blocked(r, "R_H_C")
    assert not spin_blocked(r, "R_H_S")  # a door or a lid: PartNet holds them interlocked
    assert not spin_blocked(r, "P_H")
    # a spin that turns 9 degrees either way (IAI cabinet 11's drawer) is no free spin; one that
    # turns 18 degrees is left alone (a laptop screen freeing 0.248 must stay a hinge)
    assert spin_blocked(dataclasses.replace(r, free=np.array([BLOCKED_FREE, 0.5, 0.9])), "R_H_C")
    assert not spin_blocked(dataclasses.replace(r, free=np.array([SPIN_BLOCKED_FREE, 0.5, 0.9])), "R_H_C")
    assert not spin_blocked(dataclasses.replace(r, free=np.array([0.248, 0.5, 0.9])), "R_H_C")
    assert not spin_blocked(dataclasses.replace(r, free=None), "R_H_C")  # no meshes: no veto
    vertical = dataclasses.replace(r, scores=dataclasses.replace(scores, best=2), direction=_DIRS[2],
                                   free=np.array([0.5, 0.5, 0.04]))
    assert not spin_blocked(vertical, "R_H_C")


def _switch(monkeypatch, tmp_path, fine: str, slide_direction) -> tuple[str, np.ndarray]:
    """refine_predictions on one edge typed ``fine`` whose chosen hinge line (z) the sweep
    blocks while another line turns, and whose chosen slider line (``slide_direction``) is
    free: the edge's type and axis afterwards."""
    import kinmo.refine.refine as rr
    from kinmo.mobility_tree import EdgePrediction
    from kinmo.refine.ranker import _load_ranker_cached

    from motion_cabinet import cabinet_graph
    from .test_position import _linear
    from .test_selector import _door_edge, _priors

    def fake_select(graph, k, motion_type, *args, **kwargs):
        if motion_type == "P_H":
            cands, x, p = _case([0.0, 0.0, 0.0], "P_H")
            free, d = np.array([1.0, 1.0, 1.0]), np.asarray(slide_direction, float)
        else:
            cands, x, p = _case([0.0, 0.0, 0.0], motion_type)
            free, d = np.array([0.04, 0.5, 0.9]), _DIRS[0]
        scores = CandidateScores(np.full(3, 0.5), np.zeros(3), np.zeros(3), p, np.ones(3, np.int64), 0)
        return EdgeRefinement(cands, scores, np.zeros(3), d, free=free)

    monkeypatch.setattr(rr, "select_edge", fake_select)
    g = cabinet_graph(n_points=64)
    k = _door_edge(g)
    e = len(g.sibling_edges)
    pri = _priors(g, k, fine)
    pred = EdgePrediction(pri.probs.copy(), np.tile([0.0, 0.0, 1.0], (e, 1)), np.tile(g.obb_center[2], (e, 1)))
    path = _linear(log_dir_prior=1.0).save(tmp_path / "ranker.json")
    _load_ranker_cached.cache_clear()
    out = rr.refine_predictions(g, pred, None, RefineConfig(selector="ranker", ranker=str(path)), only=[k],
                                priors=pri)
    return str(FINE_TYPES[int(np.argmax(out.type_prob[k]))]), out.axis_direction[k]


def test_a_drawer_typed_a_blocked_spin_about_its_pull_axis_slides_along_it(monkeypatch, tmp_path):
    """A drawer the GNN types a knob-like spin (R_H_C) about the line it pulls out along:
    that line cannot turn it, and the part slides along it, so it becomes a slider there."""
    t, d = _switch(monkeypatch, tmp_path, "R_H_C", [0.0, 0.0, 1.0])
    assert t.startswith("P_") and abs(d[2]) == pytest.approx(1.0)


def test_a_blocked_spin_stays_a_hinge_when_it_slides_only_across_its_line(monkeypatch, tmp_path):
    t, d = _switch(monkeypatch, tmp_path, "R_H_C", [1.0, 0.0, 0.0])
    assert t == "R_H_C" and abs(d[2]) == pytest.approx(1.0)
    # a hinge that is not continuous keeps its type even where it could slide along its line
    t, _ = _switch(monkeypatch, tmp_path, "R_H_S", [0.0, 0.0, 1.0])
    assert t == "R_H_S"


def _button(share: float = 1.1, half=(0.05, 0.05, 0.02)):
    """The test cabinet with its door (node 2) made a button on the body's front face (+z):
    its centre ``share`` of the body's half depth in front of the body's centre."""
    from motion_cabinet import cabinet_graph

    from .test_selector import _door_edge

    g = cabinet_graph(n_points=64)
    k = _door_edge(g)
    centre, halfs = g.obb_center.copy(), g.obb_half_extents.copy()
    halfs[2] = half
    centre[2] = centre[1] + [0.0, 0.0, share * halfs[1][2]]
    return dataclasses.replace(g, obb_center=centre, obb_half_extents=halfs), k


def _slide(chosen: int, free=(1.0, 1.0, 1.0), motion_type="P_V") -> EdgeRefinement:
    cands, _, p = _case([0.0, 0.0, 0.0], motion_type)
    scores = CandidateScores(np.full(3, 0.5), np.zeros(3), np.zeros(3), p, np.ones(3, np.int64), chosen)
    return EdgeRefinement(cands, scores, np.zeros(3), _DIRS[chosen], free=np.asarray(free, float))


def test_a_button_slid_across_its_face_is_pressed_along_the_normal():
    """Meta-World's button box: the button, on the box's front face, typed a vertical slider."""
    from kinmo.refine.edge import pressed_into_face

    g, k = _button()
    assert bool(g.sibling_contact[k])
    out = pressed_into_face(g, k, _slide(2))
    assert out.scores.best == 0 and abs(out.direction[2]) == pytest.approx(1.0)
    # the calibration is asked for the new line
    out = pressed_into_face(g, k, _slide(2), confidence=lambda p, prior: 0.42)
    assert out.calibrated == pytest.approx(0.42)
    # a sideways slide (x) across the face is pressed in too
    assert pressed_into_face(g, k, _slide(1)).scores.best == 0
    # without meshes (free None) every line counts as free
    r = dataclasses.replace(_slide(2), free=None)
    assert pressed_into_face(g, k, r).scores.best == 0


def test_a_slide_that_is_no_button_across_its_face_is_kept():
    from kinmo.refine.edge import PRESS_VOLUME_RATIO, pressed_into_face

    g, k = _button()
    # already along the normal
    assert pressed_into_face(g, k, _slide(0)).scores.best == 0
    # the normal line is not free either way (pressed into a solid body, nothing to pull out)
    assert pressed_into_face(g, k, _slide(2, free=(OPEN_FREE - 0.01, 1.0, 1.0))).scores.best == 2
    # hinges and cylindrical joints are left alone
    for t in ("R_H_S", "PR_V"):
        assert pressed_into_face(g, k, _slide(2, motion_type=t)).scores.best == 2
    # centre inside the body's box (a drawer in its carcass): no face to press into
    g_in, _ = _button(share=0.9)
    assert pressed_into_face(g_in, k, _slide(2)).scores.best == 2
    # not small beside the body (a door, a drawer front)
    body = np.prod(2.0 * g.obb_half_extents[1])
    side = (1.01 * PRESS_VOLUME_RATIO * body / 8.0 / 0.02) ** 0.5
    g_big, _ = _button(half=(side, side, 0.02))
    assert pressed_into_face(g_big, k, _slide(2)).scores.best == 2
    # not in contact
    contact = g.sibling_contact.copy()
    contact[k] = False
    assert pressed_into_face(dataclasses.replace(g, sibling_contact=contact), k, _slide(2)).scores.best == 2


def _press(monkeypatch, tmp_path, reference_moves: bool, neighbour_moves: bool = False,
           unnamed: bool = True, name: str | None = None) -> np.ndarray:
    """refine_predictions on the button edge, its chosen line vertical (across its face): the
    button's axis afterwards, with its reference (the body) predicted static or moving, the
    drawer it touches predicted static or moving, in an object with or without known part
    names."""
    import kinmo.refine.refine as rr
    from kinmo.mobility_tree import EdgePrediction
    from kinmo.refine.ranker import _load_ranker_cached

    from .test_position import _linear
    from .test_selector import _priors

    monkeypatch.setattr(rr, "select_edge", lambda *a, **kw: _slide(2))
    g, k = _button()
    if name is not None:
        g = dataclasses.replace(g, node_names=[name if n == 2 else v for n, v in enumerate(g.node_names)])
    e = len(g.sibling_edges)
    pri = dataclasses.replace(_priors(g, k, "P_V"), turned=unnamed)
    if reference_moves:  # the body typed a slider against the drawer (another edge)
        b = int(np.flatnonzero((g.sibling_edges[:, 0] == 1) & (g.sibling_edges[:, 1] == 3))[0])
        pri.probs[b] = 0.01
        pri.probs[b, FINE_TYPES.index("P_H")] = 0.91
    if neighbour_moves:  # the drawer beside the button slides out of the body
        b = int(np.flatnonzero((g.sibling_edges[:, 0] == 3) & (g.sibling_edges[:, 1] == 1))[0])
        pri.probs[b] = 0.01
        pri.probs[b, FINE_TYPES.index("P_H")] = 0.91
    pred = EdgePrediction(pri.probs.copy(), np.tile([0.0, 1.0, 0.0], (e, 1)), np.tile(g.obb_center[2], (e, 1)))
    path = _linear(log_dir_prior=1.0).save(tmp_path / "ranker.json")
    _load_ranker_cached.cache_clear()
    out = rr.refine_predictions(g, pred, None, RefineConfig(selector="ranker", ranker=str(path)), only=[k],
                                priors=pri)
    return out.axis_direction[k]


def test_only_a_button_on_a_part_predicted_static_is_pressed_in(monkeypatch, tmp_path):
    assert abs(_press(monkeypatch, tmp_path, reference_moves=False)[2]) == pytest.approx(1.0)
    # on a moving part the slide is the mobility tree's to judge (rule 2b fixes a handle
    # sliding across its drawer to the drawer)
    assert abs(_press(monkeypatch, tmp_path, reference_moves=True)[1]) == pytest.approx(1.0)
    # a part touching a moving part (a handle on a drawer) slides with it, across the body's
    # face (a chest's handle, out of fold)
    assert abs(_press(monkeypatch, tmp_path, reference_moves=False, neighbour_moves=True)[1]) == \
        pytest.approx(1.0)
    # known part names tell a button from a slider or a lever (a PartNet toaster's lever has
    # a button's square section): the GNN's line stays
    assert abs(_press(monkeypatch, tmp_path, reference_moves=False, unnamed=False)[1]) == pytest.approx(1.0)
    assert abs(_press(monkeypatch, tmp_path, reference_moves=False, unnamed=False, name="slider")[1]) == \
        pytest.approx(1.0)
    # ... unless the name says button (a Meta-World button box's MJCF body)
    assert abs(_press(monkeypatch, tmp_path, reference_moves=False, unnamed=False, name="button")[2]) == \
        pytest.approx(1.0)


def test_button_and_key_names_are_pressable():
    from kinmo.refine.edge import pressable

    for name in ("button", "Button_3", "power button", "key", "key_12"):
        assert pressable(name, unnamed=False)
    for name in ("slider", "lever", "switch", "keyboard", "buttonbox", "door", ""):
        assert not pressable(name, unnamed=False)
        assert pressable(name, unnamed=True)


def test_a_lever_tab_slid_across_its_face_is_kept():
    """A toaster's lever: a long narrow tab sliding across the face in its slot."""
    from kinmo.refine.edge import PRESS_SECTION_RATIO, pressed_into_face

    g, k = _button(half=(0.1, 0.1 * PRESS_SECTION_RATIO * 0.9, 0.05))
    assert pressed_into_face(g, k, _slide(2)).scores.best == 2
    g, k = _button(half=(0.1, 0.1 * PRESS_SECTION_RATIO * 1.1, 0.05))
    assert pressed_into_face(g, k, _slide(2)).scores.best == 0
