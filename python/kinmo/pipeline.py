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
    out/cache/{labeled,unlabeled}/   kinmo prepare
    out/gnn_fine/, out/gnn_coarse/   kinmo train gnn (split.json in gnn_fine)
    out/axis/                        kinmo train axis
    out/eval/pre-segmented/          kinmo eval pre-segmented (Table 1)
    out/pseudo/                      kinmo pseudo-label
    out/ancsh/<Category>/<setting>/  kinmo train ancsh
    out/eval/<Category>/             kinmo eval --category (Table 2)
    out/report/                      kinmo report

The per-shape stages (prepare, render, pseudo-label) run in worker processes through pure
per-shape functions, ready to be mapped on Ray instead; training runs in this process (a
torch.distributed launch would wrap :func:`kinmo.train.gnn.train_gnn` and
:func:`kinmo.ancsh.train.train_ancsh`).
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Callable
from pathlib import Path
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field

from kinmo.errors import KinmoDataError
from kinmo.io import write_json, write_text

__all__ = ["PipelineConfig", "PipelineResult", "default_categories", "run_pipeline", "run_demo"]

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


class PipelineResult(BaseModel):
    """Where the stages wrote their results."""

    out: Path
    stages: dict[str, list[str]] = Field(default_factory=dict)
    categories: list[str] = Field(default_factory=list)
    skipped_categories: dict[str, str] = Field(default_factory=dict)
    report: Path | None = None


def _stage(folder: Path, key: dict[str, Any], run: Callable[[], Any], log: Callable[[str], None], name: str) -> bool:
    """Run ``run`` unless ``folder/.done`` holds ``key``; returns True if it ran."""
    marker = folder / ".done"
    text = json.dumps(key, sort_keys=True, default=str)
    if marker.is_file() and marker.read_text() == text:
        log(f"[dim]{name}: up to date ({folder})[/]")
        return False
    log(f"[bold cyan]{name}[/] -> {folder}")
    run()
    folder.mkdir(parents=True, exist_ok=True)
    write_text(marker, text)
    return True


def default_categories(labeled: Path, split_file: Path | None = None, min_train: int = 2) -> tuple[list[str], dict[str, str]]:
    """Categories with enough data for ANCSH.

    A category qualifies when the objects fitting its most common kinematic structure
    (:func:`kinmo.ancsh.structure.category_structure`) include at least ``min_train`` training
    objects and one test object of the split.

    Returns
    -------
    categories : list of str
        Sorted.
    skipped : dict of str to str
        Category → reason it was left out.
    """
    from kinmo.ancsh.structure import category_structure, object_parts
    from kinmo.data.readers import find_shapes, read_shape

    per: dict[str, dict] = {}
    for path in find_shapes(labeled):
        try:
            shape = read_shape(path)
        except KinmoDataError:
            continue
        per.setdefault(shape.category, {})[shape.id] = object_parts(shape.links or [])
    test: set[str] = set()
    if split_file is not None and split_file.is_file():
        test = set(json.loads(split_file.read_text()).get("test", []))
    keep, skipped = [], {}
    for cat, objs in sorted(per.items()):
        st, fitting = category_structure(objs)
        if st is None:
            skipped[cat] = "no object with a revolute/prismatic structure"
            continue
        n_test = sum(o in test for o in fitting)
        n_train = len(fitting) - n_test
        if n_train < min_train or n_test < 1:
            skipped[cat] = f"{n_train} training and {n_test} test objects fit {st.signature()}"
            continue
        keep.append(cat)
    return keep, skipped


def run_pipeline(cfg: PipelineConfig, console: Any = None, progress: bool = True) -> PipelineResult:
    """Run every stage of the pipeline (module docstring), resuming finished stages.

    Parameters
    ----------
    cfg : PipelineConfig
    console : rich.console.Console, optional
        Where stage headers go.
    progress : bool
        Show each stage's progress bar.

    Returns
    -------
    PipelineResult

    Raises
    ------
    KinmoDataError
        A dataset folder is missing.
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
    res = PipelineResult(out=out)
    base = {"seed": cfg.seed, "preset": cfg.preset}

    # 1. prepare
    from kinmo.prepare import PrepareConfig, prepare_dataset

    cache_l, cache_u = out / "cache" / "labeled", out / "cache" / "unlabeled"
    prep = PrepareConfig(seed=cfg.seed)
    _stage(cache_l, {"src": str(cfg.labeled), **dataclasses.asdict(prep)}, lambda: prepare_dataset(
        cfg.labeled, cache_l, prep, workers=cfg.workers, progress=progress), log, "prepare labelled")
    if cfg.unlabeled is not None:
        _stage(cache_u, {"src": str(cfg.unlabeled), **dataclasses.asdict(prep)}, lambda: prepare_dataset(
            cfg.unlabeled, cache_u, prep, workers=cfg.workers, progress=progress), log, "prepare unlabelled")
    res.stages["prepare"] = [str(cache_l)] + ([str(cache_u)] if cfg.unlabeled else [])

    # 2. motion GNN, fine and coarse types (Sec. 3.1-3.2)
    from kinmo.train.config import preset as gnn_preset
    from kinmo.train.gnn import train_gnn

    gnn_runs = {}
    split_file = out / "gnn_fine" / "split.json"
    for types in ("fine", "coarse"):
        run_dir = out / f"gnn_{types}"
        gcfg = gnn_preset(cfg.preset, types=types, seed=cfg.seed, epochs=cfg.gnn_epochs)
        split = split_file if types == "coarse" else None
        _stage(run_dir, {**base, "gnn": gcfg.model_dump()}, lambda gcfg=gcfg, run_dir=run_dir, split=split: train_gnn(
            cache_l, run_dir, gcfg, split=split, progress=progress), log, f"train gnn ({types})")
        gnn_runs[types] = run_dir
    res.stages["gnn"] = [str(p) for p in gnn_runs.values()]

    # 3. axis-selection network (Sec. 3.3)
    from kinmo.refine.train import preset_config as axis_preset
    from kinmo.refine.train import train_axis_model

    axis_dir = out / "axis"
    acfg = axis_preset(cfg.preset, **({"epochs": cfg.axis_epochs} if cfg.axis_epochs else {}), seed=cfg.seed)
    _stage(axis_dir, {**base, "axis": acfg.model_dump()}, lambda: train_axis_model(
        cache_l, axis_dir, acfg, split=split_file, progress=progress), log, "train axis")
    res.stages["axis"] = [str(axis_dir)]

    # 4. Table 1 on the held-out pre-segmented shapes
    from kinmo.evaluate.pre_segmented import run_evaluation

    t1 = out / "eval" / "pre-segmented"
    _stage(t1, {**base, "models": [str(p) for p in gnn_runs.values()], "axis": str(axis_dir)},
           lambda: run_evaluation([gnn_runs["fine"], gnn_runs["coarse"]], cfg.labeled, out=t1, split=split_file,
                                  progress=progress, **_refine_kwargs(axis_dir)),
           log, "eval pre-segmented (Table 1)")
    res.stages["table1"] = [str(t1)]

    # 5. pseudo-labels on the unlabelled shapes (Sec. 3.3)
    pseudo = out / "pseudo"
    if cfg.unlabeled is not None:
        from kinmo.pseudo_label import PseudoLabelConfig, pseudo_label_dataset

        pcfg = PseudoLabelConfig(threshold=cfg.threshold)
        _stage(pseudo, {**base, "pseudo": pcfg.model_dump()}, lambda: pseudo_label_dataset(
            cfg.unlabeled, gnn_runs["fine"], axis_dir, pseudo, pcfg, workers=cfg.workers, cache=cache_u,
            progress=progress), log, "pseudo-label")
        res.stages["pseudo"] = [str(pseudo)]

    # 6. ANCSH on partial scans, three settings, per category (Sec. 3.4, Table 2)
    from kinmo.ancsh.config import preset as ancsh_preset
    from kinmo.ancsh.evaluate import evaluate_category
    from kinmo.ancsh.train import train_ancsh

    if cfg.categories:
        cats, skipped = list(cfg.categories), {}
    else:
        cats, skipped = default_categories(cfg.labeled, split_file)
    res.categories, res.skipped_categories = cats, skipped
    for cat, why in skipped.items():
        log(f"[dim]ANCSH: {cat} left out: {why}[/]")
    settings = [s for s in cfg.settings if s == "supervised" or cfg.unlabeled is not None]
    scans = out / "scans"
    for cat in cats:
        runs = []
        for setting in settings:
            run_dir = out / "ancsh" / cat / setting
            overrides = {
                "epochs": cfg.ancsh_epochs, "semi_epochs": cfg.semi_epochs,
                "steps_per_epoch": cfg.ancsh_steps_per_epoch, "frames_per_object": cfg.frames_per_object,
                "unlabeled_frames_per_object": cfg.frames_per_object,
                "test_frames_per_object": cfg.frames_per_object,
                "labeled_fraction": cfg.labeled_fraction, "seed": cfg.seed,
            }
            ac = ancsh_preset(cfg.preset, **{k: v for k, v in overrides.items() if v is not None})
            _stage(run_dir, {**base, "ancsh": ac.model_dump(), "cat": cat, "setting": setting},
                   lambda ac=ac, run_dir=run_dir, setting=setting, cat=cat: train_ancsh(
                       cat, setting, run_dir, ac, data=cfg.labeled, partnet=cfg.unlabeled,
                       pseudo=pseudo if cfg.unlabeled is not None else None, split=split_file, scans=scans,
                       progress=progress, console=console),
                   log, f"train ancsh {cat} ({setting})")
            runs.append(run_dir)
        ev = out / "eval" / cat
        _stage(ev, {**base, "runs": [str(r) for r in runs], "frames": cfg.frames_per_object},
               lambda runs=runs, ev=ev, cat=cat: evaluate_category(
                   cat, runs, data=cfg.labeled, out=ev, scans=scans, frames=cfg.frames_per_object, seed=cfg.seed,
                   progress=progress, console=console),
               log, f"eval {cat} (Table 2)")
        res.stages.setdefault("ancsh", []).extend(str(r) for r in runs)
        res.stages.setdefault("table2", []).append(str(ev))

    # 7. report
    from kinmo.report import write_report

    rep = write_report(out, out / "report")
    res.report = rep.html
    write_json(out / "pipeline_result.json", json.loads(res.model_dump_json()))
    return res


def _refine_kwargs(axis_dir: Path) -> dict[str, Any]:
    """Options of :func:`kinmo.evaluate.pre_segmented.run_evaluation` that add the OBB
    (refined) settings of Table 1, where that function supports them."""
    import inspect

    from kinmo.evaluate.pre_segmented import run_evaluation

    params = inspect.signature(run_evaluation).parameters
    for name in ("axis_model", "refine"):
        if name in params:
            return {name: axis_dir}
    return {}


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
    (:func:`kinmo.synth.generate_dataset`, different seeds), then :func:`run_pipeline` with
    the ``quick`` preset, shortened so that it finishes in minutes on 2 CPU cores, and the
    report.

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
    from kinmo.synth import CATEGORIES, generate_dataset

    out = Path(out)
    if data is None:
        cats = [c for c in ("Refrigerator", "Laptop", "StorageFurniture", "Microwave") if c in CATEGORIES]
        lab = out / "data" / "partnet-mobility"
        unl = out / "data" / "partnet"
        generate_dataset(lab, n_labeled, seed, categories=cats, progress=progress)
        generate_dataset(unl, n_unlabeled, seed + 1, categories=cats, partnet=True, progress=progress)
        data, unlabeled = lab, unl
    cfg = PipelineConfig(
        labeled=data, unlabeled=unlabeled, out=out / "run", preset="quick", seed=seed,
        gnn_epochs=3 if tiny else 25, axis_epochs=2 if tiny else 8,
        ancsh_epochs=1 if tiny else 4, semi_epochs=1 if tiny else 2,
        ancsh_steps_per_epoch=2 if tiny else 15, frames_per_object=1 if tiny else 3,
        categories=(["Laptop"] if tiny else None),
    )
    return run_pipeline(cfg, console=console, progress=progress)
