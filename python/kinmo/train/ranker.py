"""``kinmo train ranker``: out-of-fold motion GNNs on a split's training objects, then the
learned candidate selector fit on their predictions (kinmo extension, issue 11).

Moved here from :mod:`kinmo.refine.fit_selector` (issue 22) so that ``refine/`` stays below
:mod:`kinmo.inference`: the fold GNNs are trained (:func:`kinmo.train.gnn.train_gnn`) and
predict through :class:`kinmo.inference.predictor.Predictor` (no selector); the groups and the fit are
:mod:`kinmo.refine.fit_selector`'s (see its docstring for the method).

Outputs (``OUT/``): ``ranker.json``, ``cv.json``, ``oof_groups.npz``, ``folds/<types>_<f>/``.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from kinmo.data.cache import load_cache
from kinmo.data.graph import PartGraph
from kinmo.errors import KinmoDataError, KinmoError
from kinmo.executor import map_unordered
from kinmo.inference.predictor import Predictor
from kinmo.io import write_json
from kinmo.parallel import resolve_workers
from kinmo.progress import CountingBar
from kinmo.refine.fit_selector import DEFAULT_FEATURES, collect_groups, fit_type_rankers, fold_ids
from kinmo.refine.groups import EdgeGroups
from kinmo.refine.ranker import Ranker
from kinmo.refine.semantic_prior import SemanticPrior
from kinmo.runs import member_folders
from kinmo.train.config import NO_AUGMENTATIONS, TrainConfig, preset as make_preset
from kinmo.train.gnn import load_run, train_gnn, train_members
from kinmo.train.split import Split

__all__ = ["fit_rankers", "fold_config", "fold_plan", "oof_predictions", "ranker_graphs", "train_fold",
           "train_folds", "train_ranker"]


def train_fold(graphs: Sequence[PartGraph], run_dir: Path, config: TrainConfig, split: Split,
               members: int = 0, progress: bool = False) -> None:
    """Train one fold GNN of :func:`fold_plan` and its ensemble members: a fold whose own
    ``model.pt`` exists only gets its missing members (:func:`kinmo.train.gnn.train_members`),
    so an interrupted run resumes. Used by :func:`train_folds` and ``kinmo train all``."""
    if not (Path(run_dir) / "model.pt").is_file():
        train_gnn(graphs, run_dir, config, split, progress=progress)
    train_members(graphs, run_dir, config, members, progress=progress)


def _fold_job(job: tuple) -> str:
    """:func:`train_fold` of one job of :func:`train_folds` (a worker); returns its run folder."""
    graphs, run_dir, cfg, split, progress, members = job
    train_fold(graphs, run_dir, cfg, split, members, progress)
    return str(run_dir)


def _fold_failed(job: tuple, exc: Exception) -> str:
    raise KinmoError(f"fold GNN {job[1]}: {exc}") from exc


def _fold_trained(run_dir: Path, members: int) -> bool:
    """Whether the fold GNN of ``run_dir`` and ``members`` ensemble members of it are trained."""
    return (run_dir / "model.pt").is_file() and len(member_folders(run_dir)) >= members


def fold_config(preset: str, types: str, *, seed: int = 0, threads: int = 1,
                epochs: int | None = None, augment: bool = True) -> TrainConfig:
    """The training configuration of a fold GNN (:func:`fold_plan`): the configuration of
    ``kinmo train all``'s own motion GNN of ``types``, so that the ranker learns how far to
    trust GNNs trained like the one it refines at inference (issue 34).

    Until issue 34 the fold GNNs trained 2/3 of the preset's epochs, with the preset's
    flattened hierarchies and dropped names for the coarse types too (``kinmo train all``'s
    coarse GNN trains without). On the test split of the shared data their out-of-fold
    flips were unsure (axis-candidate mass of the flipped line: median 0.69), while the
    motion GNN's own flips on test objects were sure (median 0.998), and the ranker fit on
    the former never overruled the latter (docs/results/table1_four_settings.md, issue 34).

    Parameters
    ----------
    preset : str
        GNN preset (:func:`kinmo.train.config.preset`).
    types : {"fine", "coarse"}
    seed, threads
    epochs : int, optional
        The fold GNN's epochs; by default the preset's (``kinmo train all --gnn-epochs N``
        gives N to every GNN).
    augment : bool
        As :attr:`kinmo.pipeline.config.PipelineConfig.augment_gnn`: the fine fold GNNs train
        with the preset's hierarchy and name augmentations (``flatten_prob``,
        ``drop_names_prob``); the coarse ones, and every one without ``augment``, train
        without.

    Returns
    -------
    TrainConfig
        On device ``"auto"``: CUDA where there is one (the paper preset's fold GNNs take
        hours on a CPU), the CPU elsewhere, as every other GNN training of kinmo.
    """
    plain = {} if augment and types == "fine" else NO_AUGMENTATIONS
    extra = {} if epochs is None else {"epochs": epochs}
    return make_preset(preset, types=types, seed=seed, threads=threads, device="auto", **extra,
                       **plain)


def ranker_graphs(data: str | Path, split: Split) -> list[PartGraph]:
    """The graphs :func:`train_ranker` fits on: the labelled graphs of ``split``'s training ids.

    Parameters
    ----------
    data : str or Path
        A ``kinmo prepare`` cache.
    split : Split

    Returns
    -------
    list of PartGraph
        In the cache's order.

    Raises
    ------
    KinmoDataError
        None of them is in ``data``.
    """
    train = set(split.train)
    graphs = [g for g in load_cache(data) if g.shape_id in train and g.has_labels]
    if not graphs:
        raise KinmoDataError(data, "no labelled graph of the split's training ids")
    return graphs


def fold_plan(ids: Sequence[str], categories: Sequence[str], out: Path, *, k: int = 3,
              preset: str = "quick", types: Sequence[str] = ("fine",), seed: int = 0,
              threads: int = 1, epochs: int | None = None,
              augment: bool = True, members: int = 0,
              extra: Mapping[str, str] | None = None) -> list[tuple[Path, TrainConfig, Split]]:
    """The fold GNNs of :func:`train_folds` still to train: run folder, configuration, split.

    Parameters
    ----------
    ids : sequence of str
        The training objects that have a labelled graph, sorted.
    categories : sequence of str
        Their categories (the folds are stratified by category, :func:`fold_ids`).
    out, k, preset, types, seed, threads, epochs, augment, members
        As :func:`train_folds`.
    extra : mapping of str to str or None
        Category of each extra training object (:func:`train_folds`' ``extra``): in every
        fold's training, never held out, never in the folds' stratification.

    Returns
    -------
    list of (Path, TrainConfig, Split)
        ``out/folds/<types>_<f>/`` without a ``model.pt`` or with fewer than ``members``
        ensemble members (:func:`kinmo.runs.member_folders`), in type-set then fold order; each
        is :func:`~kinmo.train.gnn.train_gnn` of the graphs of ``ids`` with that
        configuration and split (fold ``f`` held out). ``kinmo train all`` trains them beside
        its other models (:mod:`kinmo.pipeline.run`).
    """
    ids = list(ids)
    folds = fold_ids(ids, list(categories), k, seed)
    cats = dict(zip(ids, categories))
    extra = dict(extra or {})
    if set(extra) & set(cats):
        raise ValueError(f"extra training objects that are also fold objects: {sorted(set(extra) & set(cats))[:3]}")
    cats.update(extra)
    plan = []
    for t in types:
        for f in range(k):
            run_dir = out / "folds" / f"{t}_{f}"
            if _fold_trained(run_dir, members):
                continue
            held = [i for i, ff in zip(ids, folds) if ff == f]
            rest = [i for i, ff in zip(ids, folds) if ff != f]
            cfg = fold_config(preset, t, seed=seed, threads=threads, epochs=epochs, augment=augment)
            plan.append((run_dir, cfg, Split(sorted(rest + list(extra)), held, cats, seed, 1.0 / k)))
    return plan


def train_folds(graphs: Sequence[PartGraph], train_ids: Sequence[str], out: Path, *,
                k: int = 3, preset: str = "quick", types: Sequence[str] = ("fine",), seed: int = 0,
                threads: int = 1, epochs: int | None = None, workers: int = 1,
                executor: str = "local", progress: bool = False, augment: bool = True,
                members: int = 0, extra: Sequence[PartGraph] = ()) -> int:
    """Train the fold GNNs of :func:`oof_predictions` for every type set, ``workers`` at a
    time on the project's executor (:func:`kinmo.executor.map_unordered`: the local process
    pool or Ray); each is one item, trained single-threaded (``threads``) as a sequential
    run would train it, so the models do not depend on ``workers``.

    Parameters
    ----------
    graphs, train_ids, out, k, preset, seed, threads, epochs, augment
        As :func:`oof_predictions`.
    types : sequence of {"fine", "coarse"}
    workers : int
        Fold GNNs trained at once (1: one after the other, in this process; 0: one per CPU).
    executor : str
        ``"local"``, ``"ray"``, ``"ray:auto"`` or ``"ray:ADDRESS"``.
    progress : bool
        With one worker, each fold's epoch bar; with more, a bar counting finished folds.
    members : int
        Ensemble members of each fold GNN (:func:`kinmo.train.gnn.train_members`, trained in
        the fold's item after it), so that the out-of-fold predictions are the same ensemble's
        as the model they stand for at inference.
    extra : sequence of PartGraph
        Labelled graphs added to **every** fold's training and never predicted, e.g. objects
        of ``kinmo synth`` (``kinmo eval oof --extra``): the folds are cut over ``train_ids``
        alone. Their ids must not be among ``train_ids``.

    Returns
    -------
    int
        Fold GNNs trained (those whose ``model.pt`` existed are skipped: a rerun resumes).

    Raises
    ------
    KinmoError
        A fold's training failed (the message names its folder).
    """
    by_id = {g.shape_id: g for g in graphs}
    ids = [i for i in sorted(train_ids) if i in by_id]
    try:
        plan = fold_plan(ids, [by_id[i].category for i in ids], out, k=k, preset=preset, types=types,
                         seed=seed, threads=threads, epochs=epochs, augment=augment, members=members,
                         extra={g.shape_id: g.category for g in extra})
    except ValueError as exc:
        raise KinmoError(f"{out}: {exc}") from exc
    jobs = [([by_id[i] for i in ids] + list(extra), run_dir, cfg, split) for run_dir, cfg, split in plan]
    if not jobs:
        return 0
    workers = resolve_workers(workers, len(jobs))
    jobs = [(*j, progress and workers == 1, members) for j in jobs]
    with CountingBar(len(jobs), progress and workers > 1, "train ranker", "fold GNNs", counters={}) as bar:
        map_unordered(_fold_job, jobs, workers, lambda job, r: bar.advance(), _fold_failed, executor=executor)
    return len(jobs)


def oof_predictions(graphs: Sequence[PartGraph], train_ids: Sequence[str], out: Path, *,
                    k: int = 3, preset: str = "quick", types: str = "fine", seed: int = 0,
                    threads: int = 1, progress: bool = False, epochs: int | None = None,
                    augment: bool = True, members: int = 0,
                    extra: Sequence[PartGraph] = ()) -> dict[str, object]:
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
        The fold GNNs' epochs; by default the preset's (:func:`fold_config`).
    augment : bool
        The fine fold GNNs' hierarchy and name augmentations (:func:`fold_config`).
    members : int
        Ensemble members of each fold GNN (:func:`train_folds`).
    extra : sequence of PartGraph
        More training objects of every fold GNN (:func:`train_folds`); never predicted.

    Returns
    -------
    dict of str to kinmo.predict.ShapePrediction
        By shape id, with :attr:`~kinmo.predict.ShapePrediction.priors`.
    """
    by_id = {g.shape_id: g for g in graphs}
    ids = [i for i in sorted(train_ids) if i in by_id]
    cats = [by_id[i].category for i in ids]
    folds = fold_ids(ids, cats, k, seed)
    preds: dict[str, object] = {}
    for f in range(k):
        held = [i for i, ff in zip(ids, folds) if ff == f]
        run_dir = out / "folds" / f"{types}_{f}"
        if not _fold_trained(run_dir, members):
            train_folds(graphs, train_ids, out, k=k, preset=preset, types=(types,), seed=seed,
                        threads=threads, epochs=epochs, progress=progress, augment=augment,
                        members=members, extra=extra)
        # the fold GNN alone (no selector: the ranker is what this fits), through the one
        # prediction path every command uses
        fold = Predictor(load_run(run_dir, "cpu"))
        for p in fold.predict_many([by_id[i] for i in held]):
            preds[p.shape_id] = p
    return preds


def fit_rankers(groups: dict[str, EdgeGroups], data: str | Path, source: str, *, k: int, seed: int = 0,
                category_power: float | None = None, fold: int | None = None
                ) -> tuple[Ranker, dict[str, dict]]:
    """The default rankers of out-of-fold groups (:func:`kinmo.refine.fit_selector.fit_type_rankers`
    with :data:`~kinmo.refine.fit_selector.DEFAULT_FEATURES`), as ``kinmo train all`` and
    ``kinmo eval oof`` fit them.

    Parameters
    ----------
    groups : dict of {"fine", "coarse"} to EdgeGroups
    data : str or Path
        What the groups come from, named in the error.
    source : str
        Which predictions they are, for the error (``"the out-of-fold predictions"``).
    k, seed, category_power
        As :func:`~kinmo.refine.fit_selector.fit_type_rankers`.
    fold : int, optional
        The outer fold these rankers are for (``kinmo eval oof``), named first in the error.

    Returns
    -------
    (Ranker, dict of str to dict)
        As :func:`~kinmo.refine.fit_selector.fit_type_rankers`.

    Raises
    ------
    KinmoDataError
        No ranker can be fit, e.g. no group has a right candidate (too few objects, or GNNs
        too weak): one line naming the fix.
    """
    try:
        return fit_type_rankers(groups, features=DEFAULT_FEATURES, k=k, seed=seed,
                                category_power=category_power)
    except ValueError as e:  # e.g. no group with a right candidate: nothing to learn from
        where = "" if fold is None else f"fold {fold}: "
        raise KinmoDataError(data, f"{where}cannot fit the selector on {source} ({e}); more training "
                                   "objects or a longer --preset") from None


def train_ranker(data: str | Path, out: str | Path, split: str | Path, *, folds: int = 3,
                 preset: str = "quick", types: Sequence[str] = ("fine", "coarse"), seed: int = 0,
                 threads: int = 1, progress: bool = True, epochs: int | None = None,
                 workers: int = 1, executor: str = "local", augment: bool = True,
                 category_power: float | None = None, members: int = 0,
                 extra: Sequence[PartGraph] = ()) -> tuple[Ranker, dict]:
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
        The fold GNNs' epochs; by default the preset's (:func:`fold_config`; ``kinmo train
        all --gnn-epochs N`` gives N to every GNN).
    augment : bool
        The fine fold GNNs' hierarchy and name augmentations (:func:`fold_config`), as
        ``kinmo train all``'s fine GNN.
    category_power : float, optional
        How the ranker's fit weighs categories; chosen by cross-validation when not given
        (:func:`kinmo.refine.fit_selector.fit_selector`).
    types : sequence of {"fine", "coarse"}
        Fold GNNs of these type sets; the fine ranker is fit on the fine groups, the coarse
        one on the groups of both, kept in one file
        (:func:`kinmo.refine.fit_selector.fit_type_rankers`).
    progress : bool
    workers, executor
        Fold GNNs trained at once, and where (:func:`train_folds`).
    members : int
        Ensemble members of each fold GNN (:func:`train_folds`): the ranker learns how far to
        trust the same ensemble as the motion GNN it refines (``kinmo train all
        --gnn-members``).
    extra : sequence of PartGraph
        More labelled objects in every fold GNN's training (:func:`train_folds`), e.g. the
        generated objects of ``kinmo train all --train-synth``; the ranker is fit on the
        split's objects only (their out-of-fold candidate groups and semantic prior).

    Returns
    -------
    (Ranker, dict)
        The ranker (also written) and the cross-validated numbers per type set
        (:func:`~kinmo.refine.fit_selector.fit_selector`'s, in ``cv.json``).

    Raises
    ------
    KinmoDataError
        No labelled graph of the split's training ids in ``data``, no moving edge, or no
        ranker can be fit (no candidate group with a right candidate: too few objects, or
        fold GNNs too weak).
    """
    out = Path(out)
    sp = Split.load(split)
    train = set(sp.train)
    graphs = ranker_graphs(data, sp)
    semantic = SemanticPrior.from_graphs(graphs)
    train_folds(graphs, sorted(train), out, k=folds, preset=preset, types=types, seed=seed,
                threads=threads, epochs=epochs, workers=workers, executor=executor, progress=progress,
                augment=augment, members=members, extra=extra)
    parts = {}
    for t in types:
        preds = oof_predictions(graphs, sorted(train), out, k=folds, preset=preset, types=t,
                                seed=seed, threads=threads, progress=progress, epochs=epochs,
                                augment=augment, members=members, extra=extra)
        parts[t] = collect_groups(list(preds.values()), seed=seed, semantic=semantic)
    groups = EdgeGroups.concat(list(parts.values()))
    if not groups.y:
        raise KinmoDataError(data, "no moving edge predicted moving in the out-of-fold predictions")
    ranker, by_type = fit_rankers(parts, data, "the out-of-fold predictions", k=folds, seed=seed,
                                  category_power=category_power)
    ranker.semantic = semantic
    ranker.meta["trained_on"] = {"data": str(data), "split": str(split), "types": list(types),
                                 "preset": preset, "folds": folds, "augment": augment, "members": members,
                                 "epochs": fold_config(preset, "fine", epochs=epochs).epochs}
    groups.save(out / "oof_groups.npz")
    ranker.save(out / "ranker.json")
    stats = {t: {k: v for k, v in st.items() if not isinstance(v, np.ndarray)} for t, st in by_type.items()}
    write_json(out / "cv.json", stats)
    return ranker, stats
