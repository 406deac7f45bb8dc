"""The repeated-parts vote (kinmo.refine.repeated): copies follow the majority's direction."""

from __future__ import annotations

from dataclasses import replace
from types import SimpleNamespace

import numpy as np

from kinmo.refine.candidates import Candidates
from kinmo.refine.edge import EdgeRefinement
from kinmo.refine.repeated import repeated_groups, vote_repeated
from kinmo.refine.scoring import CandidateScores

UP, SIDE = np.array([0.0, 1.0, 0.0]), np.array([1.0, 0.0, 0.0])


def _keyboard(n_keys: int, extents=None):
    """Node 0 the base, nodes 1..n keys (equal small boxes); edge k moves key k+1 on the base."""
    half = np.array([[1.0, 0.1, 0.5]] + [[0.05, 0.02, 0.05]] * n_keys)
    if extents is not None:
        half[1:] = extents
    centers = np.zeros((n_keys + 1, 3))
    centers[1:, 0] = np.arange(n_keys) * 0.12
    graph = SimpleNamespace(obb_half_extents=half, obb_center=centers,
                            obb_axes=np.repeat(np.eye(3)[None], n_keys + 1, axis=0))
    edges = np.array([[k + 1, 0] for k in range(n_keys)])
    return graph, edges


def _choice(prob_up: float, chose_up: bool) -> EdgeRefinement:
    cands = Candidates(np.zeros((2, 3)), np.stack([UP, SIDE]), ("edge", "edge"), "T_V")
    total = np.array([prob_up, 1.0 - prob_up])
    b = 0 if chose_up else 1
    scores = CandidateScores(np.ones(2), np.ones(2), np.ones(2), total, np.ones(2, np.int64), b)
    d = UP if chose_up else SIDE
    return EdgeRefinement(cands, scores, np.zeros(3), d.copy(), calibrated=float(total[b]),
                          dir_prior=np.array([0.9, 0.1]))


def _conf(p: float, prior: float = 1.0) -> float:
    return 0.5 * p + 0.5 * prior


def test_copies_turned_off_the_majority_follow_it():
    graph, edges = _keyboard(5)
    types = ["T_V"] * 5
    details = {0: _choice(0.9, True), 1: _choice(0.8, True), 2: _choice(0.3, False),
               3: _choice(0.7, True), 4: _choice(0.4, False)}
    changed = vote_repeated(graph, edges, types, details, _conf)
    assert sorted(changed) == [2, 4]
    for k, r in changed.items():
        assert r.voted and r.scores.best == 0
        assert np.allclose(r.direction, UP)
        assert r.calibrated == _conf(details[k].scores.total[0], 0.9)
        # on the candidate's own line, at the point nearest the key's centre
        o = r.candidates.origins[0]
        assert np.allclose(np.cross(r.origin - o, UP), 0.0)
        assert abs(np.dot(graph.obb_center[edges[k, 0]] - r.origin, UP)) < 1e-12


def test_the_pooled_probability_decides_not_the_count():
    graph, edges = _keyboard(5)
    # three copies unsure towards the side (0.55 / 0.45), two sure of up (0.95)
    details = {0: _choice(0.45, False), 1: _choice(0.45, False), 2: _choice(0.45, False),
               3: _choice(0.95, True), 4: _choice(0.95, True)}
    changed = vote_repeated(graph, edges, ["T_V"] * 5, details, _conf)
    assert sorted(changed) == [0, 1, 2]
    assert all(np.allclose(r.direction, UP) for r in changed.values())
    # sure of the side, they stay and the others follow them
    details = {0: _choice(0.1, False), 1: _choice(0.1, False), 2: _choice(0.1, False),
               3: _choice(0.6, True), 4: _choice(0.6, True)}
    changed = vote_repeated(graph, edges, ["T_V"] * 5, details, _conf)
    assert sorted(changed) == [3, 4] and all(np.allclose(r.direction, SIDE) for r in changed.values())


def test_pairs_types_references_and_sizes_do_not_group():
    graph, edges = _keyboard(3)
    details = {0: _choice(0.9, True), 1: _choice(0.8, True), 2: _choice(0.3, False)}
    # two copies only (a double door): no vote
    assert vote_repeated(graph, edges[:2], ["T_V"] * 2, {0: details[0], 1: details[2]}, _conf) == {}
    # another predicted type breaks the group
    assert vote_repeated(graph, edges, ["T_V", "T_V", "R_V_S"], details, _conf) == {}
    # another reference part breaks the group
    other = edges.copy()
    other[2, 1] = 1
    assert vote_repeated(graph, other, ["T_V"] * 3, details, _conf) == {}
    # a part twice the size is not a copy
    big, e3 = _keyboard(3, extents=[[0.05, 0.02, 0.05], [0.05, 0.02, 0.05], [0.1, 0.04, 0.1]])
    assert repeated_groups(big, e3, ["T_V"] * 3, [0, 1, 2]) == []
    assert vote_repeated(big, e3, ["T_V"] * 3, details, _conf) == {}
    # but the three equal keys are one group
    assert repeated_groups(graph, edges, ["T_V"] * 3, [0, 1, 2]) == [[0, 1, 2]]


def test_a_member_without_a_candidate_near_the_winner_keeps_its_choice():
    graph, edges = _keyboard(3)
    lone = _choice(0.3, False)
    lone = EdgeRefinement(Candidates(np.zeros((1, 3)), SIDE[None], ("edge",), "T_V"),
                          CandidateScores(*(np.ones(1),) * 4, np.ones(1, np.int64), 0),
                          np.zeros(3), SIDE.copy(), calibrated=0.5)
    details = {0: _choice(0.9, True), 1: _choice(0.8, True), 2: lone}
    assert vote_repeated(graph, edges, ["T_V"] * 3, details, _conf) == {}


def test_copies_turned_about_the_shape_vote_in_their_own_frames():
    """A box's flaps: copies whose hinges differ in the shape's frame but not in their own."""
    graph, edges = _keyboard(4, extents=[[0.5, 0.02, 0.2]] * 4)
    turn = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])  # 90 deg about y
    graph.obb_axes[3] = turn  # flap 3 (edge 2) is flap 1 turned a quarter about the vertical
    graph.obb_axes[4] = turn
    hinge_of = {0: SIDE, 1: SIDE, 2: turn[0], 3: turn[0]}  # each flap's long axis
    details = {}
    for k, h in hinge_of.items():
        cands = Candidates(np.zeros((2, 3)), np.stack([h, UP]), ("edge", "edge"), "R_H_S")
        total = np.array([0.8, 0.2])
        scores = CandidateScores(*(np.ones(2),) * 3, total, np.ones(2, np.int64), 0)
        details[k] = EdgeRefinement(cands, scores, np.zeros(3), h.copy(), calibrated=0.8)
    # in the shape's frame two flaps hinge about x and two about z; in their own all agree
    assert vote_repeated(graph, edges, ["R_H_S"] * 4, details, _conf) == {}
    # one flap unsure and turned to the vertical follows the others' own-frame hinge
    d2 = details[2]
    details[2] = replace(d2, scores=replace(d2.scores, total=np.array([0.4, 0.6]), best=1),
                         direction=UP.copy())
    changed = vote_repeated(graph, edges, ["R_H_S"] * 4, details, _conf)
    assert sorted(changed) == [2] and np.allclose(np.abs(changed[2].direction), np.abs(turn[0]))


def test_a_copy_that_deferred_to_a_sure_gnn_neither_votes_nor_follows():
    # four knobs: the pooled ranker leans sideways, but two copies deferred to the GNN's
    # sure vertical (kinmo.refine.defer.sure_prior); they keep it, and the sideways majority
    # of the other two does not count them
    graph, edges = _keyboard(4)
    types = ["T_V"] * 4
    up_deferred = replace(_choice(0.3, True), deferred=True)
    details = {0: up_deferred, 1: replace(_choice(0.3, True), deferred=True),
               2: _choice(0.3, False), 3: _choice(0.3, False)}
    changed = vote_repeated(graph, edges, types, details, _conf)
    assert 0 not in changed and 1 not in changed
    # the same without the flags: the copies vote, and sideways wins
    plain = {k: replace(r, deferred=False) for k, r in details.items()}
    assert sorted(vote_repeated(graph, edges, types, plain, _conf)) == [0, 1]


def _three_lines(p_side: float, p_up: tuple[float, float]) -> EdgeRefinement:
    """A member offered the side by one line and up by two lines (an OBB edge and the centre),
    which share the up direction's probability; it chose as a ranker choosing by direction
    does (:func:`kinmo.refine.ranker.direction_choice`)."""
    from kinmo.refine.ranker import direction_choice

    dirs = np.stack([SIDE, UP, UP])
    cands = Candidates(np.zeros((3, 3)), dirs, ("edge", "edge", "centre"), "P_V")
    total = np.array([p_side, *p_up])
    b = direction_choice(total, dirs)
    scores = CandidateScores(np.ones(3), np.ones(3), np.ones(3), total, np.ones(3, np.int64), b)
    return EdgeRefinement(cands, scores, np.zeros(3), dirs[b].copy(), calibrated=float(total[b]),
                          dir_prior=np.array([0.2, 0.8, 0.8]))


def test_a_ranker_choosing_by_direction_votes_with_its_direction_mass():
    """The phone of session 24: three buttons, each with the side on one line (0.39) and up,
    the right direction, on two lines (0.33 + 0.24 = 0.57). Each chose up; voting with each
    member's best line (0.39 against 0.33) turned all three to the side."""
    graph, edges = _keyboard(3)
    details = {k: _three_lines(0.39, (0.33, 0.28)) for k in range(3)}
    assert all(np.allclose(r.direction, UP) for r in details.values())
    # the mass the members' own choices compared: up wins, nothing changes
    assert vote_repeated(graph, edges, ["P_V"] * 3, details, _conf, mass=5.0) == {}
    # the best line per member (rankers choosing the arg-max line): the side wins
    changed = vote_repeated(graph, edges, ["P_V"] * 3, details, _conf)
    assert sorted(changed) == [0, 1, 2] and all(np.allclose(r.direction, SIDE) for r in changed.values())
    # mass still follows the evidence: members sure of the side turn the group
    details = {k: _three_lines(0.8, (0.1, 0.1)) for k in range(2)} | {2: _three_lines(0.39, (0.33, 0.28))}
    changed = vote_repeated(graph, edges, ["P_V"] * 3, details, _conf, mass=5.0)
    assert sorted(changed) == [2] and np.allclose(changed[2].direction, SIDE)


def test_the_vote_keeps_what_the_slide_veto_decided():
    """The table of session 24: six drawers, each with its front line (z) free and two
    sideways lines (x) blocked, chosen front by the slide veto although the sideways mass is
    larger. Voting with the mass alone turned them all sideways; with the veto's lines left
    out nothing changes. Without the sweep (no free fractions) the veto has nothing to say."""
    front, side = np.array([0.0, 0.0, 1.0]), SIDE

    def drawer(free):
        dirs = np.stack([front, side, side])
        cands = Candidates(np.zeros((3, 3)), dirs, ("edge", "edge", "centre"), "P_H")
        total = np.array([0.45, 0.17, 0.38])
        scores = CandidateScores(np.ones(3), np.ones(3), np.ones(3), total, np.ones(3, np.int64), 0)
        return EdgeRefinement(cands, scores, np.zeros(3), front.copy(), calibrated=0.45,
                              dir_prior=np.array([0.02, 0.97, 0.97]), free=free)

    graph, edges = _keyboard(6)
    details = {k: drawer(np.array([1.0, 0.05, 0.05])) for k in range(6)}
    turned = vote_repeated(graph, edges, ["P_H"] * 6, details, _conf, mass=5.0)
    assert sorted(turned) == list(range(6)) and all(np.allclose(r.direction, side) for r in turned.values())
    assert vote_repeated(graph, edges, ["P_H"] * 6, details, _conf, mass=5.0, slide_veto=True) == {}
    # no horizontal line free: the veto rules nothing out, and the mass decides again
    details = {k: drawer(np.array([0.05, 0.05, 0.05])) for k in range(6)}
    assert len(vote_repeated(graph, edges, ["P_H"] * 6, details, _conf, mass=5.0, slide_veto=True)) == 6
