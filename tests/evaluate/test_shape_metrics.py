"""Joint matching of a set of predicted links against the truth (kinmo.evaluate.shape_metrics)."""

from __future__ import annotations

import dataclasses

import numpy as np
from motion_cabinet import cabinet_graph, oracle_prediction

from kinmo.data.model import Joint, JointType
from kinmo.evaluate.shape_metrics import leaf_link_map, match_joints
from kinmo.mobility_tree import build_mobility_tree


def test_leaf_links_from_the_links_parts_equal_the_trees():
    g = cabinet_graph(seed=0)
    tree = build_mobility_tree(g, oracle_prediction(g))
    m = leaf_link_map(g, tree.links)
    leaves = np.flatnonzero(g.is_leaf)
    assert m == {int(n): int(tree.leaf_link[n]) for n in leaves}
    # a leaf listed by no link belongs to none
    rest = [dataclasses.replace(lk, parts=()) if lk.name == "door" else lk for lk in tree.links]
    assert leaf_link_map(g, rest)[2] == -1


def test_the_true_links_match_themselves_and_a_still_door_is_missed():
    g = cabinet_graph(seed=0)
    tree = build_mobility_tree(g, oracle_prediction(g))
    n, n_true, pairs = match_joints(g, tree.links)
    assert n == n_true == 2 and sorted(t.name for _, t, _ in pairs) == ["door", "drawer"]
    assert all(iou == 1.0 for _, _, iou in pairs)
    fixed = Joint(JointType.STATIC)
    still = [dataclasses.replace(lk, joint=fixed) if lk.name == "door" else lk for lk in tree.links]
    n, n_true, pairs = match_joints(g, still)
    assert n == 1 and n_true == 2 and [t.name for _, t, _ in pairs] == ["drawer"]
