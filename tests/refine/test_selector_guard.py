"""Guard of Table 1's first claim (issue 34): the learned selector overrules a GNN's confident
90° flips on real objects.

The regression of issue 34: the ranker, fit on fold GNNs whose flips were unsure, learned to
trust the GNN's axis-candidate prior, and kept the GNN's axis on every test edge, where the
flips were sure. Here the GNN is simulated on real shared objects so that its flips are
exactly as confident as its right axes (the prior says nothing about which are wrong); the
selector, fit and scored out of fold as ``kinmo train ranker`` fits it, must still find the
true axes from geometry and the semantic prior, and lower the per-category mean axis error
by a stated margin.
"""

from __future__ import annotations

from collections import defaultdict

import numpy as np

from kinmo.data.build import build_graph
from kinmo.data.model import FINE_TYPES
from kinmo.data.readers import find_shapes, read_meta, read_shape
from kinmo.mobility_tree import EdgePrediction, build_mobility_tree
from kinmo.predict import ShapePrediction
from kinmo.refine.fit_selector import DEFAULT_FEATURES, collect_groups, fit_selector
from kinmo.refine.selector import GNNPriors
from kinmo.refine.semantic_prior import SemanticPrior

#: Share of moving parts whose axis the simulated GNN flips by 90° (the motion GNN flipped
#: 7% of the test split's moving edges of the shared data, issue 34).
FLIP_SHARE = 0.07
#: The selector's per-category mean angle must be at least this much below the GNN's
#: (the issue's bar on real out-of-fold predictions is 30%).
MARGIN = 0.30


def _objects(mobility_root, per_category: int = 2) -> list:
    """Up to ``per_category`` labelled objects of every category, in id order."""
    by_cat: dict[str, list] = defaultdict(list)
    for d in find_shapes(mobility_root):
        cat, _ = read_meta(d)
        if len(by_cat[cat]) < per_category:
            by_cat[cat].append(d)
    return [d for ds in by_cat.values() for d in ds]


def _confident_gnn(g, rng: np.random.Generator) -> ShapePrediction:
    """The truth with a share of moving parts flipped by 90°, every axis equally sure."""
    fine = np.asarray(g.edge_fine)
    n_e = len(fine)
    probs = np.full((n_e, 10), 0.01 / 9)
    probs[np.arange(n_e), fine] = 0.99
    d = np.where(np.isfinite(g.edge_axis_direction), g.edge_axis_direction, [0.0, 1.0, 0.0])
    o = np.nan_to_num(np.asarray(g.edge_axis_origin, float), nan=0.0)
    d = d.copy()
    moving = [k for k in range(n_e) if FINE_TYPES[int(fine[k])] not in ("Fixed", "None")]
    flipped = {int(i) for i in {int(g.sibling_edges[k][0]) for k in moving}
               if rng.random() < FLIP_SHARE}
    axis_dirs = np.zeros((n_e, 10, 3))
    axis_prob = np.full((n_e, 10), 0.03 / 9)
    axis_prob[:, 0] = 0.97
    for k in range(n_e):
        i, j = (int(x) for x in g.sibling_edges[k])
        axes = np.asarray(g.obb_axes[i], float)  # columns or rows: both sets span the frame
        if k in moving and i in flipped:
            cos = np.abs(axes @ d[k])
            d[k] = axes[int(np.argmin(cos))]
        axis_dirs[k] = np.vstack([d[k], axes, np.asarray(g.obb_axes[j], float), np.eye(3)])
    e = EdgePrediction(probs, d, o)
    pri = GNNPriors(probs.copy(), FINE_TYPES, axis_prob, axis_dirs)
    return ShapePrediction(g, e, build_mobility_tree(g, e), FINE_TYPES, pri)


def test_selector_overrules_confident_flips_on_real_objects(mobility_root):
    rng = np.random.default_rng(0)
    graphs = [build_graph(read_shape(d), n_points=256, seed=0) for d in _objects(mobility_root)]
    graphs = [g for g in graphs if g.has_labels and len(g.sibling_edges)]
    preds = [_confident_gnn(g, rng) for g in graphs]
    groups = collect_groups(preds, semantic=SemanticPrior.from_graphs(graphs))
    flips = np.array([a > 45 for a in groups.gnn_angle])
    assert 0.05 < flips.mean() < 0.4, "the simulated GNN flips a share of the moving edges"
    ranker, st = fit_selector(groups, features=DEFAULT_FEATURES, k=3, seed=0)
    chosen = st["chosen"]
    # the flips are found: the selector moves off the GNN's line on most of them ...
    fixed = np.array([groups.angle[n][chosen[n]] < 45 for n in np.flatnonzero(flips)])
    assert fixed.mean() >= 0.5, f"only {fixed.mean():.0%} of the confident flips overruled"
    # ... and lowers Table 1's per-category mean and pooled angle by the margin
    assert st["oof_cat_angle"] <= (1 - MARGIN) * st["gnn_cat_angle"], st
    assert st["oof_joint_angle"] <= (1 - MARGIN) * st["gnn_joint_angle"], st
    # right axes are kept: few groups the GNN had right are broken
    broken = np.array([groups.angle[n][chosen[n]] > 45 for n in np.flatnonzero(~flips)])
    assert broken.mean() <= 0.05
    assert ranker.meta["l2"] in (0.003, 0.01, 0.03, 0.1)
