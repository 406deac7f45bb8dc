"""The stages of ``kinmo train all`` in order (:func:`run_pipeline`; the layout of the run
folder is in :mod:`kinmo.pipeline`).
"""

from __future__ import annotations

import dataclasses
import functools
import json
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from kinmo.ancsh.config import preset as ancsh_preset
from kinmo.ancsh.evaluate import evaluate_category
from kinmo.ancsh.generated import can_generate
from kinmo.ancsh.scans import SCAN_RULES
from kinmo.ancsh.structure import structure_slug
from kinmo.ancsh.train import train_ancsh
from kinmo.data.cache import load_cache
from kinmo.data.graph import CACHE_VERSION, PartGraph
from kinmo.data.readers import find_shapes
from kinmo.errors import KinmoDataError, KinmoError
from kinmo.evaluate.pre_segmented import run_evaluation
from kinmo.evaluate.pseudo_rule import grade_pseudo_rule, summary_line, write_pseudo_rule
from kinmo.executor import map_unordered
from kinmo.inference.bundle import write_bundle
from kinmo.inference.predictor import Predictor
from kinmo.io import write_json
from kinmo.parallel import resolve_workers
from kinmo.pipeline.config import PipelineConfig
from kinmo.pipeline.data import _graphs, _link_folder, _synth_categories
from kinmo.pipeline.plan import ANCSH_PLAN_FILE, ancsh_plan, structure_split
from kinmo.pipeline.stages import PipelineResult, StageTiming, _Clock, _stage, mark_done, stage_done
from kinmo.prepare import PrepareConfig, prepare_dataset
from kinmo.progress import CountingBar, console as new_console, literal
from kinmo.pseudo_label import PseudoLabelConfig, pseudo_label_dataset
from kinmo.ranges import fit_range_prior
from kinmo.ranges.prior import PRIOR_VERSION
from kinmo.refine.fit_selector import COARSE_L2, DEFAULT_L2
from kinmo.refine.refine import RefineConfig
from kinmo.refine.train import preset_config as axis_preset, train_axis_model
from kinmo.report import write_report
from kinmo.runs import ANCSH_SEEDS_DIR, RESULT_FILE, SYNTH_EXTRA_FILE, TABLE2_SEED_STAGE
from kinmo.stages import file_fingerprint
from kinmo.synth import SYNTH_VERSION, generate_dataset
from kinmo.train.config import NO_AUGMENTATIONS, preset as gnn_preset
from kinmo.train.gnn import train_gnn, train_members
from kinmo.train.ranker import fold_config, fold_plan, ranker_graphs, train_fold, train_ranker
from kinmo.train.split import Split

__all__ = ["RANKER_FOLDS", "RANKER_TYPES", "SPLIT_TEST_FRACTION", "run_pipeline"]

#: Share of the labelled objects held out for testing (:func:`structure_split`).
SPLIT_TEST_FRACTION = 0.25
#: Out-of-fold GNNs of the ranker stage: folds and type sets (``kinmo train ranker``'s defaults).
RANKER_FOLDS = 3
RANKER_TYPES = ("fine", "coarse")
#: The parallel pool's opening line names this many of its trainings, then counts the rest (a
#: run with ``--ancsh-seeds 3`` has 189, which made one line of some 12,000 characters in a log).
_POOL_NAMES = 6


def run_pipeline(cfg: PipelineConfig, console: Any = None, progress: bool = True,
                 timings: dict[str, StageTiming] | None = None) -> PipelineResult:
    """Run every stage of the pipeline (module docstring), resuming finished stages.

    Parameters
    ----------
    cfg : PipelineConfig
    console : rich.console.Console, optional
        Where stage headers and the time of every stage go.
    progress : bool
        Show each stage's progress bar.
    timings : dict of str to StageTiming, optional
        Times of stages run before (``kinmo demo``'s data generation), put first in the
        result's ``timings``.

    Returns
    -------
    PipelineResult

    Raises
    ------
    KinmoDataError
        A dataset folder is missing.
    KinmoError
        ``synth_extra`` with labelled data of which no category can be generated.
    """

    console = console or new_console(stderr=True)
    log = console.print
    if not cfg.labeled.is_dir():
        raise KinmoDataError(cfg.labeled, "labelled dataset folder does not exist")
    if cfg.unlabeled is not None and not cfg.unlabeled.is_dir():
        raise KinmoDataError(cfg.unlabeled, "unlabelled dataset folder does not exist")
    out = cfg.out
    out.mkdir(parents=True, exist_ok=True)
    write_json(out / "pipeline.json", json.loads(cfg.model_dump_json()))
    res = PipelineResult(out=out, timings=dict(timings or {}))
    ctx = _Context(cfg, res, _Clock(res.timings, log), console, progress)

    # 1. the train/test split, made once before any training and used by every model
    split_file, split_digest = ctx.split()

    # 2. prepare

    cache_l, cache_u = out / "cache" / "labeled", out / "cache" / "unlabeled"
    prep = PrepareConfig(seed=cfg.seed)
    ctx.prepare(cfg.labeled, cache_l, prep, "prepare labelled")
    if cfg.unlabeled is not None:
        ctx.prepare(cfg.unlabeled, cache_u, prep, "prepare unlabelled")
    res.stages["prepare"] = [str(cache_l)] + ([str(cache_u)] if cfg.unlabeled else [])
    synth_cats = _synth_categories(cache_l) if cfg.synth_extra > 0 else []  # fails before training
    # 2a. generated objects for the motion GNNs and the ranker's fold GNNs (issue 34)
    extra = ctx.generated(out, cfg.train_synth, cache_l, prep, "", "the motion GNNs train") if cfg.train_synth else None

    # 3.-8. models and tables on the labelled (and unlabelled) data
    baseline = _Variant(
        out=out, graphs=cache_l, split=split_file, labeled=cfg.labeled, unlabeled=cfg.unlabeled,
        unlabeled_cache=cache_u if cfg.unlabeled is not None else None, key={"split": split_digest}, prefix="",
        extra=extra)
    ctx.models_and_tables(baseline, cache_l)

    # 8b. the release bundle: the same recipe on every labelled object and the kept
    # pseudo-labels (issue 22; the baseline's test numbers measure the recipe)
    if cfg.release:
        ctx.release(cache_l, prep)

    # 9. the same with generated shapes added (the paper's DSG-Net study, Sec. 4.3)
    if cfg.synth_extra > 0:
        ctx.synth_extra(baseline, cache_l, prep, synth_cats)

    # 10. report

    write_json(out / RESULT_FILE, json.loads(res.model_dump_json()))  # the report shows the times
    rep = ctx.clock.run("report", lambda: write_report(out, out / "report"))
    res.report = rep.html
    write_json(out / RESULT_FILE, json.loads(res.model_dump_json()))
    tot = res.total()
    log(f"[bold]total[/]: {tot.wall_s:.1f} s wall, {tot.cpu_s:.1f} s CPU")
    return res


@dataclasses.dataclass
class _Variant:
    """What one set of models is trained and evaluated on.

    Attributes
    ----------
    out : Path
        Its folder (``gnn_fine/``, ``axis/``, ``eval/``... below it).
    graphs : Path or list
        Labelled part graphs for the motion GNN and the axis network (a cache or graphs).
    split : Path
        Split file (the ``split`` stage's ``out/split.json``, or the baseline's with the
        generated objects added to training).
    labeled : Path
        PartNet-Mobility folder ANCSH renders its labelled objects from.
    unlabeled, unlabeled_cache : Path or None
        PartNet folder to pseudo-label and its cache.
    key : dict
        Added to every stage's key.
    prefix : str
        Prefix of the stage names.
    reuse : dict of str to Path
        Finished runs of the baseline to use instead of training (``gnn_fine``,
        ``gnn_coarse``, ``axis``, ``ranker``, ``ancsh/<Category>/supervised``).
    extra : _Generated or None
        Generated objects added to the motion GNNs' and the ranker's fold GNNs' training
        (``train_synth``), with their own split ``out/split_gnn.json``.
    """

    out: Path
    graphs: Any
    split: Path
    labeled: Path
    unlabeled: Path | None
    unlabeled_cache: Path | None
    key: dict[str, Any]
    prefix: str
    reuse: dict[str, Path] = dataclasses.field(default_factory=dict)
    extra: _Generated | None = None


@dataclasses.dataclass(frozen=True)
class _Generated:
    """Generated objects of :meth:`_Context.generated`: their cache, what was generated (a
    stage key) and their graphs (loaded once, passed down)."""

    cache: Path
    info: dict[str, Any]
    graphs: list[PartGraph]


@dataclasses.dataclass
class _Context:
    """The state one :func:`run_pipeline` call shares between its stages."""

    cfg: PipelineConfig
    res: PipelineResult
    clock: _Clock
    console: Any
    progress: bool
    #: ANCSH models per category (:func:`ancsh_plan`), set by the main run's ANCSH stage.
    plan: dict[str, list[Any]] = dataclasses.field(default_factory=dict)

    #: Stages trained in the pool of :meth:`train_in_parallel` (recorded there, skipped here).
    pooled: set[str] = dataclasses.field(default_factory=set)

    def stage(self, folder: Path, key: dict[str, Any], run: Callable[[], Any], name: str,
              after: Sequence[Path] = ()) -> bool:
        """Run a stage unless it is up to date (:func:`~kinmo.pipeline.stages.stage_done`:
        same key, and newer than the stages in ``after`` whose outputs it reads)."""
        if name in self.pooled:
            return False
        return _stage(folder, key, run, self.console.print, name, self.clock, after=after)

    def prepare(self, src: Path, cache: Path, prep: Any, name: str) -> None:
        # CACHE_VERSION in the key: graphs computed another way (issue 36's OBB fit) are redone
        # in a run folder made before, as by `kinmo prepare`
        self.stage(cache, {"src": str(src), **dataclasses.asdict(prep), "cache_version": CACHE_VERSION},
                   lambda: prepare_dataset(
            src, cache, prep, workers=self.cfg.workers, progress=self.progress), name)

    def split(self) -> tuple[Path, str]:
        """The ``split`` stage: :func:`structure_split` of the labelled data into
        ``out/split.json`` (kept while the data's folders and the seed are the same).

        Returns
        -------
        (Path, str)
            The split file and a digest of its content (part of every later stage's key).
        """
        import hashlib

        cfg, out = self.cfg, self.cfg.out
        split_file = out / "split.json"
        names = sorted(p.name for p in find_shapes(cfg.labeled))
        key = {"labeled": str(cfg.labeled), "seed": cfg.seed, "test_fraction": SPLIT_TEST_FRACTION,
               "shapes": hashlib.sha256("\n".join(names).encode()).hexdigest()[:16]}
        if not split_file.is_file():  # removed by hand: made again
            (out / ".split.done").unlink(missing_ok=True)
        _stage(out, key, lambda: structure_split(cfg.labeled, SPLIT_TEST_FRACTION, seed=cfg.seed).save(split_file),
               self.console.print, "split", self.clock, marker_name=".split.done")
        self.res.split = split_file
        self.res.stages["split"] = [str(split_file)]
        return split_file, hashlib.sha256(split_file.read_bytes()).hexdigest()[:16]

    def pseudo_rule(self, v: _Variant, base: dict[str, Any], gnn_run: Path, axis_dir: Path,
                    pcfg: PseudoLabelConfig, eval_cache: Path, split_file: Path, after: list[Path],
                    check_run: Path | None = None) -> Path:
        """The ``eval pseudo-label rule`` stage (issue 34): :func:`kinmo.evaluate.pseudo_rule.grade_pseudo_rule`
        of the pseudo-labelling models (``check_run``: the second GNN that must agree) on the
        split's labelled test objects, into ``out/eval/pseudo-label-rule/`` (``summary.json``,
        ``summary.md``), and one line.

        Returns
        -------
        Path
            The output folder.
        """
        folder = v.out / "eval" / "pseudo-label-rule"

        def run() -> None:
            test = set(Split.load(split_file).test)
            graphs = [g for g in load_cache(eval_cache) if g.shape_id in test]
            predictor = Predictor.from_parts(gnn_run, axis_dir, pcfg.refine, device=pcfg.device)
            check = None if check_run is None else predictor.with_gnn(check_run, pcfg.device)
            write_pseudo_rule(grade_pseudo_rule(predictor, graphs, pcfg, check=check), folder)

        self.stage(folder, {**base, "pseudo": pcfg.model_dump(), "data": str(eval_cache),
                            "split": file_fingerprint(split_file),
                            "check": None if check_run is None else str(check_run)}, run,
                   f"{v.prefix}eval pseudo-label rule", after=after)
        f = folder / "summary.json"
        if f.is_file():
            a = json.loads(f.read_text())["all"]
            a = {"link_precision": None, "link_type_acc": None, "link_axis_mean_deg": None, **a}  # older runs
            self.console.print(f"{v.prefix}pseudo-label rule at {pcfg.threshold:g} on {int(a['objects'])} "
                               f"labelled test objects: {summary_line(a)}")
        self.res.stages[f"{v.prefix}pseudo_rule"] = [str(folder)]
        return folder

    def range_prior(self, v: _Variant, base: dict[str, Any], graphs: Callable[[], Any],
                    split_file: Path) -> Path:
        """The ``fit range prior`` stage (issue 35): :func:`kinmo.ranges.fit_range_prior` of
        the split's training graphs into ``out/ranges/ranges.json``.

        Returns
        -------
        Path
            The prior file.
        """
        folder = v.out / "ranges"
        out = folder / "ranges.json"

        def fit() -> None:
            data = graphs()
            train = set(Split.load(split_file).train)
            every = load_cache(data) if isinstance(data, (str, Path)) else data
            folder.mkdir(parents=True, exist_ok=True)
            fit_range_prior(g for g in every if g.shape_id in train).save(out)

        self.stage(folder, {**base, "ranges": PRIOR_VERSION, "split": file_fingerprint(split_file)}, fit,
                   f"{v.prefix}fit range prior")
        self.res.stages[f"{v.prefix}ranges"] = [str(out)]
        return out

    def bundle(self, v: _Variant, base: dict[str, Any], gnn: Path, axis: Path | None,
               ranker: Path | None, split_file: Path, ranges: Path | None = None,
               check: Path | None = None) -> Path:
        """The ``model bundle`` stage: ``out/model/`` (:func:`kinmo.inference.bundle.write_bundle`)
        with ``trained_on`` the split's training ids and ``check`` the coarse GNN that
        pseudo-labelling requires to agree; rewritten when a part changed.

        Returns
        -------
        Path
            The bundle folder.
        """

        folder = v.out / "model"
        parts = [gnn / "model.pt", *([axis / "model.pt"] if axis is not None else []),
                 *([ranker] if ranker is not None else []), *([ranges] if ranges is not None else []),
                 *([check / "model.pt"] if check is not None else [])]
        key = {**base, "bundle": {str(p): file_fingerprint(p) for p in parts if p.is_file()}}
        self.stage(folder, key, lambda: write_bundle(
            folder, gnn, axis, ranker, Split.load(split_file).train, ranges, check), f"{v.prefix}model bundle")
        self.res.stages[f"{v.prefix}model"] = [str(folder)]
        return folder

    def train_models(self, v: _Variant, base: dict[str, Any], trainings: list[_Training],
                     graphs: Callable[[], Any]) -> None:
        """The stages of ``trainings``: those not up to date trained ``cfg.workers`` at a time
        (:meth:`train_in_parallel`), then each stage in turn (trained here when the pool did
        not run, e.g. with one worker)."""
        self.train_in_parallel(v, base, trainings, graphs)
        for t in trainings:
            self.stage(t.folder, t.key, lambda t=t: dataclasses.replace(t, graphs=graphs()).run(
                self.progress, self.console, False), t.name)

    def train_in_parallel(self, v: _Variant, base: dict[str, Any], trainings: list[_Training],
                          graphs: Callable[[], Any]) -> None:
        """Train ``trainings`` (stages not up to date) and the ranker stage's fold GNNs
        ``cfg.workers`` at a time (issue 24; :meth:`run_in_parallel`). The stages then find
        their models trained; the ranker stage finds its folds trained and only fits."""
        cfg = self.cfg
        pending = list(trainings)
        stage = self._ranker_stage(v, base)
        if stage is not None and not stage_done(*stage):
            folder = stage[0]
            _ranker_fold_stamp(cfg, folder, v.extra)
            rg = ranker_graphs(v.graphs, Split.load(v.split))
            ids = sorted({g.shape_id for g in rg})
            cats = {g.shape_id: g.category for g in rg}
            extra = {g.shape_id: g.category for g in v.extra.graphs} if v.extra is not None else None
            plan = fold_plan(ids, [cats[i] for i in ids], folder, k=RANKER_FOLDS, preset=cfg.preset,
                             types=RANKER_TYPES, seed=cfg.seed, threads=1, epochs=cfg.gnn_epochs,
                             augment=cfg.augment_gnn, members=cfg.gnn_members, extra=extra)
            pending += [_Training(f"{v.prefix}train ranker: fold GNN {run_dir.name}", "gnn", run_dir, fcfg, split,
                                  None, None, cfg.gnn_members) for run_dir, fcfg, split in plan]
        # longest first (the axis network, then the augmented GNNs), so that the last one to
        # finish is a short one
        pending.sort(key=lambda t: (t.kind != "axis", -getattr(t.config, "flatten_prob", 0.0)))
        chains = [[t] for t in pending if t.key is None or not stage_done(t.folder, t.key)]
        if len(chains) > 1 and resolve_workers(cfg.workers, len(chains)) > 1:
            data = graphs()  # loaded once here, sent with each training
            chains = [[dataclasses.replace(t, graphs=data)] for [t] in chains]
        self.run_in_parallel(chains, lambda n, w: f"{v.prefix}train {n} models, {w} at a time",
                             f"{v.prefix}train", "models")

    def run_in_parallel(self, chains: list[list[Any]], name: Callable[[int, int], str], title: str,
                        unit: str) -> None:
        """Run chains of trainings (:class:`_Training`, :class:`_AncshStage`) ``cfg.workers``
        at a time on the project's executor (:func:`kinmo.executor.map_unordered`, local
        process pool); the trainings of a chain run in order, in one worker.

        Each training runs single-threaded in its worker exactly as its stage would run it in
        this process (same function, configuration, split and seed), so the models do not
        depend on ``-j``. A stage's marker is written as it finishes (:func:`_run_chain`); its
        wall and CPU seconds, measured in the worker, are recorded as a
        :attr:`~kinmo.pipeline.stages.StageTiming.parallel` row, and the pool's own row (named
        by ``name(trainings, workers)``) holds the wall and CPU time of all of them. With one
        worker, or fewer than two chains, nothing happens here: each stage trains in turn.

        Raises
        ------
        KinmoError
            A training failed (the message names it).
        """
        workers = resolve_workers(self.cfg.workers, len(chains))
        if len(chains) < 2 or workers < 2:
            return
        pool = name(sum(map(len, chains)), workers)
        names = [literal(t.name) for c in chains for t in c]
        more = len(names) - _POOL_NAMES
        self.console.print(f"[bold cyan]{pool}[/]: " + ", ".join(names[:_POOL_NAMES])
                           + (f" and {more} more" if more > 0 else ""))

        def done(chain: list[Any], timings: list[tuple[str, float, float]]) -> None:
            for stage_name, wall, cpu in timings:
                self.pooled.add(stage_name)
                self.clock.record(stage_name, StageTiming(wall_s=round(wall, 2), cpu_s=round(cpu, 2), parallel=True))
            bar.advance()

        with CountingBar(len(chains), self.progress, title, unit, counters={}) as bar:
            self.clock.run(pool, lambda: map_unordered(_run_chain, chains, workers, done, _chain_failed))

    def _ranker_stage(self, v: _Variant, base: dict[str, Any]) -> tuple[Path, dict[str, Any]] | None:
        """Folder and key of ``v``'s ranker stage; None when it has none (paper selector,
        no refinement, or the baseline's ranker reused)."""
        cfg = self.cfg
        if not cfg.refine or cfg.selector != "learned" or "ranker" in v.reuse:
            return None
        epochs = fold_config(cfg.preset, "fine", epochs=cfg.gnn_epochs).epochs
        # the fold GNNs' whole configuration: a preset change (e.g. its augmentations) refits
        # the ranker on fold GNNs trained like the new motion GNN, never a stale one
        fit = f"l2-{DEFAULT_L2}-{COARSE_L2}-cv-category"  # a new fit refits the ranker
        return v.out / "ranker", {**base, "ranker": {"folds": RANKER_FOLDS, "types": list(RANKER_TYPES),
                                                     "epochs": epochs, "augment": cfg.augment_gnn,
                                                     "fit": fit,
                                                     "fold_gnns": _fold_stamp(cfg, v.extra), **_members_key(cfg)}}

    def ranker(self, v: _Variant, base: dict[str, Any]) -> Path | None:
        """The ``ranker`` stage: the learned candidate selector (kinmo extension, issue 11),
        fit on out-of-fold GNN predictions of ``v``'s training objects
        (:func:`kinmo.train.ranker.train_ranker`) into ``out/ranker/``.

        Returns
        -------
        Path or None
            Its ``ranker.json``; None with ``selector="paper"`` or without refinement.
        """
        cfg = self.cfg
        if not cfg.refine or cfg.selector != "learned":
            return None
        folder = v.reuse.get("ranker", v.out / "ranker")
        stage = self._ranker_stage(v, base)
        if stage is not None:
            self.stage(*stage, lambda: _train_ranker(cfg, v, folder, self.progress), f"{v.prefix}train ranker")
        self.res.stages[f"{v.prefix}ranker"] = [str(folder)]
        return folder / "ranker.json"

    def models_and_tables(self, v: _Variant, eval_cache: Path) -> None:
        """Motion GNNs, axis network, ranker, Table 1, pseudo-labels, ANCSH and Table 2 of ``v``."""
        cfg, res, progress, console = self.cfg, self.res, self.progress, self.console
        log = console.print
        out = v.out
        base = {"seed": cfg.seed, "preset": cfg.preset, **v.key}
        # the stages that learn from the part graphs are redone when their computation changes
        # (CACHE_VERSION: e.g. the OBB fit of issue 36), not only the caches
        gbase = {**base, "graphs": CACHE_VERSION}
        # the training graphs, loaded once and only if a stage runs (several caches: concatenated)
        graphs = functools.cache(functools.partial(_graphs, v.graphs))
        split_file = v.split
        # train_synth: the motion GNNs' split adds the generated objects to training; the
        # other stages keep the real split (and filter the graphs by it)
        gnn_split, gnn_key = split_file, {}
        if v.extra is not None:
            gnn_split = out / "split_gnn.json"
            gnn_key = _add_generated(split_file, v.extra, gnn_split, "gnn_split")
            graphs = functools.cache(functools.partial(_with_extra, graphs, v.extra.graphs))

        # 3. motion GNN, fine and coarse types (Sec. 3.1-3.2), and 4. the axis-selection
        # network (Sec. 3.3): independent trainings, which with -j N train N at a time beside
        # the ranker's fold GNNs (train_in_parallel); each stage then finds its model trained

        gnn_runs: dict[str, Path] = {}
        trainings: list[_Training] = []
        for types in ("fine", "coarse"):
            if f"gnn_{types}" in v.reuse:
                gnn_runs[types] = v.reuse[f"gnn_{types}"]
                continue
            run_dir = out / f"gnn_{types}"
            gcfg = gnn_preset(cfg.preset, types=types, seed=cfg.seed, epochs=cfg.gnn_epochs,
                              **({} if cfg.augment_gnn and types == "fine" else NO_AUGMENTATIONS))
            trainings.append(_Training(f"{v.prefix}train gnn ({types})", "gnn", run_dir, gcfg, gnn_split,
                                       {**gbase, "gnn": gcfg.model_dump(), **_members_key(cfg), **gnn_key},
                                       v.graphs, cfg.gnn_members))
            gnn_runs[types] = run_dir
        axis_dir = v.reuse.get("axis", out / "axis")
        if "axis" not in v.reuse and cfg.refine:
            acfg = axis_preset(cfg.preset, **({"epochs": cfg.axis_epochs} if cfg.axis_epochs else {}),
                               seed=cfg.seed)
            trainings.append(_Training(f"{v.prefix}train axis", "axis", axis_dir, acfg, split_file,
                                       {**gbase, "axis": acfg.model_dump()}, v.graphs))
        self.train_models(v, gbase, trainings, graphs)
        res.stages[f"{v.prefix}gnn"] = [str(p) for p in gnn_runs.values()]
        if cfg.refine:
            res.stages[f"{v.prefix}axis"] = [str(axis_dir)]
            res.selector = cfg.selector

        # 5. the learned candidate selector (kinmo extension)
        ranker = self.ranker(v, gbase)

        # 5a. the range-of-motion prior (issue 35): learned ranges, clipped by a sweep at prediction
        ranges = self.range_prior(v, gbase, graphs, split_file)
        refine = (RefineConfig(selector="ranker", ranker=str(ranker), ranges=str(ranges)) if ranker is not None
                  else RefineConfig(ranges=str(ranges)))

        # 5b. the model bundle (issue 22): GNN (fine), axis network, ranker, range prior and the
        # training ids in one folder that `--model` accepts whole (learned selector by default)
        self.bundle(v, base, gnn_runs["fine"], axis_dir if cfg.refine else None, ranker, gnn_split, ranges,
                    gnn_runs["coarse"])

        # 6. Table 1 on the held-out pre-segmented shapes (always the real labelled ones),
        # with renders of the predictions for the report's gallery; with the learned
        # selector, the paper selector's OBB rows too (eval/pre-segmented-paper)

        render = cfg.render and not v.prefix  # the gallery shows the main run
        # the stages whose outputs Table 1 and the pseudo-labels read (trained again: stale)
        refiners = [*([axis_dir] if cfg.refine else []), *([ranker.parent] if ranker is not None else []),
                    ranges.parent]
        upstream = [*gnn_runs.values(), *refiners]
        if not ("gnn_fine" in v.reuse and "axis" in v.reuse):
            evals = [(out / "eval" / "pre-segmented", refine, render, "")]
            if ranker is not None:
                evals.append((out / "eval" / "pre-segmented-paper", RefineConfig(), False, ", paper selector"))
            for t1, rcfg, rend, what in evals:
                self.stage(t1, {**base, "models": [str(p) for p in gnn_runs.values()],
                                "axis": str(axis_dir) if cfg.refine else None,
                                "data": str(eval_cache), "render": rend,
                                **({"refine": rcfg.model_dump(mode="json")} if ranker is not None else {})},
                           lambda t1=t1, rcfg=rcfg, rend=rend: run_evaluation(
                               [gnn_runs["fine"], gnn_runs["coarse"]], eval_cache, out=t1, split=split_file,
                               render=rend, progress=progress, axis_model=axis_dir if cfg.refine else None,
                               refine_config=rcfg),
                           f"{v.prefix}eval pre-segmented{what} (Table 1)", after=upstream)
                res.stages.setdefault(f"{v.prefix}table1", []).append(str(t1))

        # 7. pseudo-labels on the unlabelled shapes (Sec. 3.3)
        pseudo = out / "pseudo"
        if v.unlabeled is not None:

            # a shape is kept when the coarse GNN agrees on each joint too (issue 34: the
            # fine GNN's confident 90-degree flips and false movers)
            pcfg = PseudoLabelConfig(threshold=cfg.threshold, refine=refine)
            self.stage(pseudo, {**base, "pseudo": pcfg.model_dump(), "check": str(gnn_runs["coarse"])},
                       lambda: pseudo_label_dataset(
                           v.unlabeled, gnn_runs["fine"], axis_dir, pseudo, pcfg, workers=cfg.workers,
                           cache=v.unlabeled_cache, progress=progress, check_run=gnn_runs["coarse"]),
                       f"{v.prefix}pseudo-label", after=[gnn_runs["fine"], gnn_runs["coarse"], *refiners])
            res.stages[f"{v.prefix}pseudo"] = [str(pseudo)]
            # 7a. the same rule graded on the labelled test objects (issue 34: a looser rule
            # is invisible on the unlabelled shapes); models reused from the baseline were
            # graded there
            if not ("gnn_fine" in v.reuse and "axis" in v.reuse):
                self.pseudo_rule(v, base, gnn_runs["fine"], axis_dir, pcfg, eval_cache, split_file,
                                 after=[gnn_runs["fine"], gnn_runs["coarse"], *refiners],
                                 check_run=gnn_runs["coarse"])

        # 8. ANCSH on partial scans, three settings, per category (Sec. 3.4, Table 2)
        if cfg.skip_ancsh:
            return

        if not v.prefix:
            plan, res.skipped_categories = ancsh_plan(cfg.labeled, split_file, cfg.categories)
            res.categories = sorted(plan)
            res.structures = {c: [g.structure.signature() for g in gs] for c, gs in plan.items()}
            for cat, why in res.skipped_categories.items():
                log(f"[dim]ANCSH: {cat} left out: {why}[/]")
            write_json(out / "ancsh" / ANCSH_PLAN_FILE, {
                "trained": {c: [{"structure": g.structure.signature(), "train": list(g.train), "test": list(g.test)}
                                for g in gs] for c, gs in plan.items()},
                "skipped": res.skipped_categories})
            self.plan = plan
        settings = [s for s in cfg.settings if s == "supervised" or v.unlabeled is not None]
        overrides = {
            "epochs": cfg.ancsh_epochs, "semi_epochs": cfg.semi_epochs,
            "steps_per_epoch": cfg.ancsh_steps_per_epoch, "frames_per_object": cfg.frames_per_object,
            "unlabeled_frames_per_object": cfg.frames_per_object,
            "test_frames_per_object": cfg.frames_per_object,
            "labeled_fraction": cfg.labeled_fraction, "seed": cfg.seed,
            "synth_objects": cfg.ancsh_synth, "synth_as": cfg.ancsh_synth_as,
        }
        ac = ancsh_preset(cfg.preset, **{k: val for k, val in overrides.items() if val is not None})
        # --ancsh-synth: only the (category, structure) pairs kinmo synth makes get generated
        # objects; the others keep the configuration (and stage keys) of a run without
        no_synth: dict[tuple[str, str], str] = {}
        if ac.synth_objects:
            for cat in res.categories:
                for g in self.plan[cat]:
                    why = can_generate(cat, g.structure)
                    if why is not None:
                        no_synth[(cat, g.structure.signature())] = why
                        log(f"[dim]ANCSH: {literal(f'{cat} {g.structure.signature()}: no generated objects ({why})')}[/]")
            if not v.prefix:
                res.ancsh_synth = {"objects": ac.synth_objects, "as": ac.synth_as,
                                   "without": {f"{c} {sig}": why for (c, sig), why in no_synth.items()}}

        # one chain of trainings per category and seed: per structure supervised, then semi
        # (from the supervised weights) and semi-weakly; categories share no object and render
        # into scans/<Category>/ (one render cache for every variant: the same objects), so
        # with -j N they train N at a time (run_in_parallel). With --ancsh-seeds K (main
        # variant only), seeds seed+1 .. seed+K-1 train again into ancsh-seeds/seed-<s>/
        # (their own training renders) and are evaluated on the same test scans
        seeds = [cfg.seed + k for k in range(cfg.ancsh_seeds if not v.prefix else 1)]
        roots = {s: out if s == cfg.seed else out / ANCSH_SEEDS_DIR / f"seed-{s}" for s in seeds}
        chains: dict[tuple[int, str], list[_AncshStage]] = {}
        runs_of: dict[tuple[int, str], list[Path]] = {}
        for seed, root in roots.items():
            acs = ac if seed == cfg.seed else ac.model_copy(update={"seed": seed})
            shared = _AncshShared(acs, v.labeled, v.unlabeled, pseudo if v.unlabeled is not None else None,
                                  split_file, cfg.out / "scans" if seed == cfg.seed else root / "scans")
            tag = "" if seed == cfg.seed else f", seed {seed}"
            for cat in res.categories:
                groups = self.plan[cat]
                runs: list[Path] = []
                chain = chains.setdefault((seed, cat), [])
                for g in groups:
                    # one structure: ancsh/<Category>/<setting>; several: ancsh/<Category>/<structure>/<setting>
                    sub = structure_slug(g.structure) if len(groups) > 1 else ""
                    label = f"{cat} {g.structure.signature()}" if sub else cat
                    st = {"parents": list(g.structure.parents), "joint_types": list(g.structure.joint_types)}
                    acg = (acs.model_copy(update={"synth_objects": 0})
                           if (cat, g.structure.signature()) in no_synth else acs)
                    shared_g = shared if acg is acs else dataclasses.replace(shared, config=acg)
                    group_runs: list[Path] = []
                    for setting in settings:
                        reused = v.reuse.get(f"ancsh/{cat}/{sub + '/' if sub else ''}{setting}")
                        if reused is not None and seed == cfg.seed:
                            group_runs.append(reused)
                            continue
                        run_dir = root / "ancsh" / cat / sub / setting
                        # semi starts from the supervised run's weights: its supervised stage would
                        # reproduce them; semi-weakly takes them when no pseudo-labelled scan fits
                        # (it would train the same model again)
                        init = (group_runs[0] if setting != "supervised" and group_runs and settings[0] == "supervised"
                                else None)
                        after = ([init] if init is not None else []) + ([pseudo] if setting == "semi-weakly" else [])
                        chain.append(_AncshStage(
                            f"{v.prefix}train ancsh {label} ({setting}{tag})", run_dir,
                            {**base, "ancsh": acg.key(), "scans": SCAN_RULES, "cat": cat, "setting": setting,
                             **({"structure": st} if sub else {}), **({"init": str(init)} if init is not None else {})},
                            cat, setting, g.structure, init, shared_g, after))
                        group_runs.append(run_dir)
                    runs += group_runs
                runs_of[(seed, cat)] = runs
        pending = [_pending(chain) for chain in chains.values()]
        pending = [c for c in pending if c]
        self.run_in_parallel(pending, lambda n, w: f"{v.prefix}train ancsh: {n} models in {len(pending)} chains, "
                                                   f"{w} at a time", f"{v.prefix}train ancsh", "chains")
        for (seed, cat), runs in runs_of.items():
            for a in chains.get((seed, cat), []):
                self.stage(a.folder, a.key, lambda a=a: a.run(progress, console, False), a.name, after=a.after)
            groups = self.plan[cat]
            main = seed == cfg.seed
            if main:
                res.stages.setdefault(f"{v.prefix}ancsh", []).extend(str(r) for r in runs)
            if not any(g.test for g in groups):
                if main:
                    log(f"[dim]ANCSH: {cat}: no test object of a trained structure, no Table 2 row[/]")
                continue
            ev = roots[seed] / "eval" / cat
            # the test scans and their seed are the main run's: every seed is scored on the same frames
            self.stage(ev, {**base, "runs": [str(r) for r in runs], "frames": cfg.frames_per_object,
                            "scans": SCAN_RULES},
                       lambda runs=runs, ev=ev, cat=cat: evaluate_category(
                           cat, runs, data=cfg.labeled, out=ev, scans=cfg.out / "scans" / cat,
                           frames=cfg.frames_per_object, seed=cfg.seed, progress=progress, console=console),
                       f"{v.prefix}eval {cat} (Table 2{'' if main else f', seed {seed}'})", after=runs)
            if main:
                res.stages.setdefault(f"{v.prefix}table2", []).append(str(ev))
            if len(seeds) > 1:  # the report's Table 2 over seeds (kinmo.report.paper_tables)
                res.stages.setdefault(f"{TABLE2_SEED_STAGE}{seed}", []).append(str(ev))

    def release(self, cache_l: Path, prep: Any) -> Path:
        """The release bundle (``kinmo train all --release``, issue 22) in ``out/release/model/``.

        The fine motion GNN (with the preset's augmentations), the coarse motion GNN (the
        bundle's ``check/``, which pseudo-labelling with the bundle requires to agree, issue
        34) and the axis network are trained again, by the baseline's recipe and ``-j`` at
        a time, on every labelled object plus the pseudo-labels the baseline kept (``out/pseudo/``, prepared into
        ``out/release/cache/pseudo``); nothing is held out. The learned selector is the
        baseline's ranker (fit on out-of-fold predictions of the training split). The
        bundle's ``trained_on`` lists every id used, so ``kinmo eval`` leaves them out.

        Returns
        -------
        Path
            The bundle folder.

        Raises
        ------
        KinmoDataError
            A pseudo-labelled id is also a labelled one.
        """
        import hashlib

        cfg = self.cfg
        vout = cfg.out / "release"
        caches = [cache_l]
        pseudo = cfg.out / "pseudo"
        if cfg.unlabeled is not None and pseudo.is_dir() and any(True for _ in find_shapes(pseudo)):
            pcache = vout / "cache" / "pseudo"
            self.prepare(pseudo, pcache, prep, "release: prepare pseudo-labels")
            caches.append(pcache)
        real = _graphs(caches)  # loaded once: the splits below, then every training
        cats: dict[str, str] = {}
        for g in real:
            if g.shape_id in cats:
                raise KinmoDataError(pseudo, f"shape id {g.shape_id!r} is both labelled and pseudo-labelled")
            cats[g.shape_id] = g.category
        vout.mkdir(parents=True, exist_ok=True)
        split_file = vout / "split.json"
        Split(sorted(cats), [], cats, cfg.seed, 0.0).save(split_file)
        base = {"seed": cfg.seed, "preset": cfg.preset,
                "release": hashlib.sha256(split_file.read_bytes()).hexdigest()[:16], "graphs": CACHE_VERSION}
        # generated objects for the fine GNN only (cfg.release_synth; issue 36): its own split,
        # the real objects' plus theirs; the other trainings' split leaves them out
        fine_split, fine_key, trained = split_file, {}, real
        generated = (self.generated(vout, cfg.release_synth, cache_l, prep, "release: ", "the fine GNN trains")
                     if cfg.release_synth > 0 else None)
        if generated is not None:
            fine_split = vout / "split_fine.json"
            fine_key = _add_generated(split_file, generated, fine_split, "fine_split")
            caches.append(generated.cache)
            trained = real + generated.graphs

        def graphs() -> list[PartGraph]:
            return trained

        # the fine GNN (the bundle's), the coarse GNN (its check/: pseudo-labelling with the
        # bundle requires it to agree, issue 34) and the axis network: independent trainings,
        # -j N at a time (train_models), each as the baseline trains it
        trainings: list[_Training] = []
        for types in ("fine", "coarse"):
            gcfg = gnn_preset(cfg.preset, types=types, seed=cfg.seed, epochs=cfg.gnn_epochs,
                              **({} if cfg.augment_gnn and types == "fine" else NO_AUGMENTATIONS))
            fine = types == "fine"
            trainings.append(_Training(f"release: train gnn ({types})", "gnn", vout / f"gnn_{types}", gcfg,
                                       fine_split if fine else split_file,
                                       {**base, "gnn": gcfg.model_dump(), **_members_key(cfg), **(fine_key if fine else {})},
                                       caches, cfg.gnn_members))
        gnn_dir, check_dir = trainings[0].folder, trainings[1].folder
        axis_dir = None
        if cfg.refine:
            axis_dir = vout / "axis"
            acfg = axis_preset(cfg.preset, **({"epochs": cfg.axis_epochs} if cfg.axis_epochs else {}),
                               seed=cfg.seed)
            trainings.append(_Training("release: train axis", "axis", axis_dir, acfg, split_file,
                                       {**base, "axis": acfg.model_dump()}, caches))
        # the baseline's ranker selects: no ranker stage (nor its fold GNNs) of its own
        v = _Variant(out=vout, graphs=caches, split=split_file, labeled=cfg.labeled, unlabeled=None,
                     unlabeled_cache=None, key={}, prefix="release: ", reuse={"ranker": cfg.out / "ranker"})
        self.train_models(v, base, trainings, graphs)
        ranker = cfg.out / "ranker" / "ranker.json"
        ranges = self.range_prior(v, base, lambda: cache_l, split_file)  # labelled objects only
        return self.bundle(v, base, gnn_dir, axis_dir, ranker if ranker.is_file() else None, fine_split,
                           ranges, check_dir)

    def generated(self, vout: Path, n: int, cache_l: Path, prep: Any, prefix: str, who: str) -> _Generated | None:
        """Generate and prepare ``n`` objects (of the labelled categories :mod:`kinmo.synth`
        makes, seed ``cfg.synth_seed`` or ``cfg.seed + 500``) into ``vout/generated/`` and
        ``vout/cache/generated/`` (stages named with ``prefix``): the release's
        ``release_synth`` and the main run's ``train_synth``.

        Returns
        -------
        _Generated or None
            The cache, what was generated (the stage key of what trains on them) and their
            graphs; None, with one log line (``who``: what then trains without them), when no
            labelled category can be generated.
        """
        cfg = self.cfg
        seed = _synth_seed(cfg)
        try:
            cats = _synth_categories(cache_l)
        except KinmoError:
            self.console.print(f"[dim]{prefix}kinmo synth makes none of the labelled categories; {who} "
                               "without generated objects[/]", highlight=False)
            return None
        info = {"n": n, "seed": seed, "categories": cats, "synth_version": SYNTH_VERSION}
        gen = vout / "generated"
        self.stage(gen, info, lambda: generate_dataset(gen, n, seed, categories=cats, progress=self.progress),
                   f"{prefix}generate")
        gcache = vout / "cache" / "generated"
        self.prepare(gen, gcache, prep, f"{prefix}prepare generated")
        return _Generated(gcache, info, list(load_cache(gcache)))

    def synth_extra(self, baseline: _Variant, cache_l: Path, prep: Any, cats: list[str]) -> None:
        """Train and evaluate again with ``cfg.synth_extra`` generated shapes added, into
        ``out/synth-extra-<labeled|unlabeled>-<N>/`` (:data:`SYNTH_EXTRA_FILE` says how)."""

        cfg, res = self.cfg, self.res
        vout = cfg.out / f"synth-extra-{cfg.synth_as}-{cfg.synth_extra}"
        seed = _synth_seed(cfg)
        labeled = cfg.synth_as == "labeled"
        info = {"n": cfg.synth_extra, "as": cfg.synth_as, "seed": seed, "categories": cats,
                "synth_version": SYNTH_VERSION}
        gen = vout / "data" / ("partnet-mobility" if labeled else "partnet")
        self.stage(gen, info, lambda: generate_dataset(gen, cfg.synth_extra, seed, categories=cats,
                                                       partnet=not labeled, progress=self.progress),
                   "synth-extra: generate")
        key = {"synth_extra": info}
        base_split = Split.load(cfg.out / "split.json")
        if labeled:
            gcache = vout / "cache" / "generated"
            self.prepare(gen, gcache, prep, "synth-extra: prepare generated")
            # the baseline's split with every generated object added to training: the test
            # objects stay the real held-out ones
            split_file = vout / "split.json"
            _add_generated(cfg.out / "split.json", _Generated(gcache, info, list(load_cache(gcache))), split_file,
                           "split")
            merged = _link_folder(vout / "data" / "labeled", [cfg.labeled, gen])
            # the baseline's ranker (fit on the real training objects) selects the axes
            v = _Variant(out=vout, graphs=[cache_l, gcache], split=split_file, labeled=merged,
                         unlabeled=cfg.unlabeled, unlabeled_cache=baseline.unlabeled_cache, key=key,
                         prefix="synth-extra: ", reuse={"ranker": cfg.out / "ranker"})
        else:
            merged = _link_folder(vout / "data" / "unlabeled", [p for p in (cfg.unlabeled, gen) if p is not None])
            ucache = vout / "cache" / "unlabeled"
            self.prepare(merged, ucache, prep, "synth-extra: prepare unlabelled")
            reuse = {"gnn_fine": cfg.out / "gnn_fine", "gnn_coarse": cfg.out / "gnn_coarse", "axis": cfg.out / "axis",
                     "ranker": cfg.out / "ranker"}

            for c, gs in self.plan.items():
                subs = [structure_slug(g.structure) + "/" for g in gs] if len(gs) > 1 else [""]
                reuse.update({f"ancsh/{c}/{sub}supervised": cfg.out / "ancsh" / c / sub / "supervised"
                              for sub in subs})
            v = _Variant(out=vout, graphs=cache_l, split=cfg.out / "split.json", labeled=cfg.labeled,
                         unlabeled=merged, unlabeled_cache=ucache, key=key, prefix="synth-extra: ", reuse=reuse)
        used_by = (["motion GNN"] + (["axis network"] if cfg.refine else [])
                   + ([] if cfg.skip_ancsh else ["ANCSH"])) if labeled else ["pseudo-labels", "ANCSH"]
        write_json(vout / SYNTH_EXTRA_FILE, {**info, "baseline": "..", "generated": str(gen),
                                             "used_by": used_by, "test": base_split.test})
        self.models_and_tables(v, cache_l)
        res.synth_extra = vout




@dataclasses.dataclass(frozen=True)
class _Training:
    """One model training of ``train all``: a stage's (motion GNN, axis network) or one of the
    ranker stage's fold GNNs (``key`` None: its ``model.pt`` marks it done).

    Attributes
    ----------
    name : str
        Stage name (log and timings).
    kind : {"gnn", "axis"}
        :func:`~kinmo.train.gnn.train_gnn` or :func:`~kinmo.refine.train.train_axis_model`.
    folder : Path
        The run folder.
    config : TrainConfig or AxisTrainConfig
    split : Path or Split
    key : dict or None
        The stage's key (its ``.done`` marker).
    graphs : Path or list of PartGraph
        What it trains on (a cache folder or the graphs).
    members : int
        A motion GNN's ensemble members, trained after it (:func:`~kinmo.train.gnn.train_members`).
    """

    name: str
    kind: str
    folder: Path
    config: Any
    split: Any
    key: dict[str, Any] | None
    graphs: Any
    members: int = 0

    def run(self, progress: bool, console: Any, in_pool: bool) -> None:
        """Train (``console`` and ``in_pool`` are not used: each is single-threaded already).
        A fold GNN of the ranker stage (``key`` None) is :func:`~kinmo.train.ranker.train_fold`."""
        if self.kind == "axis":
            graphs = self.graphs
            if not isinstance(graphs, (str, Path)):
                # the split's objects only: generated objects (the release's, --train-synth) train
                # the motion GNNs alone
                sp = self.split if isinstance(self.split, Split) else Split.load(self.split)
                ids = set(sp.train) | set(sp.test)
                graphs = [g for g in graphs if g.shape_id in ids]
            train_axis_model(graphs, self.folder, self.config, split=self.split, progress=progress)
        elif self.key is None:
            train_fold(self.graphs, self.folder, self.config, self.split, self.members, progress)
        else:
            train_gnn(self.graphs, self.folder, self.config, split=self.split, progress=progress)
            train_members(self.graphs, self.folder, self.config, self.members, progress=progress)


@dataclasses.dataclass(frozen=True)
class _AncshShared:
    """What every ANCSH training of a variant shares (:func:`kinmo.ancsh.train.train_ancsh`'s
    configuration, data folders, split, and the render cache whose ``<Category>/`` folders
    hold each category's scans)."""

    config: Any
    data: Path
    partnet: Path | None
    pseudo: Path | None
    split: Path
    scans: Path


@dataclasses.dataclass(frozen=True)
class _AncshStage:
    """One ANCSH training stage: name, run folder, stage key, category, setting, structure, the
    supervised run it starts from (semi) or may reuse (semi-weakly, :func:`train_ancsh`'s
    ``init``) and what the variant's trainings share."""

    name: str
    folder: Path
    key: dict[str, Any]
    category: str
    setting: str
    structure: Any
    init: Path | None
    shared: _AncshShared
    after: list[Path] = dataclasses.field(default_factory=list)

    def run(self, progress: bool, console: Any, in_pool: bool) -> None:
        """:func:`~kinmo.ancsh.train.train_ancsh` of this stage; in a pool worker, rendering
        with one process (the worker is one of ``-j``)."""
        sh = self.shared
        cfg = sh.config.model_copy(update={"render_workers": 1}) if in_pool else sh.config
        train_ancsh(self.category, self.setting, self.folder, cfg, data=sh.data, partnet=sh.partnet,
                    pseudo=sh.pseudo, split=sh.split, scans=sh.scans / self.category, init=self.init,
                    progress=progress, console=console, structure=self.structure)


def _pending(chain: list[_AncshStage]) -> list[_AncshStage]:
    """The stages of a chain to run, in order: those not up to date (:func:`stage_done`, with
    the stages they read from), and a semi or semi-weakly stage whose supervised run is among
    them."""
    out: list[_AncshStage] = []
    for a in chain:
        if not stage_done(a.folder, a.key, after=a.after) or any(b.folder == a.init for b in out):
            out.append(a)
    return out


def _run_chain(chain: list[_Training | _AncshStage]) -> list[tuple[str, float, float]]:
    """Run a chain of trainings in order, in a worker of :meth:`_Context.run_in_parallel`;
    a stage's marker is written as it finishes (an interrupted pool resumes).

    Returns
    -------
    list of (str, float, float)
        Per training: its name, wall and CPU seconds of this process.
    """
    import time

    out = []
    for t in chain:
        w0, c0 = time.perf_counter(), time.process_time()
        t.run(False, None, True)
        if t.key is not None:
            mark_done(t.folder, t.key)
        out.append((t.name, time.perf_counter() - w0, time.process_time() - c0))
    return out


def _chain_failed(chain: list[_Training | _AncshStage], exc: Exception) -> list[tuple[str, float, float]]:
    raise KinmoError(f"{chain[0].name} ({chain[0].folder}): {exc}") from exc


def _members_key(cfg: PipelineConfig) -> dict[str, Any]:
    """The stage-key entry of the motion GNNs' ensemble members: none for single models, so
    that runs without members keep their keys."""
    return {"gnn_members": cfg.gnn_members} if cfg.gnn_members else {}


def _synth_seed(cfg: PipelineConfig) -> int:
    """Seed of the generated objects (``--synth-extra`` and the release's ``--release-synth``):
    ``cfg.synth_seed``, else ``cfg.seed + 500``."""
    return cfg.synth_seed if cfg.synth_seed is not None else cfg.seed + 500


def _fold_stamp(cfg: PipelineConfig, extra: _Generated | None = None) -> dict[str, Any]:
    """The ranker's fold GNNs' configurations by type set, as JSON values, and the part graphs'
    ``CACHE_VERSION`` under ``"graphs"``: fold GNNs trained on graphs computed another way (issue
    36's OBB fit) are stale like the motion GNNs (:meth:`_Context.models_and_tables`). With
    generated objects in their training (``extra``), what was generated under ``"synth"``."""
    configs = {t: fold_config(cfg.preset, t, seed=cfg.seed, threads=1, epochs=cfg.gnn_epochs,
                              augment=cfg.augment_gnn) for t in RANKER_TYPES}
    stamp = {"graphs": CACHE_VERSION, **{t: c.model_dump(mode="json") for t, c in configs.items()},
             **({"synth": extra.info} if extra is not None else {})}
    return json.loads(json.dumps(stamp))


def _ranker_fold_stamp(cfg: PipelineConfig, folder: Path, extra: _Generated | None = None) -> None:
    """Write ``folder/folds.json``, the fold GNNs' configuration, removing folds trained with
    another one (they are trained again)."""
    import shutil

    stamp = _fold_stamp(cfg, extra)
    if (folder / "folds.json").is_file() and json.loads((folder / "folds.json").read_text()) != stamp:
        shutil.rmtree(folder / "folds", ignore_errors=True)
    folder.mkdir(parents=True, exist_ok=True)
    write_json(folder / "folds.json", stamp)


def _train_ranker(cfg: PipelineConfig, v: _Variant, folder: Path, progress: bool) -> None:
    """Fit the ranker of ``v`` into ``folder`` (:func:`kinmo.train.ranker.train_ranker`
    on ``v``'s cache and split, fold GNNs of ``cfg.preset`` and ``cfg.gnn_epochs``).

    ``train_ranker`` skips a fold whose ``folds/<types>_<f>/model.pt`` exists (trained by
    :meth:`_Context.train_in_parallel`, or by an interrupted run); ``folds.json`` holds the
    fold GNNs' configuration, and folds of another one are trained again.
    """
    _ranker_fold_stamp(cfg, folder, v.extra)
    train_ranker(v.graphs, folder, v.split, folds=RANKER_FOLDS, preset=cfg.preset, types=RANKER_TYPES,
                 seed=cfg.seed, threads=1, progress=progress, epochs=cfg.gnn_epochs,
                 workers=cfg.workers, augment=cfg.augment_gnn, members=cfg.gnn_members,
                 extra=v.extra.graphs if v.extra is not None else ())


def _add_generated(split_file: Path, gen: _Generated, path: Path, name: str) -> dict[str, Any]:
    """Write ``path``: the split of ``split_file`` with ``gen``'s objects added to its training
    ids (the release's ``split_fine.json``, the main run's ``split_gnn.json``, ``--synth-extra``'s
    ``split.json``), and return the stage-key entry of the models trained on it: what was
    generated, and under ``name`` a digest of the new split.

    Raises
    ------
    KinmoDataError
        A generated id is also one of the split's (a labelled or pseudo-labelled object).
    """
    import hashlib

    base = Split.load(split_file)
    cats = {g.shape_id: g.category for g in gen.graphs}
    if set(cats) & (set(base.train) | set(base.test)):
        raise KinmoDataError(gen.cache, "a generated shape id is also a labelled or pseudo-labelled one")
    Split(sorted(base.train + list(cats)), base.test, {**base.categories, **cats}, base.seed,
          base.test_fraction).save(path)
    return {"synth": gen.info, name: hashlib.sha256(path.read_bytes()).hexdigest()[:16]}


def _with_extra(real: Callable[[], Any], extra: list[PartGraph]) -> list[PartGraph]:
    """The graphs of ``real()`` (a cache folder or graphs) followed by ``extra``."""
    data = real()
    return [*(load_cache(data) if isinstance(data, (str, Path)) else data), *extra]
