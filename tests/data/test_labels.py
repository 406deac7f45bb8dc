"""Ground-truth motion labels: the geometric rules, the link rules, hand-checked objects."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from kinmo.data.build import build_graph
from kinmo.data.labels import (
    fine_type,
    is_vertical,
    line_segment_distance,
    node_links,
    obb_edges,
    pivot_is_central,
    pivots_are_central,
    rigid_groups,
)
from kinmo.data.model import FINE_TYPES, Joint, JointType, Link
from kinmo.data.readers import read_shape

# ---------------------------------------------------------------------- geometric rules


def test_vertical_threshold_is_45_degrees() -> None:
    for deg, vertical in [(0, True), (44.9, True), (45.0, False), (45.1, False), (90, False),
                          (135.1, True), (180, True)]:
        a = np.radians(deg)
        assert is_vertical(np.array([np.sin(a), np.cos(a), 0.0])) is vertical, deg
        assert is_vertical(3.0 * np.array([0.0, np.cos(a), np.sin(a)])) is vertical, deg


def test_line_segment_distance_matches_dense_sampling() -> None:
    rng = np.random.default_rng(3)
    for _ in range(50):
        o, d = rng.normal(size=3), rng.normal(size=3)
        a, b = rng.normal(size=3), rng.normal(size=3)
        if rng.random() < 0.2:
            b = a + 0.5 * d  # segment parallel to the line
        s = np.linspace(0, 1, 4001)[:, None]
        seg = a + s * (b - a)
        du = d / np.linalg.norm(d)
        rel = seg - o
        brute = np.linalg.norm(rel - (rel @ du)[:, None] * du, axis=1).min()
        got = float(line_segment_distance(o, d, a, b))
        assert got <= brute + 1e-12
        assert got == pytest.approx(brute, abs=2e-3 * np.linalg.norm(b - a) + 1e-9)


def test_obb_edges_are_the_12_box_edges() -> None:
    axes = np.eye(3)
    e = obb_edges(np.zeros(3), axes, np.array([1.0, 2.0, 3.0]))
    assert e.shape == (12, 2, 3)
    lengths = np.sort(np.linalg.norm(e[:, 1] - e[:, 0], axis=1))
    assert np.allclose(lengths, [2] * 4 + [4] * 4 + [6] * 4)
    # every end point is a corner
    assert np.allclose(np.abs(e.reshape(-1, 3)), [1, 2, 3])


def test_centre_versus_side() -> None:
    rng = np.random.default_rng(0)
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    axes = q.T * np.sign(np.linalg.det(q))
    c, h = np.array([0.3, -1.0, 2.0]), np.array([0.5, 0.2, 0.05])
    # through the centre, along any box axis: centre
    for k in range(3):
        assert pivot_is_central(c + 5 * axes[k], axes[k], c, axes, h)
    # along a box edge (a door hinge): side
    edge = obb_edges(c, axes, h)[5]
    assert not pivot_is_central(edge[0], edge[1] - edge[0], c, axes, h)
    # Along the thin axis (cross-section 1 x 0.4), moved 0.1 towards a face: still nearer the
    # centre than the edges across the axis (0.2 away); moved 0.475: side.
    assert pivot_is_central(c + 0.2 * h[0] * axes[0], axes[2], c, axes, h)
    assert not pivot_is_central(c + 0.95 * h[0] * axes[0], axes[2], c, axes, h)
    # Along the middle axis the edges across it bound a 1 x 0.1 cross-section: an axis 0.1
    # off the centre is nearer them (0.05) than the centre: side.
    assert not pivot_is_central(c + 0.2 * h[0] * axes[0], axes[1], c, axes, h)


def test_the_batched_pivot_rule_is_the_same_rule() -> None:
    rng = np.random.default_rng(3)
    for _ in range(20):
        q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
        c, h = rng.normal(size=3), rng.uniform(0.01, 1.0, size=3)
        # random lines, lines along box axes near the centre, and lines along box edges
        o = np.concatenate([c + rng.normal(size=(30, 3)) * h.max(),
                            c + 0.3 * rng.normal(size=(9, 3)) * h, obb_edges(c, q, h)[:, 0]])
        d = np.concatenate([rng.normal(size=(30, 3)), q[np.arange(9) % 3] * 2.0,
                            np.repeat(q, 4, axis=0)])
        got = pivots_are_central(o, d, c, q, h)
        want = [pivot_is_central(o[n], d[n], c, q, h) for n in range(len(o))]
        assert got.tolist() == want
        assert 0 < sum(want) < len(want)  # both outcomes occur
    # one OBB per line (the mobility tree's use): the same as each line against its own box
    qs = [np.linalg.qr(rng.normal(size=(3, 3)))[0] for _ in range(40)]
    cs, hs = rng.normal(size=(40, 3)), rng.uniform(0.01, 1.0, size=(40, 3))
    o = cs + 0.4 * rng.normal(size=(40, 3)) * hs
    d = np.stack([q[n % 3] for n, q in enumerate(qs)])
    got = pivots_are_central(o, d, cs, np.stack(qs), hs)
    assert got.tolist() == [pivot_is_central(o[n], d[n], cs[n], qs[n], hs[n]) for n in range(40)]
    assert 0 < got.sum() < 40


def _joint(t: JointType, d, rotates: bool = False, o=(0.0, 0.0, 0.0)) -> Joint:
    return Joint(t, np.asarray(o, float), np.asarray(d, float) / np.linalg.norm(d), None, rotates)


def test_fine_type_names() -> None:
    c, ax, h = np.zeros(3), np.eye(3), np.array([1.0, 1.0, 0.1])
    assert fine_type(_joint(JointType.SLIDER, [0, 0, 1]), c, ax, h) == "P_H"
    assert fine_type(_joint(JointType.SLIDER, [0, -1, 0]), c, ax, h) == "P_V"
    assert fine_type(_joint(JointType.SLIDER, [1, 0, 0], True), c, ax, h) == "PR_H"
    assert fine_type(_joint(JointType.SLIDER, [0, 1, 0.2], True), c, ax, h) == "PR_V"
    assert fine_type(_joint(JointType.HINGE, [0, 0, 1]), c, ax, h) == "R_H_C"
    assert fine_type(_joint(JointType.HINGE, [0, 1, 0], o=(1, 0, 0)), c, ax, h) == "R_V_S"
    assert fine_type(_joint(JointType.HINGE, [1, 0, 0], o=(0, 1, 0)), c, ax, h) == "R_H_S"
    assert fine_type(_joint(JointType.HINGE, [0, 1, 0]), c, ax, h) == "R_V_C"
    with pytest.raises(ValueError):
        fine_type(Joint(JointType.STATIC), c, ax, h)


# ---------------------------------------------------------------------------- link rules


def test_node_links_and_rigid_groups(cabinet: Path) -> None:
    s = read_shape(cabinet)
    nl = node_links(s.hierarchy, s.links)
    # root spans links; the door node (listed as an inner node) is pure
    assert nl == {0: -1, 1: 3, 2: 0, 3: 0, 4: 0, 5: 1, 6: 2, 7: 4}
    # static base joins the heavy body's group; moving links head their own
    assert rigid_groups(s.links) == {0: 0, 1: 1, 2: 2, 3: 3, 4: 3}


def test_rigid_group_walks_through_chains() -> None:
    j = Joint(JointType.STATIC)
    hinge = _joint(JointType.HINGE, [0, 1, 0])
    links = [
        Link(0, -1, "root", (), Joint(JointType.FREE)),
        Link(1, 0, "a", (), Joint(JointType.HEAVY)),
        Link(2, 1, "b", (), hinge),
        Link(3, 2, "c", (), j),
        Link(4, 3, "d", (), Joint(JointType.JUNK)),
        Link(5, -1, "outlier", (), Joint(JointType.JUNK)),
    ]
    assert rigid_groups(links) == {0: 0, 1: 0, 2: 2, 3: 2, 4: 2, 5: 5}


def _labels(graph) -> dict[tuple[str, str], str]:
    names = graph.node_names
    return {
        (names[i], names[j]): FINE_TYPES[k]
        for (i, j), k in zip(graph.sibling_edges, graph.edge_fine)
    }


def test_cabinet_edge_labels(cabinet: Path) -> None:
    g = build_graph(read_shape(cabinet), n_points=64)
    lab = _labels(g)
    expected = {
        ("door", "body"): "R_V_S", ("door", "base"): "R_V_S",
        ("drawer", "body"): "P_H", ("drawer", "base"): "P_H",
        ("knob", "door"): "R_H_C",
        ("body", "base"): "Fixed", ("base", "body"): "Fixed",
        ("panel", "handle"): "Fixed", ("handle", "panel"): "Fixed",
        # reverse directions, unrelated siblings, grand-parent links
        ("body", "door"): "None", ("base", "drawer"): "None", ("door", "knob"): "None",
        ("knob", "body"): "None", ("drawer", "door"): "None", ("door", "drawer"): "None",
        ("knob", "drawer"): "None", ("drawer", "knob"): "None", ("knob", "base"): "None",
    }
    for k, v in expected.items():
        assert lab[k] == v, k
    assert len(lab) == 5 * 4 + 2
    names = g.node_names
    axis = {
        (names[i], names[j]): (o, d, lk)
        for (i, j), o, d, lk in zip(
            g.sibling_edges, g.edge_axis_origin, g.edge_axis_direction, g.edge_link
        )
    }
    o, d, lk = axis[("door", "body")]
    assert lk == 0 and np.allclose(d, [0, 1, 0])
    # canonical origin: the axis point nearest to the door's OBB centre
    c = g.obb_center[names.index("door")]
    assert np.allclose(o, [0.0, c[1], 0.51])
    o, d, lk = axis[("knob", "door")]
    assert lk == 2 and np.allclose(d, [0, 0, -1]) and np.allclose(o, [0.25, 0.65, 0.535])
    o, d, lk = axis[("drawer", "body")]
    assert lk == 1 and np.allclose(d, [0, 0, 1]) and np.allclose(o[:2], 0)
    for key, (o, d, lk) in axis.items():
        moving = lab[key] not in ("Fixed", "None")
        assert np.isfinite(o).all() == moving and np.isfinite(d).all() == moving
        assert (lk >= 0) == moving
    assert list(g.node_link) == [-1, 3, 0, 0, 0, 1, 2, 4]


# --------------------------------------------------------------- hand-checked real objects


@pytest.mark.exactdata
@pytest.mark.parametrize(
    "shape_id, moving, reference, expected",
    [
        ("10849", "door", "frame", "R_V_S"),  # refrigerator door
        ("20453", "drawer", "back_panel", "P_H"),  # table drawer
        ("10040", "screen_side", "base_side", "R_H_S"),  # laptop lid
    ],
)
def test_hand_checked_objects(
    mobility_root: Path, shape_id: str, moving: str, reference: str, expected: str
) -> None:
    s = read_shape(mobility_root / shape_id)
    g = build_graph(s, n_points=32)
    lab = _labels(g)
    assert lab[(moving, reference)] == expected
    assert lab[(reference, moving)] == "None"
    # every moving edge of the object has the expected motion family
    moving_types = {FINE_TYPES[k] for k, lk in zip(g.edge_fine, g.edge_link) if lk >= 0}
    assert moving_types <= {expected, "R_H_C"}  # the laptop's hinge shaft spins centrally
