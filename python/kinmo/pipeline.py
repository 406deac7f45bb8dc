"""The whole pipeline, from dataset folders to trained models and tables (``kinmo train all``,
``kinmo demo``).

Liu et al. CVPR 2023, Fig. 2: the motion GNN and the axis-selection network are trained on
labelled PartNet-Mobility objects, pseudo-label the unlabelled PartNet shapes, and ANCSH is
trained on rendered partial scans in the three settings of Table 2 (``supervised``,
``semi``, ``semi-weakly``) and evaluated on scans of held-out objects.

Every stage writes its own folder below ``out`` and is skipped when that folder already holds
a finished result of the same configuration (a ``.done`` file with the configuration's
JSON), so an interrupted run resumes where it stopped. Layout::

    out/pipeline.json            the PipelineConfig
    out/split.json               train/test split by category and kinematic structure
                                     (:func:`structure_split`), used by every model
    out/cache/{labeled,unlabeled}/   kinmo prepare
    out/gnn_fine/, out/gnn_coarse/   kinmo train gnn (split.json in gnn_fine)
    out/axis/                        kinmo train axis
    out/eval/pre-segmented/          kinmo eval pre-segmented (Table 1)
    out/pseudo/                      kinmo pseudo-label
    out/ancsh/<Category>/<setting>/  kinmo train ancsh
    out/eval/<Category>/             kinmo eval --category (Table 2)
    out/synth-extra-<as>-<N>/        --synth-extra N: the same with generated shapes added
    out/report/                      kinmo report

The per-shape stages (prepare, render, pseudo-label) run in worker processes through pure
per-shape functions, ready to be mapped on Ray instead; training runs in this process (a
torch.distributed launch would wrap :func:`kinmo.train.gnn.train_gnn` and
:func:`kinmo.ancsh.train.train_ancsh`).
"""

from __future__ import annotations

import dataclasses
import functools
import json
from collections.abc import Callable
from pathlib import Path
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, model_validator

from kinmo.errors import KinmoDataError
from kinmo.io import write_json, write_text
from kinmo.runs import DEFAULT_RUN, SYNTH_EXTRA_FILE

__all__ = ["PipelineConfig", "PipelineResult", "StageTiming", "default_categories", "run_pipeline", "run_demo",
           "ANCSH_PLAN_FILE", "DEFAULT_RUN", "TINY", "CategoryRuns", "FoundData", "ancsh_plan", "category_runs",
           "find_data", "missing_data_message", "structure_split"]

SETTINGS = ("supervised", "semi", "semi-weakly")


class PipelineConfig(BaseModel):
    """Everything ``kinmo train all`` depends on.

    Attributes
    ----------
    labeled : Path
        PartNet-Mobility folders (labelled objects).
    unlabeled : Path or None
        PartNet folders (unlabelled shapes) to pseudo-label; ``None`` skips pseudo-labels and
        the ``semi`` / ``semi-weakly`` settings.
    out : Path
        Run folder.
    preset : {"quick", "paper"}
        Preset of every model (``quick``: 2 CPU cores; ``paper``: the paper's sizes, a GPU).
    categories : list of str or None
        ANCSH categories; ``None``: :func:`default_categories`.
    settings : list of str
        ANCSH settings to train.
    labeled_fraction : float
        Fraction of the labelled training objects ANCSH sees (paper ratio study: 0.3, 0.5,
        0.8, 1.0).
    seed : int
    workers : int
        Worker processes of the per-shape stages (0: one per core).
    gnn_epochs, axis_epochs, ancsh_epochs, semi_epochs : int or None
        Override the presets' epochs (tiny demo runs).
    frames_per_object : int or None
        Override the rendered scans per object.
    ancsh_steps_per_epoch : int or None
    threshold : float
        Pseudo-label score threshold (paper: 0.6).
    render : bool
        Render the Table 1 predictions of the test shapes (moving parts coloured, predicted
        and true axes) for the report's gallery.
    refine : bool
        Train the axis-selection network and add the refined (``OBB_*``) rows to Table 1;
        without it, no pseudo-labels (they need it), so ``unlabeled`` must be None and
        ``synth_as`` ``labeled``.
    skip_ancsh : bool
        Stop after the pseudo-labels: no ANCSH, no Table 2.
    synth_extra : int
        Generate this many objects (:func:`kinmo.synth.generate_dataset`, of the labelled
        data's categories that it supports) and train and evaluate everything again with
        them added, into ``out/synth-extra-<synth_as>-<N>/``; the baseline's stages are
        shared with a run without generated shapes in the same folder, so several such runs
        can be added to one. The report compares them on the real test objects (the paper's
        study with generated DSG-Net shapes, Sec. 4.3).
    synth_as : {"labeled", "unlabeled"}
        ``labeled``: the generated objects join the labelled training objects (motion GNN,
        axis network, ANCSH); ``unlabeled``: they join the PartNet shapes to pseudo-label
        (the GNN and axis network of the baseline label them; ANCSH ``semi`` and
        ``semi-weakly`` are trained again).
    synth_seed : int or None
        Seed of the generated objects (default ``seed + 500``).
    """

    model_config = ConfigDict(extra="forbid")

    labeled: Path
    unlabeled: Path | None = None
    out: Path
    preset: Literal["quick", "paper"] = "quick"
    categories: list[str] | None = None
    settings: list[Literal["supervised", "semi", "semi-weakly"]] = Field(default_factory=lambda: list(SETTINGS))
    labeled_fraction: float = Field(1.0, gt=0, le=1)
    seed: int = 0
    workers: int = Field(0, ge=0)
    gnn_epochs: int | None = Field(None, ge=1)
    axis_epochs: int | None = Field(None, ge=1)
    ancsh_epochs: int | None = Field(None, ge=1)
    semi_epochs: int | None = Field(None, ge=1)
    ancsh_steps_per_epoch: int | None = Field(None, ge=1)
    frames_per_object: int | None = Field(None, ge=1)
    threshold: float = Field(0.6, ge=0, le=1)
    render: bool = True
    refine: bool = True
    skip_ancsh: bool = False
    synth_extra: int = Field(0, ge=0, le=100000)
    synth_as: Literal["labeled", "unlabeled"] = "labeled"
    synth_seed: int | None = Field(None, ge=0, le=99999)

    @model_validator(mode="after")
    def _check(self) -> PipelineConfig:
        if not self.refine and self.unlabeled is not None:
            raise ValueError("pseudo-labels need the axis network: without refine, give no unlabelled data")
        if not self.refine and self.synth_extra and self.synth_as == "unlabeled":
            raise ValueError("generated unlabelled shapes are pseudo-labelled with the axis network: keep refine")
        return self


class StageTiming(BaseModel):
    """Time one stage took.

    Attributes
    ----------
    wall_s : float
        Wall-clock seconds.
    cpu_s : float
        CPU seconds (user + system) of this process and of the worker processes that ended
        during the stage.
    ran : bool
        False when the stage was up to date (skipped).
    """

    wall_s: float
    cpu_s: float
    ran: bool = True


class PipelineResult(BaseModel):
    """Where the stages wrote their results, and how long each took."""

    out: Path
    stages: dict[str, list[str]] = Field(default_factory=dict)
    categories: list[str] = Field(default_factory=list)
    skipped_categories: dict[str, str] = Field(default_factory=dict)
    structures: dict[str, list[str]] = Field(default_factory=dict)
    report: Path | None = None
    timings: dict[str, StageTiming] = Field(default_factory=dict)
    synth_extra: Path | None = None

    def total(self) -> StageTiming:
        """The sum over the stages."""
        return StageTiming(wall_s=sum(t.wall_s for t in self.timings.values()),
                           cpu_s=sum(t.cpu_s for t in self.timings.values()),
                           ran=any(t.ran for t in self.timings.values()))


def _cpu_seconds() -> float:
    """User + system CPU seconds of this process and its finished children."""
    import resource

    own, kids = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + kids.ru_utime + kids.ru_stime


class _Clock:
    """Times the stages of a run into ``timings`` and prints one line per stage."""

    def __init__(self, timings: dict[str, StageTiming], log: Callable[[str], None]) -> None:
        self.timings, self.log = timings, log

    def run(self, name: str, fn: Callable[[], Any]) -> Any:
        """Call ``fn``, record its wall and CPU time as stage ``name``, print them."""
        import time

        w0, c0 = time.perf_counter(), _cpu_seconds()
        value = fn()
        t = StageTiming(wall_s=round(time.perf_counter() - w0, 2), cpu_s=round(_cpu_seconds() - c0, 2))
        self.timings[name] = t
        self.log(f"[green]{name}[/]: {t.wall_s:.1f} s wall, {t.cpu_s:.1f} s CPU")
        return value

    def skipped(self, name: str) -> None:
        """Record stage ``name`` as up to date (not run)."""
        self.timings[name] = StageTiming(wall_s=0.0, cpu_s=0.0, ran=False)


def _stage(folder: Path, key: dict[str, Any], run: Callable[[], Any], log: Callable[[str], None], name: str,
           clock: _Clock | None = None) -> bool:
    """Run ``run`` unless ``folder/.done`` holds ``key``; returns True if it ran.

    With a ``clock``, the stage's time is recorded under ``name``.
    """
    marker = folder / ".done"
    text = json.dumps(key, sort_keys=True, default=str)
    if marker.is_file() and marker.read_text() == text:
        log(f"[dim]{name}: up to date ({folder})[/]")
        if clock is not None:
            clock.skipped(name)
        return False
    log(f"[bold cyan]{name}[/] -> {folder}")
    if clock is not None:
        clock.run(name, run)
    else:
        run()
    folder.mkdir(parents=True, exist_ok=True)
    write_text(marker, text)
    return True


def ancsh_plan(labeled: Path, split_file: Path | None = None, categories: list[str] | None = None,
               min_train: int = 2) -> tuple[dict[str, list[Any]], dict[str, str]]:
    """Which ANCSH models ``kinmo train all`` trains: one per category and kinematic structure.

    ANCSH is category-level with one structure, so a category whose objects have several
    structures (Refrigerator, StorageFurniture) gets one model per structure that has at least
    ``min_train`` training objects and one test object of the split
    (:func:`kinmo.ancsh.structure.structure_groups`); each test object is evaluated with the
    model of its structure. With ``categories`` given (``--category``), only those are
    planned, by the same rule; one that no structure qualifies gets one model anyway, of its
    most common structure with a training and a test object, else with a training object
    (evaluate that on other objects with ``kinmo eval --category C --data DIR``).

    Parameters
    ----------
    labeled : Path
        PartNet-Mobility dataset folder.
    split_file : Path, optional
        ``split.json`` whose ``test`` ids are held out (missing: every object is training).
    categories : list of str, optional
        Categories to plan, any spelling; default every category of ``labeled``.
    min_train : int

    Returns
    -------
    plan : dict of str to list of StructureGroup
        Category (canonical name) → its structures to train, most common first; sorted.
    skipped : dict of str to str
        Category → why it gets no model (the counts of its most common structures).

    Raises
    ------
    KinmoError
        A named category has no object under ``labeled``.
    """
    from kinmo.ancsh.dataset import category_key
    from kinmo.ancsh.structure import structure_groups
    from kinmo.errors import KinmoError

    per = _object_structures(labeled)
    test: set[str] = set()
    if split_file is not None and split_file.is_file():
        test = set(json.loads(split_file.read_text()).get("test", []))
    wanted = None
    if categories:
        names = {category_key(c): c for c in per}
        wanted = set()
        for c in categories:
            if category_key(c) not in names:
                raise KinmoError(f"{labeled}: no object of category {c!r} (categories: {', '.join(sorted(per))})")
            wanted.add(names[category_key(c)])
    plan: dict[str, list[Any]] = {}
    skipped: dict[str, str] = {}
    for cat, objs in sorted(per.items()):
        if wanted is not None and cat not in wanted:
            continue
        kept, rest = structure_groups(objs, test, min_train=min_train)
        if not kept and wanted is not None:  # named: the best structure there is
            kept = ([g for g in rest if g.train and g.test] or [g for g in rest if g.train])[:1]
            rest = [g for g in rest if g not in kept]
        if kept:
            plan[cat] = kept
        elif not rest:
            skipped[cat] = "no object with a revolute/prismatic structure"
        else:
            more = f"; {len(rest) - 3} more structures" if len(rest) > 3 else ""
            skipped[cat] = "; ".join(g.describe() for g in rest[:3]) + more
    return plan, skipped


def _object_structures(labeled: Path) -> dict[str, dict[str, Any]]:
    """Category → object id → its ANCSH parts (None: not expressible) of every readable
    PartNet-Mobility object under ``labeled``."""
    from kinmo.ancsh.structure import object_parts
    from kinmo.data.readers import find_shapes, read_shape

    per: dict[str, dict[str, Any]] = {}
    for path in find_shapes(labeled):
        try:
            shape = read_shape(path)
        except KinmoDataError:
            continue
        per.setdefault(shape.category, {})[shape.id] = object_parts(shape.links or [])
    return per


def structure_split(labeled: Path, test_fraction: float = 0.25, seed: int = 0) -> Any:
    """The train/test split of ``kinmo train all``, stratified by category and kinematic structure.

    :func:`kinmo.train.split.make_split` over strata ``<category>|<structure>`` for the
    structures (:func:`kinmo.ancsh.structure.object_parts`) that at least two objects of the
    category share, and ``<category>|other`` for the rest of the category (single structures,
    objects ANCSH cannot express). So every structure with 3 or more objects has at least 2
    training and 1 test object, and ANCSH can be trained and evaluated per structure
    (:func:`ancsh_plan`); a plain category-stratified split can leave a category's test
    objects all of structures without training objects (Refrigerator on the shared data).

    Parameters
    ----------
    labeled : Path
        PartNet-Mobility dataset folder.
    test_fraction : float
    seed : int

    Returns
    -------
    kinmo.train.split.Split
        Its ``categories`` are the real categories.
    """
    from collections import Counter

    from kinmo.train.split import make_split

    per = _object_structures(labeled)
    key = {(c, i): (o.structure.signature() if o is not None else None) for c, objs in per.items()
           for i, o in objs.items()}
    count = Counter((c, s) for (c, _), s in key.items() if s is not None)
    ids = [i for (_, i) in key]
    strata = [f"{c}|{s}" if s is not None and count[(c, s)] >= 2 else f"{c}|other" for (c, _), s in key.items()]
    sp = make_split(ids, strata, test_fraction, seed)
    sp.categories = {i: c for (c, i) in key}
    return sp


def default_categories(labeled: Path, split_file: Path | None = None, min_train: int = 2) -> tuple[list[str], dict[str, str]]:
    """Categories with enough data for ANCSH (:func:`ancsh_plan`).

    A category qualifies when one of its kinematic structures has at least ``min_train``
    training objects and one test object of the split.

    Returns
    -------
    categories : list of str
        Sorted.
    skipped : dict of str to str
        Category → reason it was left out.
    """
    plan, skipped = ancsh_plan(labeled, split_file, min_train=min_train)
    return sorted(plan), skipped


#: File under ``OUT/ancsh/`` listing the trained categories with their structures and the
#: categories left out with the reason (read by ``kinmo eval --category``).
ANCSH_PLAN_FILE = "categories.json"


@dataclasses.dataclass(frozen=True)
class FoundData:
    """The dataset folders ``kinmo train all`` uses (:func:`find_data`).

    Attributes
    ----------
    labeled, unlabeled : Path or None
        PartNet-Mobility (labelled) and PartNet (unlabelled) folders.
    why_labeled, why_unlabeled : str
        How each was found (one line).
    """

    labeled: Path | None
    unlabeled: Path | None
    why_labeled: str
    why_unlabeled: str


def _prepared_sources(cwd: Path) -> list[tuple[Path, Path, bool]]:
    """``(source folder, cache folder, labelled)`` of every ``kinmo prepare`` cache under
    ``cwd/cache`` whose source still exists, newest cache first."""
    found = []
    caches = [m.parent for m in (cwd / "cache").glob("*/manifest.json")] if (cwd / "cache").is_dir() else []
    for cache in sorted(caches, key=lambda c: -(c / "manifest.json").stat().st_mtime):
        try:
            man = json.loads((cache / "manifest.json").read_text())
            root = Path(man["root"])
            sources = [Path(r["source"]) for r in man.get("shapes", [])]
        except (OSError, ValueError, KeyError, TypeError):
            continue
        root = root if root.is_absolute() else cwd / root
        if not root.is_dir():
            continue
        labeled = any((src if src.is_absolute() else cwd / src).joinpath("mobility_v2.json").is_file()
                      for src in sources)
        found.append((root, cache, labeled))
    return found


def find_data(cwd: Path | None = None, env: dict[str, str] | None = None, labeled: Path | None = None,
              unlabeled: Path | None = None) -> FoundData:
    """The data of ``kinmo train all`` without options: one rule, for each of the labelled
    (PartNet-Mobility) and unlabelled (PartNet) folders, the first that exists of

    1. the folder given (``--labeled`` / ``--unlabeled``);
    2. the source folder of a cache that ``kinmo prepare DIR`` wrote under ``./cache/`` (its
       ``manifest.json`` remembers it): labelled when its shapes have ``mobility_v2.json``,
       unlabelled otherwise (the newest cache of each kind);
    3. ``./partnet-mobility`` / ``./partnet`` in the current folder;
    4. ``$KINMO_DATA/partnet-mobility`` / ``$KINMO_DATA/partnet``.

    No unlabelled folder: only the ``supervised`` setting is trained.

    Parameters
    ----------
    cwd : Path, optional
        The current folder (default ``Path.cwd()``).
    env : dict, optional
        Environment (default ``os.environ``).
    labeled, unlabeled : Path, optional
        Folders given on the command line.

    Returns
    -------
    FoundData
        ``labeled`` is None when nothing was found (:func:`missing_data_message`).
    """
    import os

    cwd = Path.cwd() if cwd is None else cwd
    env = dict(os.environ) if env is None else env
    prepared = _prepared_sources(cwd)
    root = env.get("KINMO_DATA")

    def pick(given: Path | None, is_labeled: bool, local: str) -> tuple[Path | None, str]:
        if given is not None:
            return given, "given on the command line"
        for src, cache, lab in prepared:
            if lab == is_labeled:
                return src, f"source of the cache {cache} that `kinmo prepare` wrote"
        if (cwd / local).is_dir():
            return cwd / local, f"./{local} in the current folder"
        if root and (Path(root) / local).is_dir():
            return Path(root) / local, f"$KINMO_DATA/{local}"
        return None, "none found"

    lab, why_l = pick(labeled, True, "partnet-mobility")
    unl, why_u = pick(unlabeled, False, "partnet")
    return FoundData(lab, unl, why_l, why_u)


def missing_data_message() -> str:
    """The one-line error of ``kinmo train all`` when :func:`find_data` finds no labelled data."""
    return ("no labelled PartNet-Mobility data found: run `kinmo prepare partnet-mobility/` (or put it in "
            "./partnet-mobility, set KINMO_DATA to a folder holding partnet-mobility/ and partnet/, or give "
            "--labeled DIR)")


#: Run folder of ``kinmo train all`` without ``--out``.


@dataclasses.dataclass(frozen=True)
class CategoryRuns:
    """Where ``kinmo eval --category C`` finds the ANCSH runs of a category (:func:`category_runs`).

    Attributes
    ----------
    runs : Path or None
        Folder holding the category's runs; None when there are none.
    scans : Path or None
        The run's render cache (``kinmo train all``'s ``scans/``) to reuse for the test scans.
    message : str
        Where the runs were found, or (``runs`` None) one line saying why there are none and
        the command that would train them.
    category : str
        The category as the runs name it (the folder's name), else as given.
    """

    runs: Path | None
    scans: Path | None
    message: str
    category: str = ""


def category_runs(category: str, cwd: Path | None = None) -> CategoryRuns:
    """The ANCSH runs of ``category`` without a path: those of the last ``kinmo train all`` in
    the default run folder (``runs/all/ancsh/<Category>/``), else those of ``kinmo train ancsh``
    (``runs/ancsh/<category>/``).

    Parameters
    ----------
    category : str
        Any spelling (``refrigerator``, ``Refrigerators``, ``storage_furniture``).
    cwd : Path, optional
        Current folder (default ``Path.cwd()``).

    Returns
    -------
    CategoryRuns
    """
    from kinmo.ancsh.dataset import category_key

    cwd = Path.cwd() if cwd is None else cwd
    key = category_key(category)
    keys = {key, key[:-1] if key.endswith("s") else key}  # plural: refrigerators
    run = cwd / DEFAULT_RUN
    ancsh = run / "ancsh"
    if ancsh.is_dir():
        for d in sorted(p for p in ancsh.iterdir() if p.is_dir()):
            if category_key(d.name) in keys:
                return CategoryRuns(d, run / "scans" if (run / "scans").is_dir() else None,
                                    f"runs of `kinmo train all` in {d}", d.name)
    single = cwd / "runs" / "ancsh"
    if single.is_dir():
        for d in sorted(p for p in single.iterdir() if p.is_dir()):
            if category_key(d.name) in keys:
                return CategoryRuns(d, None, f"runs of `kinmo train ancsh` in {d}", d.name)
    plan_file = ancsh / ANCSH_PLAN_FILE
    if plan_file.is_file():
        try:
            skipped = json.loads(plan_file.read_text()).get("skipped", {})
        except (OSError, ValueError):
            skipped = {}
        for cat, why in skipped.items():
            if category_key(cat) in keys:
                return CategoryRuns(None, None, (
                    f"{cat} was not trained by `kinmo train all` in {run}: {why} (a model needs 2 training "
                    f"and 1 test object of one structure); `kinmo train all --category {cat}` trains it anyway"))
    if run.is_dir():
        return CategoryRuns(None, None, f"no ANCSH run of {category!r} in {run} (its ANCSH stage has not "
                                        f"run yet?): run `kinmo train all`")
    return CategoryRuns(None, None, f"no ANCSH run of {category!r} in ./runs: run `kinmo train all` first "
                                    f"(or `kinmo train ancsh --category {category}`), or give --runs")


#: ``--preset tiny`` of ``kinmo train all`` (and ``kinmo demo --tiny``): the quick preset cut to
#: seconds per stage, to check that everything runs (tests, a first try); not for results.
TINY = {"gnn_epochs": 25, "axis_epochs": 2, "ancsh_epochs": 1, "semi_epochs": 1, "ancsh_steps_per_epoch": 2,
        "frames_per_object": 1}


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
    from rich.console import Console

    console = console or Console(stderr=True)
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

    # 1. prepare
    from kinmo.prepare import PrepareConfig

    cache_l, cache_u = out / "cache" / "labeled", out / "cache" / "unlabeled"
    prep = PrepareConfig(seed=cfg.seed)
    ctx.prepare(cfg.labeled, cache_l, prep, "prepare labelled")
    if cfg.unlabeled is not None:
        ctx.prepare(cfg.unlabeled, cache_u, prep, "prepare unlabelled")
    res.stages["prepare"] = [str(cache_l)] + ([str(cache_u)] if cfg.unlabeled else [])
    synth_cats = _synth_categories(cache_l) if cfg.synth_extra > 0 else []  # fails before training

    # 2.-6. models and tables on the labelled (and unlabelled) data
    baseline = _Variant(
        out=out, graphs=cache_l, split=None, labeled=cfg.labeled, unlabeled=cfg.unlabeled,
        unlabeled_cache=cache_u if cfg.unlabeled is not None else None, key={}, prefix="")
    ctx.models_and_tables(baseline, cache_l)

    # 7. the same with generated shapes added (the paper's DSG-Net study, Sec. 4.3)
    if cfg.synth_extra > 0:
        ctx.synth_extra(baseline, cache_l, prep, synth_cats)

    # 8. report
    from kinmo.report import write_report

    write_json(out / "pipeline_result.json", json.loads(res.model_dump_json()))  # the report shows the times
    rep = ctx.clock.run("report", lambda: write_report(out, out / "report"))
    res.report = rep.html
    write_json(out / "pipeline_result.json", json.loads(res.model_dump_json()))
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
    split : Path or None
        Split file; None: :func:`structure_split` of the labelled data (``out/split.json``).
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
        ``gnn_coarse``, ``axis``, ``ancsh/<Category>/supervised``).
    """

    out: Path
    graphs: Any
    split: Path | None
    labeled: Path
    unlabeled: Path | None
    unlabeled_cache: Path | None
    key: dict[str, Any]
    prefix: str
    reuse: dict[str, Path] = dataclasses.field(default_factory=dict)


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

    def stage(self, folder: Path, key: dict[str, Any], run: Callable[[], Any], name: str) -> bool:
        return _stage(folder, key, run, self.console.print, name, self.clock)

    def prepare(self, src: Path, cache: Path, prep: Any, name: str) -> None:
        from kinmo.prepare import prepare_dataset

        self.stage(cache, {"src": str(src), **dataclasses.asdict(prep)}, lambda: prepare_dataset(
            src, cache, prep, workers=self.cfg.workers, progress=self.progress), name)

    def models_and_tables(self, v: _Variant, eval_cache: Path) -> None:
        """Motion GNNs, axis network, Table 1, pseudo-labels, ANCSH and Table 2 of ``v``."""
        cfg, res, progress, console = self.cfg, self.res, self.progress, self.console
        log = console.print
        out = v.out
        base = {"seed": cfg.seed, "preset": cfg.preset, **v.key}
        # the training graphs, loaded once and only if a stage runs (several caches: concatenated)
        graphs = functools.cache(functools.partial(_graphs, v.graphs))
        if v.split is None:  # split by category and kinematic structure, for every model
            import hashlib

            split_file = out / "split.json"
            structure_split(cfg.labeled, seed=cfg.seed).save(split_file)
            base["split"] = hashlib.sha256(split_file.read_bytes()).hexdigest()[:16]
            v = dataclasses.replace(v, split=split_file)

        # 2. motion GNN, fine and coarse types (Sec. 3.1-3.2)
        from kinmo.train.config import preset as gnn_preset
        from kinmo.train.gnn import train_gnn

        gnn_runs: dict[str, Path] = {}
        split_file = v.split
        for types in ("fine", "coarse"):
            if f"gnn_{types}" in v.reuse:
                gnn_runs[types] = v.reuse[f"gnn_{types}"]
                continue
            run_dir = out / f"gnn_{types}"
            gcfg = gnn_preset(cfg.preset, types=types, seed=cfg.seed, epochs=cfg.gnn_epochs)
            self.stage(run_dir, {**base, "gnn": gcfg.model_dump()},
                       lambda gcfg=gcfg, run_dir=run_dir: train_gnn(
                           graphs(), run_dir, gcfg, split=split_file, progress=progress),
                       f"{v.prefix}train gnn ({types})")
            gnn_runs[types] = run_dir
        res.stages[f"{v.prefix}gnn"] = [str(p) for p in gnn_runs.values()]

        # 3. axis-selection network (Sec. 3.3)
        from kinmo.refine.train import preset_config as axis_preset
        from kinmo.refine.train import train_axis_model

        axis_dir = v.reuse.get("axis", out / "axis")
        if "axis" not in v.reuse and cfg.refine:
            acfg = axis_preset(cfg.preset, **({"epochs": cfg.axis_epochs} if cfg.axis_epochs else {}),
                               seed=cfg.seed)
            self.stage(axis_dir, {**base, "axis": acfg.model_dump()}, lambda: train_axis_model(
                graphs(), axis_dir, acfg, split=split_file, progress=progress), f"{v.prefix}train axis")
        if cfg.refine:
            res.stages[f"{v.prefix}axis"] = [str(axis_dir)]

        # 4. Table 1 on the held-out pre-segmented shapes (always the real labelled ones),
        # with renders of the predictions for the report's gallery
        from kinmo.evaluate.pre_segmented import run_evaluation

        t1 = out / "eval" / "pre-segmented"
        render = cfg.render and not v.prefix  # the gallery shows the main run
        if not ("gnn_fine" in v.reuse and "axis" in v.reuse):
            self.stage(t1, {**base, "models": [str(p) for p in gnn_runs.values()],
                            "axis": str(axis_dir) if cfg.refine else None,
                            "data": str(eval_cache), "render": render},
                       lambda: run_evaluation([gnn_runs["fine"], gnn_runs["coarse"]], eval_cache, out=t1,
                                              split=split_file, render=render, progress=progress,
                                              axis_model=axis_dir if cfg.refine else None),
                       f"{v.prefix}eval pre-segmented (Table 1)")
            res.stages[f"{v.prefix}table1"] = [str(t1)]

        # 5. pseudo-labels on the unlabelled shapes (Sec. 3.3)
        pseudo = out / "pseudo"
        if v.unlabeled is not None:
            from kinmo.pseudo_label import PseudoLabelConfig, pseudo_label_dataset

            pcfg = PseudoLabelConfig(threshold=cfg.threshold)
            self.stage(pseudo, {**base, "pseudo": pcfg.model_dump()},
                       lambda: pseudo_label_dataset(
                           v.unlabeled, gnn_runs["fine"], axis_dir, pseudo, pcfg, workers=cfg.workers,
                           cache=v.unlabeled_cache, progress=progress), f"{v.prefix}pseudo-label")
            res.stages[f"{v.prefix}pseudo"] = [str(pseudo)]

        # 6. ANCSH on partial scans, three settings, per category (Sec. 3.4, Table 2)
        if cfg.skip_ancsh:
            return
        from kinmo.ancsh.config import preset as ancsh_preset
        from kinmo.ancsh.evaluate import evaluate_category
        from kinmo.ancsh.train import train_ancsh

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
        scans = cfg.out / "scans"  # one render cache for every variant: scans of the same objects
        overrides = {
            "epochs": cfg.ancsh_epochs, "semi_epochs": cfg.semi_epochs,
            "steps_per_epoch": cfg.ancsh_steps_per_epoch, "frames_per_object": cfg.frames_per_object,
            "unlabeled_frames_per_object": cfg.frames_per_object,
            "test_frames_per_object": cfg.frames_per_object,
            "labeled_fraction": cfg.labeled_fraction, "seed": cfg.seed,
        }
        ac = ancsh_preset(cfg.preset, **{k: val for k, val in overrides.items() if val is not None})
        from kinmo.ancsh.structure import structure_slug

        for cat in res.categories:
            groups = self.plan[cat]
            runs: list[Path] = []
            for g in groups:
                # one structure: ancsh/<Category>/<setting>; several: ancsh/<Category>/<structure>/<setting>
                sub = structure_slug(g.structure) if len(groups) > 1 else ""
                label = f"{cat} {g.structure.signature()}" if sub else cat
                st = {"parents": list(g.structure.parents), "joint_types": list(g.structure.joint_types)}
                group_runs: list[Path] = []
                for setting in settings:
                    reused = v.reuse.get(f"ancsh/{cat}/{sub + '/' if sub else ''}{setting}")
                    if reused is not None:
                        group_runs.append(reused)
                        continue
                    run_dir = out / "ancsh" / cat / sub / setting
                    # semi starts from the supervised run's weights: its supervised stage would
                    # reproduce them
                    init = (group_runs[0] if setting == "semi" and group_runs and settings[0] == "supervised"
                            else None)
                    self.stage(run_dir, {**base, "ancsh": ac.model_dump(), "cat": cat, "setting": setting,
                                         **({"structure": st} if sub else {}),
                                         **({"init": str(init)} if init is not None else {})},
                               lambda run_dir=run_dir, setting=setting, cat=cat, init=init, g=g: train_ancsh(
                                   cat, setting, run_dir, ac, data=v.labeled, partnet=v.unlabeled,
                                   pseudo=pseudo if v.unlabeled is not None else None, split=split_file,
                                   scans=scans, init=init, progress=progress, console=console,
                                   structure=g.structure),
                               f"{v.prefix}train ancsh {label} ({setting})")
                    group_runs.append(run_dir)
                runs += group_runs
            res.stages.setdefault(f"{v.prefix}ancsh", []).extend(str(r) for r in runs)
            if not any(g.test for g in groups):
                log(f"[dim]ANCSH: {cat}: no test object of a trained structure, no Table 2 row[/]")
                continue
            ev = out / "eval" / cat
            self.stage(ev, {**base, "runs": [str(r) for r in runs], "frames": cfg.frames_per_object},
                       lambda runs=runs, ev=ev, cat=cat: evaluate_category(
                           cat, runs, data=cfg.labeled, out=ev, scans=scans, frames=cfg.frames_per_object,
                           seed=cfg.seed, progress=progress, console=console),
                       f"{v.prefix}eval {cat} (Table 2)")
            res.stages.setdefault(f"{v.prefix}table2", []).append(str(ev))

    def synth_extra(self, baseline: _Variant, cache_l: Path, prep: Any, cats: list[str]) -> None:
        """Train and evaluate again with ``cfg.synth_extra`` generated shapes added, into
        ``out/synth-extra-<labeled|unlabeled>-<N>/`` (:data:`SYNTH_EXTRA_FILE` says how)."""
        from kinmo.synth import SYNTH_VERSION, generate_dataset
        from kinmo.train.gnn import load_cache
        from kinmo.train.split import Split

        cfg, res = self.cfg, self.res
        vout = cfg.out / f"synth-extra-{cfg.synth_as}-{cfg.synth_extra}"
        seed = cfg.synth_seed if cfg.synth_seed is not None else cfg.seed + 500
        labeled = cfg.synth_as == "labeled"
        info = {"n": cfg.synth_extra, "as": cfg.synth_as, "seed": seed, "categories": cats,
                "synth_version": SYNTH_VERSION}
        gen = vout / "data" / ("partnet-mobility" if labeled else "partnet")
        self.stage(gen, info, lambda: generate_dataset(gen, cfg.synth_extra, seed, categories=cats,
                                                       partnet=not labeled, progress=self.progress),
                   "synth-extra: generate")
        key = {"synth_extra": info}
        base_split = Split.load(cfg.out / "gnn_fine" / "split.json")
        if labeled:
            gcache = vout / "cache" / "generated"
            self.prepare(gen, gcache, prep, "synth-extra: prepare generated")
            gen_graphs = load_cache(gcache)
            # the baseline's split with every generated object added to training: the test
            # objects stay the real held-out ones
            split = Split(sorted(base_split.train + [g.shape_id for g in gen_graphs]), base_split.test,
                          {**base_split.categories, **{g.shape_id: g.category for g in gen_graphs}},
                          base_split.seed, base_split.test_fraction)
            split_file = vout / "split.json"
            split.save(split_file)
            merged = _link_folder(vout / "data" / "labeled", [cfg.labeled, gen])
            v = _Variant(out=vout, graphs=[cache_l, gcache], split=split_file, labeled=merged,
                         unlabeled=cfg.unlabeled, unlabeled_cache=baseline.unlabeled_cache, key=key,
                         prefix="synth-extra: ")
        else:
            merged = _link_folder(vout / "data" / "unlabeled", [p for p in (cfg.unlabeled, gen) if p is not None])
            ucache = vout / "cache" / "unlabeled"
            self.prepare(merged, ucache, prep, "synth-extra: prepare unlabelled")
            reuse = {"gnn_fine": cfg.out / "gnn_fine", "gnn_coarse": cfg.out / "gnn_coarse", "axis": cfg.out / "axis"}
            from kinmo.ancsh.structure import structure_slug

            for c, gs in self.plan.items():
                subs = [structure_slug(g.structure) + "/" for g in gs] if len(gs) > 1 else [""]
                reuse.update({f"ancsh/{c}/{sub}supervised": cfg.out / "ancsh" / c / sub / "supervised"
                              for sub in subs})
            v = _Variant(out=vout, graphs=cache_l, split=cfg.out / "gnn_fine" / "split.json", labeled=cfg.labeled,
                         unlabeled=merged, unlabeled_cache=ucache, key=key, prefix="synth-extra: ", reuse=reuse)
        used_by = (["motion GNN"] + (["axis network"] if cfg.refine else [])
                   + ([] if cfg.skip_ancsh else ["ANCSH"])) if labeled else ["pseudo-labels", "ANCSH"]
        write_json(vout / SYNTH_EXTRA_FILE, {**info, "baseline": "..", "generated": str(gen),
                                             "used_by": used_by, "test": base_split.test})
        self.models_and_tables(v, cache_l)
        res.synth_extra = vout


def _synth_categories(cache: Path) -> list[str]:
    """The categories of a labelled cache that :mod:`kinmo.synth` generates (sorted).

    Raises
    ------
    KinmoError
        None of them.
    """
    from kinmo.errors import KinmoError
    from kinmo.synth import CATEGORIES
    from kinmo.train.gnn import load_cache

    real = sorted({g.category for g in load_cache(cache)})
    cats = [c for c in real if c in CATEGORIES]
    if not cats:
        raise KinmoError(f"--synth-extra: none of the labelled categories ({', '.join(real)}) can be "
                         f"generated (kinmo synth makes {', '.join(CATEGORIES)})")
    return cats


def _graphs(source: Any) -> Any:
    """A cache folder as is, or the graphs of several caches concatenated."""
    if isinstance(source, (str, Path)):
        return source
    from kinmo.train.gnn import load_cache

    return [g for c in source for g in load_cache(c)]


def _link_folder(folder: Path, sources: list[Path]) -> Path:
    """``folder`` holding a symbolic link to every shape folder of ``sources`` (a dataset made
    of several); links are replaced, nothing else is touched."""
    from kinmo.data.readers import find_shapes

    folder.mkdir(parents=True, exist_ok=True)
    for src in sources:
        for shape in find_shapes(src):
            link = folder / shape.name
            if link.is_symlink():
                if link.resolve() == shape.resolve():
                    continue
                link.unlink()
            elif link.exists():
                raise KinmoDataError(link, "exists and is not a link made by kinmo")
            link.symlink_to(shape.resolve(), target_is_directory=True)
    return folder


#: Categories of the objects ``kinmo demo`` generates.
DEMO_CATEGORIES = ("Refrigerator", "Laptop", "StorageFurniture", "Microwave")
#: ``kinmo demo --tiny``: simple objects (few parts, so few edges to refine in Table 1).
TINY_CATEGORIES = ("Laptop", "Refrigerator")


def run_demo(
    out: Path,
    n_labeled: int = 24,
    n_unlabeled: int = 12,
    seed: int = 0,
    data: Path | None = None,
    unlabeled: Path | None = None,
    tiny: bool = False,
    console: Any = None,
    progress: bool = True,
) -> PipelineResult:
    """``kinmo demo``: the whole pipeline on objects kinmo generates itself (or on ``data``).

    Generates ``n_labeled`` PartNet-Mobility objects and ``n_unlabeled`` PartNet shapes
    (:func:`kinmo.synth.generate_dataset`, different seeds, :data:`DEMO_CATEGORIES`), then
    :func:`run_pipeline` with the ``quick`` preset shortened for 2 CPU cores: motion GNNs 25
    epochs, axis network 8, ANCSH 16 epochs of 15 steps (+4 semi-supervised) on 3 scans per
    object, Table 1 renders for the gallery, and the report. With the defaults this was
    measured at 158 CPU-seconds (2 min 27 s wall on 2 cores, 1.45 GB peak memory).

    Parameters
    ----------
    out : Path
        Run folder (generated data under ``out/data``).
    n_labeled, n_unlabeled : int
    seed : int
    data, unlabeled : Path, optional
        Real PartNet-Mobility / PartNet folders to use instead of generated objects.
    tiny : bool
        A minimal configuration (a few epochs, one frame per object) for tests.
    """
    from rich.console import Console

    from kinmo.synth import CATEGORIES, SYNTH_VERSION, generate_dataset

    console = console or Console(stderr=True)
    out = Path(out)
    timings: dict[str, StageTiming] = {}
    if data is None:
        cats = [c for c in (TINY_CATEGORIES if tiny else DEMO_CATEGORIES) if c in CATEGORIES]
        lab = out / "data" / "partnet-mobility"
        unl = out / "data" / "partnet"
        key = {"labeled": n_labeled, "unlabeled": n_unlabeled, "seed": seed, "categories": cats,
               "synth_version": SYNTH_VERSION}
        _stage(out / "data", key, lambda: (
            generate_dataset(lab, n_labeled, seed, categories=cats, progress=progress),
            generate_dataset(unl, n_unlabeled, seed + 1, categories=cats, partnet=True, progress=progress)),
            console.print, f"generate {n_labeled} labelled + {n_unlabeled} unlabelled objects",
            _Clock(timings, console.print))
        data, unlabeled = lab, unl
    cfg = PipelineConfig(
        labeled=data, unlabeled=unlabeled, out=out / "run", preset="quick", seed=seed,
        **(TINY if tiny else {"gnn_epochs": 25, "axis_epochs": 8, "ancsh_epochs": 16, "semi_epochs": 4,
                              "ancsh_steps_per_epoch": 15, "frames_per_object": 3}),
        categories=(["Laptop"] if tiny else None),
    )
    return run_pipeline(cfg, console=console, progress=progress, timings=timings)
