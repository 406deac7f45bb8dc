"""Part graph -> tensors: normalised frame, node/edge features, labels, batching."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from kinmo.data.model import COARSE_INDEX, FINE_INDEX
from kinmo.errors import KinmoDataError
from kinmo.features import (
    EDGE_DIM,
    NODE_DIM,
    SemanticVocab,
    collate,
    edge_features,
    graph_tensors,
    yaw_rotation,
)
from motion_cabinet import cabinet_graph


def test_normalised_frame_and_round_trip():
    g = cabinet_graph(n_points=32)
    t = graph_tensors(g)
    pts = g.points[0].astype(np.float64)
    lo, hi = pts.min(0), pts.max(0)
    np.testing.assert_allclose(t.center, (lo + hi) / 2)
    assert t.scale == pytest.approx(g.scale)
    # node points are relative to the node's OBB centre, in units of the scale
    np.testing.assert_allclose(t.points[2].numpy() * g.scale + g.obb_center[2], g.points[2], atol=1e-5)
    np.testing.assert_allclose(t.to_mesh(t.obb_center.numpy()), g.obb_center, atol=1e-5)
    np.testing.assert_allclose(t.obb_size.numpy(), 2 * g.obb_half_extents / g.scale, atol=1e-6)
    # ground-truth axis origins map back to the mesh frame; directions are unit
    k = int(np.flatnonzero(g.edge_fine == FINE_INDEX["R_V_S"])[0])
    np.testing.assert_allclose(t.to_mesh(t.axis_origin[k].numpy()), g.edge_axis_origin[k], atol=1e-5)
    assert bool(t.has_axis[k]) and float(t.axis_direction[k].norm()) == pytest.approx(1.0)
    fixed = int(np.flatnonzero(g.edge_fine == FINE_INDEX["Fixed"])[0])
    assert not bool(t.has_axis[fixed]) and float(t.axis_direction[fixed].abs().sum()) == 0.0


def test_semantic_vocab_and_subsampling():
    g = cabinet_graph(n_points=32)
    vocab = SemanticVocab(["Door", "body"])
    assert len(vocab) == 3 and vocab.index("door") == vocab.index("DOOR") > 0
    assert vocab.index("handle") == 0
    t = graph_tensors(g, vocab, n_points=10)
    assert t.points.shape == (6, 10, 3)
    assert t.semantic.tolist() == [0, vocab.index("body"), vocab.index("door"), 0, 0, 0]


def test_edge_features_layout_and_rotation_invariants():
    t = graph_tensors(cabinet_graph())
    ef = edge_features(t.edges, t.obb_center, t.obb_axes, t.obb_size, t.contact, t.distance)
    assert ef.shape == (t.n_edges, EDGE_DIM)
    i, j = t.edges[:, 0], t.edges[:, 1]
    torch.testing.assert_close(ef[:, :3], t.obb_center[i] - t.obb_center[j])
    torch.testing.assert_close(ef[:, -2], t.contact.float())
    # under a yaw rotation the frame-relative parts (|dc|, local offsets, axis dots, sizes) stay put
    r = t.rotated(yaw_rotation(0.7))
    ef_r = edge_features(r.edges, r.obb_center, r.obb_axes, r.obb_size, r.contact, r.distance)
    torch.testing.assert_close(ef_r[:, 3:], ef[:, 3:], atol=1e-5, rtol=1e-5)
    assert not torch.allclose(ef_r[:, :3], ef[:, :3])
    # rotated ground truth stays consistent: the door's axis is still vertical (yaw about y)
    k = int(torch.nonzero(t.edge_fine == FINE_INDEX["R_V_S"])[0])
    torch.testing.assert_close(r.axis_direction[k], t.axis_direction[k], atol=1e-6, rtol=0)


def test_collate_offsets_and_coarse_labels():
    ts = [graph_tensors(cabinet_graph(seed=s, jitter=0.1, n_points=16)) for s in range(3)]
    b = collate(ts)
    assert b.n_nodes == 18 and b.n_edges == 3 * ts[0].n_edges
    assert b.node_feat.shape == (18, NODE_DIM)
    assert b.node_offsets.tolist() == [0, 6, 12, 18]
    assert b.parent[6:12].tolist() == [-1, 6, 6, 6, 9, 9]
    assert int(b.edges[ts[0].n_edges:].min()) >= 6
    assert b.node_graph.tolist() == [0] * 6 + [1] * 6 + [2] * 6
    coarse = b.edge_labels("coarse")
    fine = b.edge_labels("fine")
    assert bool((coarse[fine == FINE_INDEX["R_V_S"]] == COARSE_INDEX["R"]).all())
    assert bool((coarse[fine == FINE_INDEX["P_H"]] == COARSE_INDEX["P"]).all())
    with pytest.raises(ValueError):
        b.edge_labels("medium")
    # random subsets with a generator are reproducible
    b1 = collate(ts, n_points=8, generator=torch.Generator().manual_seed(3))
    b2 = collate(ts, n_points=8, generator=torch.Generator().manual_seed(3))
    torch.testing.assert_close(b1.points, b2.points)
    with pytest.raises(ValueError):
        collate([])


def test_bad_graphs_raise_kinmo_data_error():
    g = cabinet_graph()
    g.points = g.points[:, :, :2]
    with pytest.raises(KinmoDataError, match="points"):
        graph_tensors(g)
    g = cabinet_graph()
    g.edge_fine = g.edge_fine.copy()
    g.edge_fine[0] = 42
    with pytest.raises(KinmoDataError, match="unknown type"):
        graph_tensors(g)
    g = cabinet_graph()
    k = int(np.flatnonzero(g.edge_fine == FINE_INDEX["P_H"])[0])
    g.edge_axis_direction = g.edge_axis_direction.copy()
    g.edge_axis_direction[k] = np.nan
    with pytest.raises(KinmoDataError, match="axis"):
        graph_tensors(g)


def _box_surface(rng, half, n=600):
    """Points on the surface of an axis-aligned box of half-extents ``half``."""
    p = rng.uniform(-1.0, 1.0, size=(n, 3))
    face = rng.integers(0, 3, size=n)
    p[np.arange(n), face] = np.sign(rng.uniform(-1.0, 1.0, size=n))
    return p * half


def test_quarter_turns_are_exact_and_obb_signs_match_a_fit_of_the_turned_points():
    from kinmo.features import canonical_obb_axes, quarter_turn
    from kinmo.geometry.obb import fit_obb

    for k in range(4):
        q = quarter_turn(k)
        assert set(np.unique(q)) <= {-1.0, 0.0, 1.0} and np.linalg.det(q) == 1.0
        np.testing.assert_allclose(q, yaw_rotation(k * np.pi / 2), atol=1e-12)
    rng = np.random.default_rng(3)
    checked = 0
    for _ in range(20):
        a = np.linalg.qr(rng.normal(size=(3, 3)))[0]
        a *= np.sign(np.linalg.det(a))
        pts = _box_surface(rng, np.array([1.0, 0.6, 0.3])) @ a.T + rng.normal(size=3)
        fit = fit_obb(pts)
        for k in (1, 2, 3):
            q = quarter_turn(k)
            turned = fit_obb(pts @ q.T)
            got = canonical_obb_axes(torch.from_numpy((fit.axes @ q.T)[None]))[0].numpy()
            np.testing.assert_allclose(got, turned.axes, atol=1e-6)
            checked += 1
    assert checked == 60


def test_tied_obb_rows_are_ordered_as_a_fit_of_the_turned_points():
    """Issue 36: a part with a square section (two equal sides) gets its tied axes in the order
    the Rust fit gives the turned part, so the quarter-turn average does not depend on the
    facing an object comes in; without ``sizes`` (the order before) they come out swapped."""
    from kinmo.features import canonical_obb_axes, quarter_turn
    from kinmo.geometry.obb import fit_obb

    rng = np.random.default_rng(5)
    swapped = 0
    for half in ([1.0, 0.5, 0.5], [0.7, 0.7, 0.3], [0.4, 0.9, 0.4]):
        pts = _box_surface(rng, np.array(half), n=2000)
        fit = fit_obb(pts)
        sizes = torch.from_numpy(2.0 * fit.half_extents[None])
        for k in (1, 2, 3):
            q = quarter_turn(k)
            turned = fit_obb(pts @ q.T)
            rotated = torch.from_numpy((fit.axes @ q.T)[None])
            got = canonical_obb_axes(rotated, sizes)[0].numpy()
            np.testing.assert_allclose(got, turned.axes, atol=1e-6)
            swapped += not np.allclose(canonical_obb_axes(rotated)[0].numpy(), turned.axes, atol=1e-6)
    assert swapped > 0


def test_turned_tensors_turn_labels_with_the_shape_and_four_turns_give_it_back():
    t = graph_tensors(cabinet_graph(n_points=32))
    one = t.turned(1)
    q = torch.as_tensor(np.array([[0.0, 0, 1], [0, 1, 0], [-1, 0, 0]]), dtype=torch.float32)
    torch.testing.assert_close(one.points, t.points @ q.T)
    torch.testing.assert_close(one.axis_direction, t.axis_direction @ q.T)
    back = t.turned(1).turned(1).turned(1).turned(1)
    for name in ("points", "obb_center", "axis_direction", "axis_origin"):
        torch.testing.assert_close(getattr(back, name), getattr(t, name))
    # the boxes come back in the fit's canonical row order (this hand-made graph's tied rows
    # are not in it)
    from kinmo.features import canonical_obb_axes

    torch.testing.assert_close(back.obb_axes, canonical_obb_axes(t.obb_axes, t.obb_size))
    # every row of the turned boxes keeps the sign rule: its largest component positive
    for r in range(2):
        row = one.obb_axes[:, r, :]
        lead = row.gather(1, row.abs().argmax(dim=1, keepdim=True))
        assert bool((lead > 0).all())
