"""Fit the learned candidate selector on out-of-fold GNN predictions (``kinmo train ranker``).

The ranker of :mod:`kinmo.refine.selector` must learn how far to trust the GNN's priors on
objects the GNN has *not* been trained on: on its own training objects the GNN is nearly
always right. So the training objects of a split are cut into ``k`` folds (stratified by
category, seeded), a motion GNN is trained on ``k - 1`` folds (the same preset) and predicts
the held-out fold; the predictions of all folds are the out-of-fold (OOF) predictions. Every
edge the OOF GNN predicts moving that truly moves gives one group: its candidates
(:func:`~kinmo.refine.selector.edge_candidates`), their features and labels (within 5° and
0.05 of the shape's diagonal of the true axis). The semantic direction prior
(:mod:`~kinmo.refine.semantic_prior`) is built from the same training objects, each shape left
out of its own features. The ranker is fit on those groups; its
calibration (Platt scaling of the winner's probability) is fit on ranker predictions that are
themselves out-of-fold over the same folds. The test split is never touched.

Outputs (``OUT/``): ``ranker.json`` (:meth:`~kinmo.refine.ranker.Ranker.save`),
``folds/<f>/`` (the fold GNN runs, reused when present: an interrupted fit resumes), and
``oof_groups.npz`` (the features, labels and edge metadata, for analysis).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from kinmo.data.graph import PartGraph
from kinmo.refine.features import FEATURE_GROUPS, FEATURES
from kinmo.refine.ranker import Ranker, calibrate, fit_ranker
from kinmo.refine.selector import (
    candidate_features,
    candidate_labels,
    edge_candidates,
    shape_meshes,
)
from kinmo.refine.semantic_prior import SemanticPrior

__all__ = ["DEFAULT_FEATURES", "EdgeGroups", "collect_groups", "fit_selector", "fold_ids",
           "joint_weights", "oof_predictions", "select_groups", "train_ranker"]


def fold_ids(ids: Sequence[str], categories: Sequence[str], k: int, seed: int = 0) -> list[int]:
    """Fold of each id (``0..k-1``): within each category a seeded shuffle dealt round-robin.

    Raises
    ------
    ValueError
        ``k < 2`` or mismatched lengths.
    """
    if k < 2:
        raise ValueError(f"folds: expected >= 2, got {k}")
    if len(ids) != len(categories):
        raise ValueError("fold_ids: ids and categories differ in length")
    rng = np.random.default_rng(seed)
    out = [0] * len(ids)
    start = 0
    for cat in sorted(set(categories)):
        members = sorted(n for n, c in enumerate(categories) if c == cat)
        members = [members[m] for m in rng.permutation(len(members))]
        for r, n in enumerate(members):
            out[n] = (start + r) % k
        start += len(members)
    return out


def oof_predictions(graphs: Sequence[PartGraph], train_ids: Sequence[str], out: Path, *,
                    k: int = 3, preset: str = "quick", types: str = "fine", seed: int = 0,
                    threads: int = 1, progress: bool = False, epochs: int | None = None
                    ) -> dict[str, object]:
    """Out-of-fold predictions of the training objects (module docstring).

    Parameters
    ----------
    graphs : sequence of PartGraph
        Labelled graphs (at least those of ``train_ids``).
    train_ids : sequence of str
        The training split's ids; only these are used.
    out : Path
        ``out/folds/<types>_<f>/`` receive the fold runs (skipped when their
        ``model.pt`` exists).
    k, preset, types, seed, threads
        Folds and the GNN's training options (:func:`kinmo.train.config.preset`).
    progress : bool
    epochs : int, optional
        The fold GNNs' epochs instead of the preset's (``kinmo train all --preset tiny``).

    Returns
    -------
    dict of str to kinmo.predict.ShapePrediction
        By shape id, with :attr:`~kinmo.predict.ShapePrediction.priors`.
    """
    from kinmo.predict import predict_graphs
    from kinmo.train.config import preset as make_preset
    from kinmo.train.gnn import load_run, train_gnn
    from kinmo.train.split import Split

    by_id = {g.shape_id: g for g in graphs}
    ids = [i for i in sorted(train_ids) if i in by_id]
    cats = [by_id[i].category for i in ids]
    folds = fold_ids(ids, cats, k, seed)
    preds: dict[str, object] = {}
    for f in range(k):
        held = [i for i, ff in zip(ids, folds) if ff == f]
        rest = [i for i, ff in zip(ids, folds) if ff != f]
        run_dir = out / "folds" / f"{types}_{f}"
        if not (run_dir / "model.pt").is_file():
            # "auto": CUDA where there is one (the paper preset's fold GNNs take hours on
            # a CPU), the CPU elsewhere, as every other GNN training of kinmo
            cfg = make_preset(preset, types=types, seed=seed, threads=threads, device="auto",
                              epochs=epochs)
            split = Split(rest, held, {i: by_id[i].category for i in ids}, seed, 1.0 / k)
            train_gnn([by_id[i] for i in ids], run_dir, cfg, split, progress=progress)
        run = load_run(run_dir, "cpu")
        for p in predict_graphs(run, [by_id[i] for i in held]):
            preds[p.shape_id] = p
    return preds


@dataclass
class EdgeGroups:
    """Labelled candidate groups of moving edges.

    Attributes
    ----------
    x : list of (C, len(FEATURES)) float64
    y : list of (C,) bool
    angle, dist : list of (C,) float64
        Each candidate's angle (degrees) and line distance (/ shape diagonal) to the truth.
    shape_id, category : list of str
    edge : list of int
    gnn_angle, gnn_dist : list of float
        The GNN's own error on the edge.
    revolute : list of bool
    joint : list of str
        The moving part of each edge, ``"shape_id/node/type set"``. One joint of the mobility
        tree is one moving part, whatever the number of its sibling edges (a drawer touching
        20 panels gives 20 groups), so the per-joint statistics of :func:`fit_selector`
        weight each group by one over its part's group count. May be empty (older groups):
        no per-joint statistics then.
    """

    x: list[np.ndarray]
    y: list[np.ndarray]
    angle: list[np.ndarray]
    dist: list[np.ndarray]
    shape_id: list[str]
    category: list[str]
    edge: list[int]
    gnn_angle: list[float]
    gnn_dist: list[float]
    revolute: list[bool]
    joint: list[str] = field(default_factory=list)

    def save(self, path: Path) -> None:
        """Write all groups into one ``.npz`` (ragged arrays concatenated with offsets)."""
        from kinmo.io import atomic_path

        sizes = np.array([len(y) for y in self.y], dtype=np.int64)
        with atomic_path(path) as tmp, open(tmp, "wb") as fh:
            np.savez_compressed(
                fh, x=np.vstack(self.x) if self.x else np.zeros((0, len(FEATURES))),
                y=np.concatenate(self.y) if self.y else np.zeros(0, bool),
                angle=np.concatenate(self.angle) if self.angle else np.zeros(0),
                dist=np.concatenate(self.dist) if self.dist else np.zeros(0),
                sizes=sizes, shape_id=np.array(self.shape_id), category=np.array(self.category),
                edge=np.array(self.edge), gnn_angle=np.array(self.gnn_angle),
                gnn_dist=np.array(self.gnn_dist), revolute=np.array(self.revolute),
                joint=np.array(self.joint),
                features=np.array(FEATURES))


def collect_groups(predictions: Sequence, *, seed: int = 0, with_meshes: bool = True,
                   semantic: SemanticPrior | None = None) -> EdgeGroups:
    """Candidate groups of every truly moving edge that a prediction calls moving.

    Parameters
    ----------
    predictions : sequence of kinmo.predict.ShapePrediction
        Of labelled graphs (with :attr:`~kinmo.predict.ShapePrediction.priors`).
    seed : int
    with_meshes : bool
        Load each shape's meshes for the swept-collision terms
        (:func:`~kinmo.refine.selector.shape_meshes`).
    semantic : SemanticPrior, optional
        The training objects' direction prior; each shape is left out of its own
        (``exclude``), so the ``sem_prior`` features are out-of-fold like the GNN's.

    Returns
    -------
    EdgeGroups
    """
    from kinmo.data.model import FINE_TYPES
    from kinmo.metrics.axis import axis_angle_deg, line_distance
    from kinmo.refine.selector import GNNPriors

    out = EdgeGroups([], [], [], [], [], [], [], [], [], [], [])
    for p in predictions:
        g = p.graph
        pri = p.priors if p.priors is not None else GNNPriors(p.edges.probs, p.type_names)
        names = p.type_names
        lab = np.argmax(p.edges.probs, axis=1)
        meshes = shape_meshes(g) if with_meshes else None
        for k, (i, j) in enumerate(np.asarray(g.sibling_edges).reshape(-1, 2)):
            t_true = FINE_TYPES[int(g.edge_fine[k])]
            t_pred = names[int(lab[k])]
            if t_true in ("Fixed", "None") or t_pred in ("Fixed", "None"):
                continue
            cands, frames = edge_candidates(g, int(i), int(j), t_pred, p.edges.direction[k],
                                            p.edges.origin[k])
            x, _ = candidate_features(g, int(i), int(j), k, cands, frames, pri,
                                      p.edges.direction[k], p.edges.origin[k], None, meshes,
                                      seed=seed, semantic=semantic, exclude=g.shape_id)
            to, td = g.edge_axis_origin[k], g.edge_axis_direction[k]
            rev = not t_true.startswith("P_")
            y = candidate_labels(cands, to, td, float(g.scale), rev)
            ang = np.atleast_1d(axis_angle_deg(cands.directions, np.broadcast_to(td, (len(cands), 3))))
            dist = np.atleast_1d(line_distance(cands.origins, cands.directions,
                                               np.broadcast_to(to, (len(cands), 3)),
                                               np.broadcast_to(td, (len(cands), 3)))) / g.scale
            out.x.append(x)
            out.y.append(y)
            out.angle.append(np.asarray(ang, float))
            out.dist.append(np.asarray(dist, float) if rev else np.zeros(len(cands)))
            out.shape_id.append(g.shape_id)
            out.category.append(g.category)
            out.edge.append(k)
            out.gnn_angle.append(float(axis_angle_deg(p.edges.direction[k], td)))
            out.gnn_dist.append(float(line_distance(p.edges.origin[k], p.edges.direction[k], to, td))
                                / g.scale if rev else 0.0)
            out.revolute.append(rev)
            type_set = "fine" if len(names) == len(FINE_TYPES) else "coarse"
            out.joint.append(f"{g.shape_id}/{int(i)}/{type_set}")
    return out


def select_groups(groups: EdgeGroups, ranker: Ranker) -> tuple[np.ndarray, np.ndarray]:
    """The ranker's choice on every group: ``(index (G,) int64, p_max (G,) float64)``."""
    idx, pm = [], []
    for x in groups.x:
        p = ranker.probabilities(x)
        idx.append(int(np.argmax(p)))
        pm.append(float(p.max()))
    return np.asarray(idx, np.int64), np.asarray(pm)


def fit_selector(groups: EdgeGroups, *, features: tuple[str, ...] = FEATURES, k: int = 3,
                 seed: int = 0, l2: float = 0.1, per_joint: bool = True) -> tuple[Ranker, dict]:
    """Fit the ranker on all groups and its Platt calibration on ranker-OOF choices.

    Parameters
    ----------
    groups : EdgeGroups
    features : tuple of str
    k : int
        Folds (by shape) of the calibration's inner cross-validation.
    seed : int
    l2 : float
    per_joint : bool
        Weight each group by one over the number of groups of its moving part
        (``groups.joint``; uniform when the groups have no parts), so that every joint
        counts once, as in the per-joint evaluation of Table 1, and a drawer touching 20
        panels does not count 20 times. On the OOF groups of the 132 training objects, over
        five fold seeds: per-joint angle 8.71 ± 0.48° → 8.67 ± 0.22°, per-joint line
        distance 0.047 → 0.039 (docs/results/table1_four_settings.md, fourth round).

    Returns
    -------
    (Ranker, dict)
        The calibrated ranker and the cross-validated numbers (``oof_top1``: share of groups
        whose choice is right; ``oof_angle``/``oof_dist`` means of the chosen candidates;
        ``gnn_angle``/``gnn_dist`` the GNN's own; ``recall``: share with a right candidate;
        with ``groups.joint``, the same per joint, ``oof_joint_angle``, ``oof_joint_dist``,
        ``gnn_joint_angle``, ``gnn_joint_dist``: each moving part weighs 1 however many
        sibling edges it has, as in the per-joint evaluation of Table 1).
    """
    shapes = sorted(set(groups.shape_id))
    cat_of = {s: c for s, c in zip(groups.shape_id, groups.category)}
    f_of = dict(zip(shapes, fold_ids(shapes, [cat_of[s] for s in shapes], k, seed)))
    gf = np.array([f_of[s] for s in groups.shape_id])
    pairs = list(zip(groups.x, groups.y))
    per_part = joint_weights(groups)
    wj = per_part if per_joint else np.ones(len(pairs))
    chosen = np.zeros(len(pairs), np.int64)
    pmax = np.zeros(len(pairs))
    for f in range(k):
        tr_idx = np.flatnonzero(gf != f)
        r = fit_ranker([pairs[n] for n in tr_idx], features=features, l2=l2, seed=seed,
                       weights=wj[tr_idx])
        for n in np.flatnonzero(gf == f):
            p = r.probabilities(groups.x[n])
            chosen[n], pmax[n] = int(np.argmax(p)), float(p.max())
    correct = np.array([bool(y[c]) for y, c in zip(groups.y, chosen)])
    ranker = fit_ranker(pairs, features=features, l2=l2, seed=seed, weights=wj)
    ranker.platt = calibrate(pmax, correct)
    conf = np.array([ranker.confidence(p) for p in pmax])
    stats = {
        "groups": len(pairs),
        "recall": float(np.mean([y.any() for y in groups.y])) if pairs else float("nan"),
        "oof_top1": float(correct.mean()) if pairs else float("nan"),
        "oof_angle": float(np.mean([a[c] for a, c in zip(groups.angle, chosen)])),
        "oof_dist": float(np.mean([d[c] for d, c, r in zip(groups.dist, chosen, groups.revolute)
                                   if r])),
        "gnn_angle": float(np.mean(groups.gnn_angle)),
        "gnn_dist": float(np.mean([d for d, r in zip(groups.gnn_dist, groups.revolute) if r])),
        **_joint_stats(groups, chosen, per_part),
        "calibrated_kept_0.6": float(np.mean(conf >= 0.6)),
        "calibrated_kept_0.6_correct": float(correct[conf >= 0.6].mean()) if (conf >= 0.6).any()
        else float("nan"),
    }
    ranker.meta.update({"features_fit": list(features), "folds": k, "seed": seed, "l2": l2,
                        "per_joint": per_joint, "cv": stats})
    return ranker, {**stats, "chosen": chosen, "pmax": pmax, "correct": correct}


def joint_weights(groups: EdgeGroups) -> np.ndarray:
    """``(G,) float64``: one over the number of groups of each group's moving part.

    Ones when ``groups.joint`` is empty (groups collected without parts).
    """
    from collections import Counter

    if len(groups.joint) != len(groups.y):
        return np.ones(len(groups.y))
    n_of = Counter(groups.joint)
    return np.array([1.0 / n_of[k] for k in groups.joint], dtype=np.float64)


def _joint_stats(groups: EdgeGroups, chosen: np.ndarray, w: np.ndarray) -> dict[str, float]:
    """Per-joint means of the chosen and the GNN's angle and distance (see :func:`fit_selector`).

    ``w`` is :func:`joint_weights` of ``groups``.
    """
    if not groups.y or len(groups.joint) != len(groups.y):
        return {}
    rv = np.asarray(groups.revolute, bool)
    a = np.array([x[c] for x, c in zip(groups.angle, chosen)])
    d = np.array([x[c] for x, c in zip(groups.dist, chosen)])
    ga, gd = np.asarray(groups.gnn_angle, float), np.asarray(groups.gnn_dist, float)

    def mean(v: np.ndarray, m: np.ndarray) -> float:
        return float((v * w)[m].sum() / w[m].sum()) if m.any() else float("nan")

    every = np.ones(len(w), bool)
    return {"joints": float(w.sum()), "oof_joint_angle": mean(a, every),
            "oof_joint_dist": mean(d, rv), "gnn_joint_angle": mean(ga, every),
            "gnn_joint_dist": mean(gd, rv)}


#: Features of the default ranker: all but the axis network's feasibility (the OOF groups are
#: built without a network, so that the selector runs without one) and the point proxy of
#: the collision (``collide_*``), which the swept collision supersedes: on the 1,410
#: out-of-fold groups of the 132 training objects (docs/results/table1_four_settings.md)
#: it is the one group whose removal improves both the OOF angle (9.47 -> 9.11 deg) and the
#: OOF line distance (0.0464 -> 0.0456).
DEFAULT_FEATURES: tuple[str, ...] = tuple(
    f for f in FEATURES if f != "feasibility" and f not in FEATURE_GROUPS["collision"])


def train_ranker(data: str | Path, out: str | Path, split: str | Path, *, folds: int = 3,
                 preset: str = "quick", types: Sequence[str] = ("fine", "coarse"), seed: int = 0,
                 threads: int = 1, progress: bool = True, epochs: int | None = None
                 ) -> tuple[Ranker, dict]:
    """``kinmo train ranker``: OOF GNNs on the split's training objects, then the ranker.

    Parameters
    ----------
    data : str or Path
        A ``kinmo prepare`` cache of PartNet-Mobility (labelled).
    out : str or Path
        Output folder: ``ranker.json``, ``cv.json``, ``oof_groups.npz``, ``folds/``.
    split : str or Path
        The GNN runs' ``split.json``: only its ``train`` ids are used.
    folds, preset, seed, threads
        OOF folds and the fold GNNs' training options.
    epochs : int, optional
        The fold GNNs' epochs instead of the preset's.
    types : sequence of {"fine", "coarse"}
        Fold GNNs of these type sets; their groups are pooled (one ranker serves both).
    progress : bool

    Returns
    -------
    (Ranker, dict)
        The ranker (also written) and the cross-validated numbers (:func:`fit_selector`).

    Raises
    ------
    KinmoDataError
        No labelled graph of the split's training ids in ``data``, or no moving edge.
    """
    from kinmo.errors import KinmoDataError
    from kinmo.io import write_json
    from kinmo.train.gnn import load_cache
    from kinmo.train.split import Split

    out = Path(out)
    sp = Split.load(split)
    train = set(sp.train)
    graphs = [g for g in load_cache(data) if g.shape_id in train and g.has_labels]
    if not graphs:
        raise KinmoDataError(data, "no labelled graph of the split's training ids")
    semantic = SemanticPrior.from_graphs(graphs)
    parts = []
    for t in types:
        preds = oof_predictions(graphs, sorted(train), out, k=folds, preset=preset, types=t,
                                seed=seed, threads=threads, progress=progress, epochs=epochs)
        parts.append(collect_groups(list(preds.values()), seed=seed, semantic=semantic))
    groups = EdgeGroups(*[[v for p in parts for v in getattr(p, f)]
                          for f in EdgeGroups.__dataclass_fields__])
    if not groups.y:
        raise KinmoDataError(data, "no moving edge predicted moving in the out-of-fold predictions")
    ranker, stats = fit_selector(groups, features=DEFAULT_FEATURES, k=folds, seed=seed)
    ranker.semantic = semantic
    ranker.meta["trained_on"] = {"data": str(data), "split": str(split), "types": list(types),
                                 "preset": preset, "folds": folds}
    groups.save(out / "oof_groups.npz")
    ranker.save(out / "ranker.json")
    write_json(out / "cv.json", {k: v for k, v in stats.items() if not isinstance(v, np.ndarray)})
    return ranker, stats
