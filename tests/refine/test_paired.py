"""Paired doors open from the middle (kinmo.refine.paired): a hinge at the seam moves outward."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from kinmo.refine.candidates import Candidates
from kinmo.refine.edge import EdgeRefinement
from kinmo.refine.paired import door_pairs, open_from_the_middle
from kinmo.refine.scoring import CandidateScores

UP, SIDE = np.array([0.0, 1.0, 0.0]), np.array([1.0, 0.0, 0.0])


def _box_points(center, half, n: int = 6) -> np.ndarray:
    """A grid of points filling a box (mesh frame)."""
    g = np.linspace(-1.0, 1.0, n)
    grid = np.stack(np.meshgrid(g, g, g, indexing="ij"), axis=-1).reshape(-1, 3)
    return np.asarray(center, float) + grid * np.asarray(half, float)


def _cabinet(centers_x=(-0.25, 0.25), width: float = 0.24):
    """Node 0 the body; nodes 1.. doors (thin vertical panels in the front plane z = 0.5)."""
    half_body = np.array([0.5, 0.5, 0.5])
    half_door = np.array([width, 0.45, 0.01])
    centers = [np.zeros(3)] + [np.array([x, 0.0, 0.5]) for x in centers_x]
    halves = [half_body] + [half_door] * len(centers_x)
    points = np.stack([_box_points(c, h) for c, h in zip(centers, halves)])
    graph = SimpleNamespace(points=points, obb_center=np.stack(centers),
                            obb_half_extents=np.stack(halves),
                            obb_axes=np.repeat(np.eye(3)[None], len(centers), axis=0))
    edges = np.array([[k + 1, 0] for k in range(len(centers_x))])
    return graph, edges


def _door(graph, node: int, chose: str, p_left: float, p_right: float) -> EdgeRefinement:
    """Vertical lines at the door's left and right edges, and a horizontal line at its top."""
    c, h = graph.obb_center[node], graph.obb_half_extents[node]
    origins = np.stack([c - [h[0], 0, 0], c + [h[0], 0, 0], c + [0, h[1], 0]])
    cands = Candidates(origins, np.stack([UP, UP, SIDE]), ("edge", "edge", "edge"), "R_V_S")
    total = np.array([p_left, p_right, 1.0 - p_left - p_right])
    b = {"left": 0, "right": 1, "top": 2}[chose]
    scores = CandidateScores(np.ones(3), np.ones(3), np.ones(3), total, np.ones(3, np.int64), b)
    return EdgeRefinement(cands, scores, origins[b].copy(), cands.directions[b].copy(),
                          calibrated=float(total[b]), dir_prior=np.array([0.9, 0.9, 0.1]))


def test_a_door_hinged_at_the_seam_moves_to_its_outer_edge():
    # 45332's test case: the left door hinged at its outer (left) edge, the right one at the
    # seam (its left edge), although its outer edge was close in the ranking
    graph, edges = _cabinet()
    details = {0: _door(graph, 1, "left", 0.6, 0.3), 1: _door(graph, 2, "left", 0.45, 0.4)}
    types = ["R_V_S", "R_V_S"]
    assert [(p.k, p.l) for p in door_pairs(graph, edges, types, details)] == [(0, 1)]
    changed = open_from_the_middle(graph, edges, types, details)
    assert sorted(changed) == [1]
    r = changed[1]
    assert r.scores.best == 1
    assert np.isclose(r.origin[0], 0.25 + 0.24) and np.allclose(np.abs(r.direction), UP)
    assert r.calibrated == details[1].calibrated  # the pair's confidence, not the line's
    # both at the seam: both move; both outer already: nothing moves
    both = {0: _door(graph, 1, "right", 0.3, 0.6), 1: _door(graph, 2, "left", 0.45, 0.4)}
    assert sorted(open_from_the_middle(graph, edges, types, both)) == [0, 1]
    outer = {0: _door(graph, 1, "left", 0.6, 0.3), 1: _door(graph, 2, "right", 0.3, 0.6)}
    assert open_from_the_middle(graph, edges, types, outer) == {}


def test_rows_of_three_centre_lines_and_other_directions_are_left_alone():
    types3 = ["R_V_S"] * 3
    # a row of three doors hinged alike (Refrigerator 11709): every door has two neighbours
    # or a neighbour with two, so no pair is formed
    graph, edges = _cabinet(centers_x=(-0.5, 0.0, 0.5))
    row = {k: _door(graph, k + 1, "left", 0.6, 0.3) for k in range(3)}
    assert door_pairs(graph, edges, types3, row) == []
    assert open_from_the_middle(graph, edges, types3, row) == {}
    graph, edges = _cabinet()
    types = ["R_V_S", "R_V_S"]
    # a chosen line through the part's centre, beside a door hinged at its outer edge, moves
    # to its own outer edge; two centre lines give nothing to go by
    def through_centre(node):
        r = _door(graph, node, "left", 0.45, 0.4)
        return EdgeRefinement(r.candidates, r.scores, graph.obb_center[node].copy(), UP.copy(),
                              calibrated=0.45, dir_prior=r.dir_prior)

    moved = open_from_the_middle(graph, edges, types, {0: _door(graph, 1, "left", 0.6, 0.3),
                                                       1: through_centre(2)})
    assert sorted(moved) == [1] and np.isclose(moved[1].origin[0], 0.25 + 0.24)
    assert open_from_the_middle(graph, edges, types, {0: through_centre(1), 1: through_centre(2)}) == {}
    # beside a door hinged at the seam, which moves out first, it moves too
    both = open_from_the_middle(graph, edges, types, {0: _door(graph, 1, "right", 0.3, 0.6),
                                                      1: through_centre(2)})
    assert sorted(both) == [0, 1] and np.isclose(both[0].origin[0], -0.25 - 0.24)
    # directions that disagree, a centre-pivot type, or parts far apart: no pair
    seam = {0: _door(graph, 1, "left", 0.6, 0.3), 1: _door(graph, 2, "top", 0.2, 0.2)}
    assert door_pairs(graph, edges, types, seam) == []
    seam[1] = _door(graph, 2, "left", 0.45, 0.4)
    assert door_pairs(graph, edges, ["R_V_S", "R_V_C"], seam) == []
    far, edges_far = _cabinet(centers_x=(-0.9, 0.9))
    apart = {0: _door(far, 1, "left", 0.6, 0.3), 1: _door(far, 2, "left", 0.45, 0.4)}
    assert door_pairs(far, edges_far, types, apart) == []
    # a part at right angles to the other (a box's top flap and the wall below it): no pair
    graph.obb_half_extents[2] = [0.01, 0.45, 0.24]  # the same box, thinnest along x
    assert door_pairs(graph, edges, types, seam) == []
    # doors of other sizes are not mirror images
    graph.obb_half_extents[2] = [0.12, 0.45, 0.01]
    assert door_pairs(graph, edges, types, seam) == []
    graph.obb_half_extents[2] = [0.24, 0.45, 0.01]
    assert len(door_pairs(graph, edges, types, seam)) == 1


#: Shared objects with two doors side by side (9) and Refrigerator 11709, a row of three
#: doors hinged alike. Session 35 ran the pairing over the true joints of all 235 labelled
#: objects: it found pairs on exactly the nine cabinets, and every pair was hinged outward.
CABINETS = ("45001", "45332", "45463", "45963", "46108", "46120", "46490", "46563", "49182")
ROW_OF_THREE = "11709"


def test_the_true_door_pairs_of_real_cabinets_are_hinged_at_their_outer_edges(mobility_root):
    """The premise of the rule, on real objects: the pairs it forms among the *true* hinge
    lines are all outer, and a row of three doors hinged alike forms none."""
    from kinmo.data.build import build_graph
    from kinmo.data.model import FINE_TYPES
    from kinmo.data.readers import read_shape

    def truth(folder):
        g = build_graph(read_shape(folder), n_points=256)
        types = [FINE_TYPES[int(f)] if f >= 0 else "None" for f in g.edge_fine]
        det = {}
        for e, kind in enumerate(types):
            d, o = g.edge_axis_direction[e], g.edge_axis_origin[e]
            if kind.startswith("R") and np.isfinite(d).all() and np.isfinite(o).all():
                det[e] = SimpleNamespace(direction=d / np.linalg.norm(d), origin=o,
                                         abstained=False, scores=SimpleNamespace(best=0))
        return g, np.asarray(g.sibling_edges), types, det

    found = 0
    for shape_id in CABINETS:
        g, edges, types, det = truth(mobility_root / shape_id)
        pairs = door_pairs(g, edges, types, det)
        assert pairs, f"{shape_id}: no door pair among its true hinges"
        for k, l, u, width_k, width_l in pairs:
            for e, out, width in ((k, -u, width_k), (l, u, width_l)):
                v = det[e].origin - g.obb_center[int(edges[e, 0])]
                v = v - (v @ det[e].direction) * det[e].direction
                assert v @ out > 0.5 * width, (shape_id, e)
        found += len(pairs)
    assert found >= 20
    g, edges, types, det = truth(mobility_root / ROW_OF_THREE)
    assert sum(t.startswith("R") for t in types) and door_pairs(g, edges, types, det) == []
