"""Flattened hierarchies and dropped names (kinmo.data.augment, issue 22) on real objects."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from kinmo.data.augment import drop_names, flat_groups, flat_variants, flatten_shape
from kinmo.data.build import build_graph
from kinmo.data.model import JointType
from kinmo.data.readers import find_shapes, read_shape
from kinmo.features import SemanticVocab


@pytest.fixture(scope="module")
def shapes(mobility_root):
    """A few labelled objects whose PartNet hierarchy is deeper than a root and leaves."""
    out = []
    for folder in find_shapes(mobility_root):
        s = read_shape(folder)
        depth = max(s.hierarchy.depth(n) for n in s.hierarchy.order)
        n_moving = sum(lk.joint.type in (JointType.HINGE, JointType.SLIDER) for lk in s.links)
        if depth >= 2 and 1 <= n_moving <= 3 and len(s.hierarchy.order) <= 40:
            out.append(s)
        if len(out) == 3:
            break
    assert len(out) == 3
    return out


def test_link_flattening_has_a_leaf_per_link_and_the_joints(shapes):
    for s in shapes:
        g = build_graph(flatten_shape(s, "link", names=False), n_points=16)
        with_parts = [lk for lk in s.links if lk.parts]
        n = g.n_nodes - 1
        assert n >= len(with_parts)
        assert g.parent[0] == -1 and np.all(g.parent[1:] == 0)
        assert g.node_names == ["unknown"] + [f"part_{k}" for k in range(n)]
        pairs = {tuple(e) for e in g.sibling_edges.tolist()}
        assert pairs == set(itertools.permutations(range(1, n + 1), 2))
        # link k (sorted by id) is leaf k + 1 and holds the meshes of all its PartNet leaves
        for k, lk in enumerate(sorted(with_parts, key=lambda lk: lk.id)):
            assert g.node_link[k + 1] == lk.id
        node_of = {int(g.node_link[v]): v for v in range(1, n + 1)}
        # every moving joint between a link and its parent link labels the edge child -> parent
        by_id = {lk.id: lk for lk in s.links}
        for lk in s.links:
            if lk.joint.type not in (JointType.HINGE, JointType.SLIDER) or lk.parent < 0:
                continue
            par = lk.parent
            while by_id[par].joint.type in (JointType.STATIC, JointType.HEAVY, JointType.JUNK) \
                    and by_id[par].parent >= 0:
                par = by_id[par].parent
            e = np.flatnonzero((g.sibling_edges[:, 0] == node_of[lk.id])
                               & (g.sibling_edges[:, 1] == node_of[par]))
            assert len(e) == 1
            assert g.edge_link[e[0]] == lk.id
            np.testing.assert_allclose(g.edge_axis_direction[e[0]], lk.joint.direction, atol=1e-9)


def test_leaf_flattening_keeps_every_partnet_leaf(shapes):
    for s in shapes:
        leaves = [n for n in s.hierarchy.order if s.hierarchy.nodes[n].is_leaf]
        flat = flatten_shape(s, "leaf")
        assert len(flat.hierarchy.order) == 1 + len(leaves)
        assert [flat.hierarchy.nodes[k + 1].objs for k in range(len(leaves))] == \
            [s.hierarchy.nodes[n].objs for n in leaves]
        assert [flat.hierarchy.nodes[k + 1].name for k in range(len(leaves))] == \
            [s.hierarchy.nodes[n].name for n in leaves]
        # every link now lists exactly the new leaves of its PartNet leaves
        for old, new in zip(s.links, flat.links):
            assert new.joint is old.joint
            want = sorted(1 + leaves.index(x) for p in old.parts for x in s.hierarchy.leaves(p))
            assert sorted(new.parts) == want
        g = build_graph(flat, n_points=8)
        assert g.has_labels and np.any(g.edge_link >= 0)


def test_flat_groups_partition_the_leaves(shapes):
    for s in shapes:
        for mode in ("link", "leaf"):
            got = sorted(x for _, g in flat_groups(s, mode) for x in g)
            assert got == sorted(n for n in s.hierarchy.order if s.hierarchy.nodes[n].is_leaf)
    with pytest.raises(ValueError):
        flat_groups(shapes[0], "tree")


def test_flat_variants_are_seeded(shapes):
    graphs = [build_graph(s, n_points=8) for s in shapes]
    a = flat_variants(graphs, 1.0, 0.5, seed=3)
    b = flat_variants(graphs, 1.0, 0.5, seed=3)
    assert len(a) == len(b) == 2 * len(graphs)
    assert a[: len(graphs)][0].shape_id == graphs[0].shape_id
    assert [g.meta.get("flattened") for g in a] == [g.meta.get("flattened") for g in b]
    assert [g.node_names for g in a] == [g.node_names for g in b]
    for g, h in zip(a, b):
        np.testing.assert_array_equal(g.points, h.points)
    assert all(g.meta["flattened"] in ("link", "leaf") for g in a[len(graphs):])
    assert flat_variants(graphs, 0.0, 0.0) == graphs
    dropped = flat_variants(graphs, 0.0, 1.0)
    assert all(g.meta.get("names_dropped") for g in dropped)
    with pytest.raises(ValueError):
        flat_variants(graphs, 1.5, 0.0)


def test_dropped_names_are_unknown_to_the_vocabulary(shapes):
    g = build_graph(shapes[0], n_points=8)
    vocab = SemanticVocab.from_graphs([g])
    d = drop_names(g)
    assert d.points is g.points and d.node_names != g.node_names
    assert all(vocab.index(n) == 0 for n in d.node_names)
    known = [n for n in g.node_names if vocab.index(n) > 0]
    assert known
    assert vocab.index(f"{known[0]}_2") == vocab.index(known[0].upper()) > 0
    assert SemanticVocab(["door", "door_3", "part_1", "unknown"]).names == ["door"]
