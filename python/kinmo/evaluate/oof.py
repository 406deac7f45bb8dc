"""Table 1 out of fold on every labelled object (``kinmo eval oof``; issue 34).

The test split of ``kinmo train all`` holds 69 of the 235 shared objects: a per-category effect
of the refinement is hard to see on it (a selector that stopped changing any axis once passed
as "within ±0.5° pooled"). This evaluation predicts **every** labelled object with models that
did not train on it:

1. The objects are cut into ``k`` folds (stratified by category, seeded:
   :func:`kinmo.refine.fit_selector.fold_ids`).
2. Per fold and type set (fine, coarse), a motion GNN is trained on the other folds with the
   configuration of ``kinmo train all``'s own motion GNNs (:func:`kinmo.train.ranker.fold_config`),
   and predicts the held-out fold: the ``GNN_fine`` / ``GNN_coarse`` rows.
3. Per fold, the learned selector (:mod:`kinmo.refine.ranker`) is fit on the candidate groups
   of the *other* folds' out-of-fold predictions (a ranker per type set, as
   :func:`kinmo.train.ranker.train_ranker` fits them; the semantic prior from the other
   folds' objects) and refines the held-out fold's predictions: the ``OBB_fine`` /
   ``OBB_coarse`` rows, through :class:`kinmo.inference.predictor.Predictor` as every command.
4. Per fold, the range prior (:func:`kinmo.ranges.fit_range_prior`, issue 35) is fit on the
   other folds' objects, and the refined rows' joints get their ranges from it, clipped by the
   sweep, as ``kinmo predict`` gives them: the range columns of the ``OBB`` rows score the
   learned ranges on every labelled object, and those of the ``GNN`` rows the tree's default
   ranges (0–90°, 0.3 × size).

5. Per fold, the pseudo-label rule (:mod:`kinmo.evaluate.pseudo_rule`, issue 34) is graded
   on the held-out objects, as ``kinmo train all`` grades it on its test split: the fold's
   fine GNN, selector and range prior score every joint
   (:func:`kinmo.pseudo_label.score_graph`), the fold's coarse GNN is the second model that
   must agree, and every joint of a kept object is graded against the truth. No
   axis-selection network is loaded; the default ranker does not read one
   (:data:`kinmo.refine.fit_selector.DEFAULT_FEATURES` leave its feasibility out), so the
   choice is the one ``kinmo pseudo-label`` makes. On 235 objects this is about 3.4 times
   the test split's 69, so a handful of annotation exceptions (rocker buttons,
   bottom-hinged doors) move it less.

With ``extra`` (``kinmo eval oof --extra CACHE``), the labelled graphs of another cache, e.g.
objects of ``kinmo synth`` prepared by ``kinmo prepare``, join **every** fold GNN's training;
they are never held out, predicted or graded, and the selectors, range priors and semantic
priors are fit on the real objects only, as without them. ``folds/extra.json`` names them: a
folder whose fold GNNs trained with other extra objects is refused, never mixed.

Caveat, stated in the output: the groups a fold's ranker is fit on were predicted by GNNs
that trained on that fold's objects (their features, never their labels, depend on them).

Outputs (``OUT/``): ``table1.csv``, ``table1.md`` (:func:`kinmo.evaluate.tables.write_report`:
per category, the ``mean`` over categories and the pooled ``all`` row), ``oof.json`` (the
per-category mean and pooled joint axis error of the four settings and the selector's gain),
``folds/<types>_<f>/`` (the GNN runs, reused when present: an interrupted run resumes),
``rankers/ranker_<f>.json``, ``ranges/ranges_<f>.json`` and ``pseudo-label-rule/``
(``summary.json``, ``summary.md``: :func:`kinmo.evaluate.pseudo_rule.write_pseudo_rule`;
``oof.json``'s ``pseudo_rule`` is the same document).
"""

from __future__ import annotations

import json
import shutil
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from kinmo.data.cache import load_cache
from kinmo.data.graph import PartGraph
from kinmo.errors import KinmoDataError
from kinmo.evaluate.pseudo_rule import PseudoRuleReport, grade_pseudo_rule, write_pseudo_rule
from kinmo.evaluate.shape_metrics import EvalReport, evaluate_graphs
from kinmo.evaluate.tables import write_report
from kinmo.inference.predictor import Predictor
from kinmo.io import write_json
from kinmo.pseudo_label import PseudoLabelConfig
from kinmo.ranges import fit_range_prior
from kinmo.refine.config import RefineConfig
from kinmo.refine.fit_selector import collect_groups, fold_ids
from kinmo.refine.selector import shape_meshes
from kinmo.refine.semantic_prior import SemanticPrior
from kinmo.train.gnn import load_run
from kinmo.train.ranker import fit_rankers, train_folds

__all__ = ["OOFResult", "SETTINGS", "oof_summary", "oof_table1"]

#: The four settings of Table 1, in the paper's column order.
SETTINGS = ("GNN_coarse", "GNN_fine", "OBB_coarse", "OBB_fine")


def oof_summary(report: EvalReport) -> dict[str, Any]:
    """Per-category mean and pooled joint axis angle error (degrees) of each setting, and the
    selector's relative change ``OBB / GNN - 1`` per type set (negative: the selector helps).

    Parameters
    ----------
    report : EvalReport
        With the columns of :data:`SETTINGS` (those present are used).

    Returns
    -------
    dict
        ``{"angle_joint": {setting: {"mean": deg, "all": deg}}, "recall": {...},
        "gain_fine": {"mean": r, "all": r}, "gain_coarse": {...}}``.
    """
    out: dict[str, Any] = {"angle_joint": {}, "recall": {}, "joint_type_acc": {}}
    for m in report.models:
        for key in ("angle_joint", "recall", "joint_type_acc"):
            out[key][m] = {row: float(report.table[(m, row)][key]) for row in ("mean", "all")}
    for t in ("fine", "coarse"):
        g, o = out["angle_joint"].get(f"GNN_{t}"), out["angle_joint"].get(f"OBB_{t}")
        if g and o:
            out[f"gain_{t}"] = {row: o[row] / g[row] - 1.0 if g[row] > 0 else float("nan")
                                for row in ("mean", "all")}
    return out


@dataclass(frozen=True)
class OOFResult:
    """What :func:`oof_table1` computed (also written, module docstring).

    Attributes
    ----------
    report : EvalReport
        Table 1's four settings (:data:`SETTINGS`), per category.
    pseudo_rule : PseudoRuleReport or None
        The pseudo-label rule graded out of fold (step 5); None when not graded.
    """

    report: EvalReport
    pseudo_rule: PseudoRuleReport | None = None


def oof_table1(
    data: str | Path | Sequence[PartGraph],
    out: str | Path,
    *,
    folds: int = 5,
    preset: str = "quick",
    seed: int = 0,
    workers: int = 1,
    epochs: int | None = None,
    augment: bool = True,
    executor: str = "local",
    progress: bool = True,
    members: int = 0,
    pseudo_rule: bool = True,
    pseudo: PseudoLabelConfig | None = None,
    extra: str | Path | Sequence[PartGraph] | None = None,
) -> OOFResult:
    """Table 1's four settings out of fold on every labelled object (module docstring).

    Parameters
    ----------
    data : str, Path or sequence of PartGraph
        A ``kinmo prepare`` cache of PartNet-Mobility objects (or its graphs); the labelled
        graphs are used.
    out : str or Path
        Output folder (module docstring); an existing one resumes its trained folds.
    folds : int
        ``k`` (at least 2).
    preset, seed, epochs, augment
        The GNNs' training (:func:`kinmo.train.ranker.fold_config`), as ``kinmo train all``.
    workers, executor
        GNNs trained at once, and where (:func:`kinmo.train.ranker.train_folds`).
    progress : bool
    members : int
        Ensemble members of every fold GNN (``folds/<types>_<f>/members/<k>/``,
        :func:`kinmo.train.gnn.train_members`): each fold is then predicted by the average of
        ``1 + members`` GNNs trained with seeds ``seed``, ``seed + 1`` ..., and its ranker is
        fit on the other folds' ensemble predictions.
    pseudo_rule : bool
        Grade the pseudo-label rule out of fold (module docstring, step 5).
    pseudo : PseudoLabelConfig or None
        Its options (``threshold``, ``score``, ``sign``, ``agree_prob``, ``agree_deg`` ...;
        ``refine`` is not used: the fold's selector is); None: ``kinmo pseudo-label``'s
        defaults.
    extra : str, Path, sequence of PartGraph or None
        A cache (or its graphs) whose labelled graphs join every fold GNN's training (module
        docstring); None: none.

    Returns
    -------
    OOFResult
        Table 1 (columns :data:`SETTINGS`, rows per category) and the graded pseudo-label
        rule (also written, module docstring).

    Raises
    ------
    KinmoDataError
        Fewer labelled graphs than folds, or a fold's selector cannot be fit (no candidate
        group of the other folds has a right candidate: too few objects, or GNNs too weak);
        an ``extra`` object whose id is also an evaluated one, or an ``out`` whose fold GNNs
        trained with other extra objects.
    """
    out = Path(out)
    graphs = [g for g in (load_cache(data) if isinstance(data, (str, Path)) else data)
              if g.has_labels and len(g.sibling_edges)]
    if len(graphs) < folds:
        raise KinmoDataError(data if isinstance(data, (str, Path)) else out,
                             f"{len(graphs)} labelled graphs: fewer than --folds {folds}")
    graphs.sort(key=lambda g: g.shape_id)
    ids = [g.shape_id for g in graphs]
    more = _extra_graphs(extra, set(ids), out)
    fold_of = dict(zip(ids, fold_ids(ids, [g.category for g in graphs], folds, seed)))
    train_folds(graphs, ids, out, k=folds, preset=preset, types=("fine", "coarse"), seed=seed,
                threads=1, epochs=epochs, workers=workers, executor=executor, progress=progress,
                augment=augment, members=members, extra=more)
    gnn: dict[str, dict[str, Any]] = {"fine": {}, "coarse": {}}
    runs: dict[tuple[str, int], Any] = {}
    for t in gnn:
        for f in range(folds):
            runs[(t, f)] = load_run(out / "folds" / f"{t}_{f}", "cpu")
            held = [g for g in graphs if fold_of[g.shape_id] == f]
            for p in Predictor(runs[(t, f)]).gnn_predictions(held):
                gnn[t][p.shape_id] = p
    semantic_all = SemanticPrior.from_graphs(graphs)
    groups = {t: collect_groups([gnn[t][i] for i in ids], seed=seed, semantic=semantic_all)
              for t in ("fine", "coarse")}
    refined: dict[str, dict[str, Any]] = {"fine": {}, "coarse": {}}
    pseudo = pseudo or PseudoLabelConfig()
    rule = PseudoRuleReport(float(pseudo.threshold), 0) if pseudo_rule else None
    (out / "rankers").mkdir(parents=True, exist_ok=True)
    (out / "ranges").mkdir(parents=True, exist_ok=True)
    for f in range(folds):
        rest = {i for i in ids if fold_of[i] != f}
        ranker, _ = fit_rankers({t: g.of_shapes(rest) for t, g in groups.items()},
                                data if isinstance(data, (str, Path)) else out,
                                "the other folds' predictions", k=3, seed=seed, fold=f)
        ranker.semantic = SemanticPrior.from_graphs([g for g in graphs if g.shape_id in rest])
        path = ranker.save(out / "rankers" / f"ranker_{f}.json")
        prior = fit_range_prior(g for g in graphs if g.shape_id in rest)
        prior_path = out / "ranges" / f"ranges_{f}.json"
        prior.save(prior_path)
        cfg = RefineConfig(selector="ranker", ranker=str(path))
        pr = {t: Predictor(runs[(t, f)], None, cfg, ranges=prior) for t in refined}
        for g in graphs:
            if fold_of[g.shape_id] != f:
                continue
            meshes = shape_meshes(g)  # read once: both selectors' sweeps and the rule's
            for t in refined:
                refined[t][g.shape_id] = pr[t].refine_prediction(gnn[t][g.shape_id], meshes)
            if rule is not None:
                rule.extend(grade_pseudo_rule(pr["fine"], [g], pseudo, meshes=meshes, check=pr["coarse"]))
    preds = {"GNN_coarse": [gnn["coarse"][i] for i in ids], "GNN_fine": [gnn["fine"][i] for i in ids],
             "OBB_coarse": [refined["coarse"][i] for i in ids],
             "OBB_fine": [refined["fine"][i] for i in ids]}
    report = evaluate_graphs(graphs, preds)
    write_report(report, out)
    extra_out: dict[str, Any] = {}
    if rule is not None:
        extra_out["pseudo_rule"] = write_pseudo_rule(rule, out / "pseudo-label-rule")
    else:  # an earlier run's grading would sit beside a table it was not made with
        shutil.rmtree(out / "pseudo-label-rule", ignore_errors=True)
    write_json(out / "oof.json", {"folds": folds, "preset": preset, "seed": seed, "members": members,
                                  "objects": len(graphs), "extra_training_objects": len(more),
                                  **oof_summary(report), **extra_out})
    return OOFResult(report, rule)


def _extra_graphs(extra: str | Path | Sequence[PartGraph] | None, ids: set[str], out: Path) -> list[PartGraph]:
    """The labelled graphs of ``extra`` (:func:`oof_table1`), checked against the evaluated
    ``ids`` and against ``out/folds/extra.json`` (written here: the ids the fold GNNs train on
    beside the folds; a folder with trained folds and no such file trained with none).

    Raises
    ------
    KinmoDataError
        ``extra`` without a labelled graph, an extra id also evaluated, or ``out``'s fold GNNs
        trained with other extra objects.
    """
    if extra is None:
        more: list[PartGraph] = []
    else:
        more = sorted((g for g in (load_cache(extra) if isinstance(extra, (str, Path)) else extra)
                       if g.has_labels and len(g.sibling_edges)), key=lambda g: g.shape_id)
    where = extra if isinstance(extra, (str, Path)) else out
    if extra is not None and not more:
        raise KinmoDataError(where, "no labelled part graph with a joint to add to the folds' training")
    both = sorted({g.shape_id for g in more} & ids)
    if both:
        raise KinmoDataError(where, f"{len(both)} extra training objects are also evaluated ones, e.g. {both[0]!r}")
    stamp = {"extra": [g.shape_id for g in more]}
    path = out / "folds" / "extra.json"
    if not any((out / "folds").glob("**/model.pt")):
        before = stamp  # nothing trained yet
    elif path.is_file():
        before = json.loads(path.read_text())
    else:
        before = {"extra": []}
    if before != stamp:
        raise KinmoDataError(out, f"its fold GNNs trained with {len(before.get('extra', []))} extra objects, "
                                  f"not these {len(more)}; give another --out")
    write_json(path, stamp)
    return more
