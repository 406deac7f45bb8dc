"""``kinmo demo``: the whole pipeline on objects kinmo generates itself."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from kinmo.pipeline.config import PipelineConfig, TINY
from kinmo.pipeline.run import run_pipeline
from kinmo.pipeline.stages import PipelineResult, StageTiming, _Clock, _stage
from kinmo.progress import console as new_console
from kinmo.synth import CATEGORIES, SYNTH_VERSION, generate_dataset

__all__ = ["DEMO_CATEGORIES", "TINY_CATEGORIES", "run_demo"]


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
    selector: str = "learned",
) -> PipelineResult:
    """``kinmo demo``: the whole pipeline on objects kinmo generates itself (or on ``data``).

    Generates ``n_labeled`` PartNet-Mobility objects and ``n_unlabeled`` PartNet shapes
    (:func:`kinmo.synth.generate_dataset`, different seeds, :data:`DEMO_CATEGORIES`), then
    :func:`run_pipeline` with the ``quick`` preset shortened for 2 CPU cores: motion GNNs 25
    epochs, axis network 8, ANCSH 16 epochs of 15 steps (+4 semi-supervised) on 3 scans per
    object, Table 1 renders for the gallery, and the report. With the defaults: 184
    CPU-seconds, 2 min 46 s wall on 2 idle cores, 1.43 GB peak memory (ranker stage and the
    paper selector's Table 1 included).

    With the learned selector (the default) 3 of the 12 generated shapes (Laptops) reach the
    0.6 calibrated confidence (its fold GNNs train 25 epochs on 24 objects; out-of-fold top-1
    about 0.56), so the semi-weakly setting adds pseudo-labelled scans for Laptop only; the
    paper's selector (``selector="paper"``) kept 7 of the 12 on the same models (uncalibrated
    scores).

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
    selector : {"learned", "paper"}
        :attr:`PipelineConfig.selector`.
    """
    console = console or new_console(stderr=True)
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
        **(TINY if tiny else {"augment_gnn": False, "gnn_epochs": 25, "axis_epochs": 8, "ancsh_epochs": 16, "semi_epochs": 4,
                              "ancsh_steps_per_epoch": 15, "frames_per_object": 3}),
        categories=(["Laptop"] if tiny else None), selector=selector,
    )
    return run_pipeline(cfg, console=console, progress=progress, timings=timings)
