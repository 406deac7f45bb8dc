"""The slide veto judged against the parts predicted not to move (kinmo.refine.edge, issue 36).

A cabinet that faces +x (the ROS convention), y-up: a carcass open at +x, a door closing
that opening, and a drawer inside, behind the door. The drawer slides along x. Against the
whole object every line of the drawer is blocked (the door is in front of it), so the
blocked-slide veto cannot act; against the carcass alone x is free and z still blocked.
"""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from kinmo.data.graph import PartGraph
from kinmo.refine.candidates import Candidates
from kinmo.refine.edge import BLOCKED_FREE, OPEN_FREE, EdgeRefinement, fixed_parts_slide_veto, vetoed_slides
from kinmo.refine.scoring import CandidateScores
from kinmo.refine.selector import ShapeMeshes, fixed_leaves, line_sweeps

# +z (PartNet's front, here the side walls), +x (this cabinet's front), +y (vertical)
_DIRS = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
_T = 0.02  # wall thickness
_GAP = 0.004  # the drawer's clearance inside the carcass


def _box(lo, hi):
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    m = trimesh.creation.box(extents=hi - lo)
    m.apply_translation((lo + hi) / 2)
    return m


def _surface(mesh, n, seed):
    return np.asarray(trimesh.sample.sample_surface(mesh, n, seed=seed)[0], dtype=np.float64)


def _cabinet() -> tuple[PartGraph, ShapeMeshes]:
    """0 cabinet → 1 carcass, 2 door, 3 drawer (leaves); the carcass spans x, y, z in
    [-0.3, 0.3] x [0, 0.8] x [-0.4, 0.4], open at +x."""
    x0, x1, y1, z0, z1 = -0.3, 0.3, 0.8, -0.4, 0.4
    walls = [_box((x0, 0, z0), (x0 + _T, y1, z1)),            # back
             _box((x0, 0, z0), (x1, _T, z1)),                  # floor
             _box((x0, y1 - _T, z0), (x1, y1, z1)),            # top
             _box((x0, 0, z0), (x1, y1, z0 + _T)),             # side walls (z)
             _box((x0, 0, z1 - _T), (x1, y1, z1))]
    carcass = trimesh.util.concatenate(walls)
    door = _box((x1, 0, z0), (x1 + _T, y1, z1))
    inner = (np.array([x0 + _T + _GAP, _T + _GAP, z0 + _T + _GAP]),
             np.array([x1 - _GAP, y1 - _T - _GAP, z1 - _T - _GAP]))
    drawer = _box(*inner)
    parts = {1: carcass, 2: door, 3: drawer}
    pts = np.zeros((4, 512, 3))
    for k, m in parts.items():
        pts[k] = _surface(m, 512, k)
    pts[0] = np.concatenate([pts[1][:171], pts[2][:171], pts[3][:170]])
    boxes = [trimesh.util.concatenate(list(parts.values())).bounds] + [m.bounds for m in parts.values()]
    centre = np.array([b.mean(axis=0) for b in boxes])
    half = np.array([(b[1] - b[0]) / 2 for b in boxes])
    sib = np.array([(a, b) for a in (1, 2, 3) for b in (1, 2, 3) if a != b], dtype=np.int64)
    graph = PartGraph(
        shape_id="rosCabinet", category="StorageFurniture", format="partnet",
        node_ids=np.arange(4, dtype=np.int64), node_names=["cabinet", "part_1", "part_2", "part_3"],
        parent=np.array([-1, 0, 0, 0], dtype=np.int64), is_leaf=np.array([False, True, True, True]),
        depth=np.array([0, 1, 1, 1], dtype=np.int64), points=pts.astype(np.float32),
        obb_center=centre, obb_axes=np.tile(np.eye(3), (4, 1, 1)), obb_half_extents=half,
        child_edges=np.array([(0, 1), (0, 2), (0, 3)], dtype=np.int64), sibling_edges=sib,
        sibling_contact=np.ones(len(sib), dtype=bool), sibling_distance=np.zeros(len(sib)),
        scale=float(np.linalg.norm(half[0]) * 2))
    meshes = ShapeMeshes({k: (np.asarray(m.vertices, np.float64), np.asarray(m.faces, np.int64))
                          for k, m in parts.items()})
    return graph, meshes


def _drawer_edge(graph: PartGraph) -> int:
    return int(np.flatnonzero((graph.sibling_edges[:, 0] == 3) & (graph.sibling_edges[:, 1] == 1))[0])


def _choice(graph, meshes, best: int, motion: str = "P_H") -> EdgeRefinement:
    """The selector's choice of line ``best`` for the drawer, its ``free`` the swept test
    against everything outside the drawer (as :func:`kinmo.refine.selector.candidate_features`)."""
    c = Candidates(np.tile(graph.obb_center[3], (3, 1)), _DIRS.copy(), ("axis",) * 3, motion)
    free, _ = line_sweeps(graph, 3, c, meshes, np.array([1, 2]))
    p = np.array([0.6, 0.3, 0.1])
    scores = CandidateScores(np.full(3, 0.5), np.zeros(3), np.zeros(3), p, np.ones(3, np.int64), best)
    return EdgeRefinement(c, scores, graph.obb_center[3].copy(), _DIRS[best].copy(),
                          calibrated=0.5, dir_prior=np.array([0.8, 0.1, 0.1]), free=free.max(axis=1))


def test_fixed_leaves_leave_out_every_moving_subtree():
    graph, _ = _cabinet()
    np.testing.assert_array_equal(fixed_leaves(graph, [2, 3]), [1])
    np.testing.assert_array_equal(fixed_leaves(graph, [3, 3]), [1, 2])
    np.testing.assert_array_equal(fixed_leaves(graph, []), [1, 2, 3])
    np.testing.assert_array_equal(fixed_leaves(graph, [0]), [])  # the root's subtree is all


def test_a_drawer_behind_a_door_is_blocked_every_way_against_the_whole_object():
    graph, meshes = _cabinet()
    r = _choice(graph, meshes, 0)
    assert (r.free < BLOCKED_FREE).all()  # the door closes its only way out
    assert not vetoed_slides(r.candidates, r.free).any()  # so the blocked-slide veto cannot act


def test_against_the_fixed_parts_the_drawer_slides_out_of_the_open_side():
    graph, meshes = _cabinet()
    k = _drawer_edge(graph)
    r = _choice(graph, meshes, 0)
    seen = []
    out = fixed_parts_slide_veto(graph, k, r, meshes, fixed_leaves(graph, [2, 3]),
                                 confidence=lambda p, prior: seen.append((p, prior)) or 0.25)
    assert out.scores.best == 1
    np.testing.assert_allclose(out.direction, [1.0, 0.0, 0.0], atol=1e-12)  # out of the front, +x
    assert out.free[1] >= OPEN_FREE and out.free[0] < BLOCKED_FREE
    assert seen == [(pytest.approx(0.3), pytest.approx(0.1))] and out.calibrated == 0.25
    # the new line is judged by the test that chose it: z is now a vetoed slide
    assert vetoed_slides(out.candidates, out.free)[0]


def test_the_veto_leaves_alone_what_it_should():
    graph, meshes = _cabinet()
    k = _drawer_edge(graph)
    # the door predicted not to move: it stays in the way, nothing is free, nothing changes
    r = _choice(graph, meshes, 0)
    assert fixed_parts_slide_veto(graph, k, r, meshes, fixed_leaves(graph, [3])) is r
    # the chosen line already free against the fixed parts (x, blocked only by the door)
    r = _choice(graph, meshes, 1)
    assert fixed_parts_slide_veto(graph, k, r, meshes, fixed_leaves(graph, [2, 3])) is r
    # hinges and cylindrical joints are left alone; so is an edge without meshes
    for t in ("R_H_S", "PR_H"):
        r = _choice(graph, meshes, 0, t)
        assert fixed_parts_slide_veto(graph, k, r, meshes, fixed_leaves(graph, [2, 3])) is r
    r = _choice(graph, meshes, 0)
    no_mesh = EdgeRefinement(r.candidates, r.scores, r.origin, r.direction, free=None)
    assert fixed_parts_slide_veto(graph, k, no_mesh, meshes, fixed_leaves(graph, [2, 3])) is no_mesh
    # a horizontal line free against the whole object: the blocked-slide veto has decided
    free = r.free.copy()
    free[1] = 1.0
    open_front = EdgeRefinement(r.candidates, r.scores, r.origin, r.direction, free=free)
    assert fixed_parts_slide_veto(graph, k, open_front, meshes, fixed_leaves(graph, [2, 3])) is open_front


def _refine(monkeypatch, tmp_path, door_moves: bool, vetoes: bool = True) -> np.ndarray:
    """refine_predictions on the drawer's edge alone (``only``), the selector's choice z: the
    drawer's refined direction. The door's edge is typed a hinge when ``door_moves``."""
    import kinmo.refine.refine as rr
    from kinmo.data.model import FINE_INDEX, FINE_TYPES
    from kinmo.mobility_tree import EdgePrediction
    from kinmo.refine.config import RefineConfig
    from kinmo.refine.ranker import _load_ranker_cached
    from kinmo.refine.selector import GNNPriors

    from .test_position import _linear

    graph, meshes = _cabinet()
    k = _drawer_edge(graph)
    monkeypatch.setattr(rr, "select_edge", lambda g, edge, *a, **kw: _choice(graph, meshes, 0))
    e = len(graph.sibling_edges)
    probs = np.full((e, 10), 0.01)
    probs[:, FINE_INDEX["None"]] = 0.91
    probs[k] = 0.01
    probs[k, FINE_INDEX["P_H"]] = 0.91
    if door_moves:
        door = int(np.flatnonzero((graph.sibling_edges[:, 0] == 2) & (graph.sibling_edges[:, 1] == 1))[0])
        probs[door] = 0.01
        probs[door, FINE_INDEX["R_V_S"]] = 0.91
    dirs = np.zeros((e, 10, 3))
    dirs[:] = [0.0, 0.0, 1.0]
    priors = GNNPriors(probs, FINE_TYPES, np.full((e, 10), 0.1), dirs)
    pred = EdgePrediction(probs.copy(), np.tile([0.0, 0.0, 1.0], (e, 1)), np.tile(graph.obb_center[3], (e, 1)))
    path = _linear(log_dir_prior=1.0).save(tmp_path / "ranker.json")
    _load_ranker_cached.cache_clear()
    cfg = RefineConfig(selector="ranker", ranker=str(path), sweep_vetoes=vetoes, vote_repeated=False,
                       pair_doors=False)
    out = rr.refine_predictions(graph, pred, None, cfg, only=[k], priors=priors, meshes=meshes)
    return out.axis_direction[k]


def test_refinement_slides_a_drawer_out_past_a_door_predicted_to_open(monkeypatch, tmp_path):
    # the door's edge is not refined (``only``), but it is predicted to move: not an obstacle
    np.testing.assert_allclose(_refine(monkeypatch, tmp_path, door_moves=True), [1.0, 0.0, 0.0], atol=1e-12)
    # a door predicted to stay closed keeps the drawer in: the selector's choice stands
    np.testing.assert_allclose(np.abs(_refine(monkeypatch, tmp_path, door_moves=False)), [0.0, 0.0, 1.0])
    # without the sweep vetoes nothing changes
    np.testing.assert_allclose(np.abs(_refine(monkeypatch, tmp_path, door_moves=True, vetoes=False)),
                               [0.0, 0.0, 1.0])


def test_a_drawer_freeing_a_little_of_its_side_line_is_judged_against_the_fixed_parts():
    """IAI cabinet 2's upper drawer: its side line frees 0.108 against the whole object, over
    BLOCKED_FREE; the veto has its own bar, FIXED_PARTS_BLOCKED_FREE."""
    from kinmo.refine.edge import FIXED_PARTS_BLOCKED_FREE

    graph, meshes = _cabinet()
    k = _drawer_edge(graph)
    r = _choice(graph, meshes, 0)
    for whole, acts in ((0.108, True), (FIXED_PARTS_BLOCKED_FREE - 0.01, True), (FIXED_PARTS_BLOCKED_FREE, False)):
        assert BLOCKED_FREE < whole
        free = r.free.copy()
        free[0] = whole
        little = EdgeRefinement(r.candidates, r.scores, r.origin, r.direction, free=free)
        out = fixed_parts_slide_veto(graph, k, little, meshes, fixed_leaves(graph, [2, 3]))
        assert (out.scores.best == 1) is acts and (out is little) is not acts
