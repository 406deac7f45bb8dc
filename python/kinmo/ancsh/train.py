"""Training of ANCSH on rendered partial scans of one category (``kinmo train ancsh``).

Liu et al. CVPR 2023, Sec. 3.4 and 4.3 (Table 2). :func:`train_ancsh` runs one of the three
settings of :data:`kinmo.ancsh.config.SETTINGS` for a category:

1. the category's PartNet-Mobility objects under ``data`` are mapped onto the category's
   kinematic structure (:func:`kinmo.ancsh.objects.scan_category`); objects with another
   structure are left out (listed in ``data.json``);
2. the train/test split is read (``split``, e.g. the motion GNN run's ``split.json``) or made
   over every object under ``data`` with :func:`kinmo.train.split.make_split` (the GNN's
   default fraction and the run's seed give the GNN's split), and written to
   ``RUN/split.json``: test objects are never rendered for training;
3. ``labeled_fraction`` of the fitting training objects (``round(fraction * n)``, at least
   one; a seeded subset, nested across fractions for one seed: :func:`_labeled_subset`) are
   rendered (``kinmo render`` pipeline, :func:`kinmo.render.dataset.render_dataset`, random
   joint states and viewpoints) into ``SCANS/labeled``;
4. ``semi-weakly``: the pseudo-labelled PartNet shapes of the category (``kinmo
   pseudo-label`` output, PartNet-Mobility format) that fit the structure are rendered at
   random articulations of their predicted joints into ``SCANS/pseudo-labeled`` and join the
   labelled scans;
5. with ``synth_objects`` > 0, generated objects of the structure (``kinmo synth``) join the
   labelled scans, mixed into the batches or pretrained on first (``synth_as``,
   :mod:`kinmo.ancsh.generated`);
6. ANCSH (:class:`kinmo.ancsh.model.ANCSH`) is trained for ``epochs x steps_per_epoch``
   batches;
7. ``semi``: the PartNet shapes of the category are rendered at rest
   (:func:`kinmo.ancsh.semi.unlabeled_object`) into ``SCANS/unlabeled``, the model labels
   them, confident scans (segmentation confidence and RANSAC inlier ratio above the
   thresholds, then the ``pseudo_keep_fraction`` best by inlier ratio) become pseudo-targets
   (:mod:`kinmo.ancsh.semi`) and training continues ``semi_epochs`` epochs on both.

Shapes whose id is a test object are never used as unlabelled or pseudo-labelled data.

Run folder:

- ``config.json``: the :class:`~kinmo.ancsh.config.ANCSHConfig` (category and setting filled
  in);
- ``split.json``: the split used;
- ``model.pt``: checkpoint (state dict, config, structure; rewritten after every epoch);
- ``metrics.csv``: one row per epoch (:data:`METRIC_COLUMNS`);
- ``data.json``: the objects and scans used (labelled, pseudo-labelled, unlabelled, kept
  pseudo-targets), objects left out and why, data roots, training time;
- ``pseudo_targets.csv`` (``semi``): confidence of every unlabelled scan and whether it was
  kept;
- ``objects/``: symbolic links to (or wrappers of) the rendered objects.

Runs are reproducible: ``seed`` seeds the split, the renders, torch, the batch order and the
point sampling.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch

from kinmo.ancsh.config import ANCSHConfig, SETTINGS, preset
from kinmo.ancsh.dataset import ANCSHFrames, load_samples, object_parts_of, scan_category
from kinmo.ancsh.fit import METRIC_COLUMNS, fit, metrics_csv
from kinmo.ancsh.generated import GeneratedData, generated_samples, mix, pretrain_epochs
from kinmo.ancsh.inference import (
    ANCSHRun,
    build_model,
    load_run,
    predict_scans,
    quiet_estimate,
    save_checkpoint,
)
from kinmo.ancsh.scans import all_categories, category_folders, render_objects
from kinmo.ancsh.structure import KinematicStructure, ObjectParts
from kinmo.errors import KinmoDataError, KinmoError
from kinmo.io import write_json, write_text
from kinmo.train import distributed
from kinmo.train.loop import resolve_device, training_session
from kinmo.train.split import Split, make_split

#: ``metrics.csv`` text of a run (:func:`kinmo.ancsh.fit.metrics_csv`; this name is kept for
#: the report's test fixtures).
_metrics_csv = metrics_csv

__all__ = [
    "METRIC_COLUMNS",
    "ANCSHRun",
    "TrainResult",
    "fit",
    "load_run",
    "predict_scans",
    "quiet_estimate",
    "render_objects",
    "save_checkpoint",
    "train_ancsh",
]


@dataclass
class TrainResult:
    """Outcome of :func:`train_ancsh`.

    Attributes
    ----------
    run_dir : Path
    config : ANCSHConfig
    structure : KinematicStructure
    history : list of dict
        The rows of ``metrics.csv``.
    data : dict
        The content of ``data.json``.
    seconds : float
    """

    run_dir: Path
    config: ANCSHConfig
    structure: KinematicStructure
    history: list[dict[str, Any]]
    data: dict[str, Any]
    seconds: float = 0.0



def _labeled_subset(ids: list[str], fraction: float, seed: int) -> list[str]:
    """The labelled training objects of a run with ``labeled_fraction`` (paper's ratio study).

    Parameters
    ----------
    ids : list of str
        The category's training objects that fit its structure.
    fraction : float
        In (0, 1].
    seed : int

    Returns
    -------
    list of str
        ``max(1, round(fraction * len(ids)))`` objects (Python rounding: 30 % of 4 is 1, 80 %
        of 4 is 3), sorted: the first ones of a permutation of the sorted ids seeded by
        ``(seed, 7)``, so that for one seed the subsets of smaller fractions are contained in
        those of larger ones (the ratio study adds objects, it does not swap them). All of
        ``ids`` for ``fraction >= 1``.
    """
    if fraction >= 1.0 or not ids:
        return list(ids)
    k = max(1, int(round(len(ids) * fraction)))
    ordered = sorted(ids)
    order = np.random.default_rng([seed, 7]).permutation(len(ordered))
    return sorted(str(ordered[i]) for i in order[:k])


def _say(console: Any, text: str) -> None:
    if console is not None:
        console.print(text, highlight=False, soft_wrap=True)


def train_ancsh(
    category: str,
    setting: str,
    out: str | Path,
    config: ANCSHConfig | None = None,
    data: str | Path | None = None,
    partnet: str | Path | None = None,
    pseudo: str | Path | None = None,
    split: str | Path | None = None,
    scans: str | Path | None = None,
    init: str | Path | None = None,
    progress: bool = True,
    console: Any = None,
    structure: KinematicStructure | None = None,
) -> TrainResult:
    """Train ANCSH on rendered scans of one category in one setting (module docstring).

    Parameters
    ----------
    category : str
        Any spelling (``"Laptop"``, ``"storage_furniture"``).
    setting : {"supervised", "semi", "semi-weakly"}
    out : str or Path
        Run folder.
    config : ANCSHConfig, optional
        Default: the ``quick`` preset.
    data : str or Path
        PartNet-Mobility dataset folder (labelled objects).
    partnet : str or Path, optional
        ``semi``: PartNet dataset folder (unlabelled shapes); default ``data/../partnet``.
    pseudo : str or Path, optional
        ``semi-weakly``: output folder of ``kinmo pseudo-label`` (required).
    split : str or Path, optional
        A ``split.json`` (e.g. the GNN run's) instead of making one.
    scans : str or Path, optional
        Render cache, shareable by the runs of one experiment; default ``out/scans``.
    init : str or Path, optional
        A finished ``supervised`` run of the same category, split and network size.
        ``semi``: its weights replace the supervised stage (which it would reproduce).
        ``semi-weakly``: used only when no pseudo-labelled scan fits the structure; this run
        then trains on exactly the supervised run's scans, so it must also have the same
        training configuration, and its weights and ``metrics.csv`` are taken instead of
        training them again (``data.json``: ``weights_of``).
    progress : bool
        Rich progress bars.
    console : rich.console.Console, optional
        Receives one-line status messages.
    structure : KinematicStructure, optional
        Train on the objects with this structure (one model per structure of a category with
        several, :func:`kinmo.ancsh.structure.structure_groups`); default the category's most
        common one.

    Returns
    -------
    TrainResult

    Raises
    ------
    KinmoError
        Unknown category, no structure, no training object, missing ``pseudo`` / ``partnet``
        folder, nothing rendered, ``init`` with the ``supervised`` setting or not matching
        this run.
    KinmoDataError
        Unreadable split or data.
    ValueError
        Unknown setting.
    """
    from kinmo.ancsh.semi import records_csv, semi_pseudo_targets

    if setting not in SETTINGS:
        raise ValueError(f"unknown setting {setting!r} (choose from {', '.join(SETTINGS)})")
    if data is None:
        raise KinmoError("no PartNet-Mobility dataset folder given (--data)")
    t_start = time.perf_counter()
    data = Path(data)
    out = Path(out)
    dist_info, _ = distributed.setup(resolve_device((config or preset("quick")).device))
    main = dist_info.is_main  # torchrun: rank 0 writes the run folder
    cat = scan_category(data, category, structure)
    if cat.structure is None:
        raise KinmoError(f"{data}: no object of category {cat.category} can be expressed by ANCSH")
    structure = cat.structure
    cfg = (config or preset("quick")).model_copy(update={"category": cat.category, "setting": setting})
    cfg = ANCSHConfig.model_validate(cfg.model_dump())
    if init is not None and setting == "supervised":
        raise KinmoError("--init only applies to the semi and semi-weakly settings (a supervised run)")
    if setting == "semi-weakly" and pseudo is None:
        raise KinmoError("the semi-weakly setting needs the pseudo-labelled shapes of `kinmo pseudo-label` (--pseudo)")
    if setting == "semi":
        partnet = Path(partnet) if partnet is not None else data.parent / "partnet"
        if not partnet.is_dir():
            raise KinmoError(f"{partnet}: PartNet folder of the unlabelled shapes is missing (--partnet)")

    out.mkdir(parents=True, exist_ok=True)
    scans_dir = Path(scans) if scans is not None else out / "scans"
    # split
    if split is not None:
        sp = Split.load(split)
    else:
        ids, cats = all_categories(data)
        sp = make_split(ids, cats, cfg.test_fraction, cfg.seed)
    if main:
        sp.save(out / "split.json")
    test_ids = set(sp.test)
    train_fit = [i for i in cat.fitting if i in set(sp.train)]
    left_out = {i: cat.describe(i) for i in sorted(cat.folders) if i not in cat.fitting}
    labeled_ids = _labeled_subset(train_fit, cfg.labeled_fraction, cfg.seed)
    if not labeled_ids:
        raise KinmoError(
            f"category {cat.category}: no training object fits its structure {structure.signature()} "
            f"(fitting: {cat.fitting}, test: {sorted(test_ids & set(cat.fitting))})")
    if main:
        write_json(out / "config.json", cfg.model_dump(mode="json"))
    _say(console, f"{cat.category}: structure {structure.signature()}, {len(labeled_ids)} labelled "
                  f"training objects {labeled_ids}, test objects held out "
                  f"{sorted(test_ids & set(cat.folders))}")

    # labelled scans
    with distributed.main_first():  # torchrun: rank 0 renders, the others then read
        files, failed = render_objects({i: cat.folders[i] for i in labeled_ids}, out / "objects" / "labeled",
                                       scans_dir / "labeled", cfg.frames_per_object, cfg, progress)
    samples, skipped = load_samples(files, {i: cat.parts[i] for i in labeled_ids}, structure,
                                    cfg.theta, cfg.cache_points, cfg.seed)
    info: dict[str, Any] = {
        "category": cat.category, "setting": setting, "structure": structure.signature(),
        "data": str(data.resolve()), "scans": str(scans_dir.resolve()),
        "labeled_objects": labeled_ids, "labeled_scans": len(samples),
        "test_objects": sorted(test_ids & set(cat.folders)),
        "objects_left_out": left_out, "render_failed": dict(failed), "skipped_scans": list(skipped),
        "pseudo_labeled_objects": [], "pseudo_labeled_scans": 0,
        "unlabeled_objects": [], "unlabeled_scans": 0, "pseudo_target_scans": 0,
    }

    # semi-weakly: pseudo-labelled PartNet shapes, rendered at random articulations
    if setting == "semi-weakly":
        proot = Path(pseudo)  # type: ignore[arg-type]
        if not proot.is_dir():
            raise KinmoError(f"{proot}: folder of pseudo-labelled shapes is missing (--pseudo)")
        pfolders = {k: f for k, f in category_folders(proot, cat.category).items()
                    if (f / "mobility_v2.json").is_file()}
        pparts: dict[str, ObjectParts | None] = {}
        ignored: dict[str, str] = {}
        for k, f in sorted(pfolders.items()):
            if k in test_ids:
                ignored[k] = "is a test object"
                continue
            try:
                p = object_parts_of(f)[1]
            except KinmoDataError as e:
                ignored[k] = f"unreadable: {e}"
                continue
            if p is None or p.structure != structure:
                ignored[k] = (f"structure {p.structure.signature() if p else 'not expressible'}, "
                              f"not {structure.signature()}")
                continue
            pparts[k] = p
        info["pseudo_labeled_found"] = len(pfolders)
        info["pseudo_labeled_ignored"] = ignored
        with distributed.main_first():
            pfiles, pfailed = render_objects({k: pfolders[k] for k in pparts}, out / "objects" / "pseudo-labeled",
                                             scans_dir / "pseudo-labeled", cfg.frames_per_object, cfg, progress)
        psamples, pskipped = load_samples(pfiles, pparts, structure, cfg.theta, cfg.cache_points, cfg.seed)
        for s in psamples:
            s.kind = "pseudo-labeled"
        samples += psamples
        info["pseudo_labeled_objects"] = sorted(pparts)
        info["pseudo_labeled_scans"] = len(psamples)
        info["render_failed"].update(pfailed)
        info["skipped_scans"] += pskipped
        _say(console, f"semi-weakly: {len(pparts)} of {len(pfolders)} pseudo-labelled {cat.category} shapes "
                      f"fit the structure, {len(psamples)} scans")
    if not samples:
        raise KinmoError(f"category {cat.category}: no usable training scan was rendered ({failed})")

    # generated objects of the structure (cfg.synth_objects): mixed into the batches or
    # pretrained on, at the same number of steps (kinmo.ancsh.generated)
    generated = GeneratedData([], [], skipped="synth_objects is 0")
    if cfg.synth_objects > 0:
        with distributed.main_first():
            generated = generated_samples(cat.category, structure, cfg, scans_dir, progress)
        info["render_failed"].update(generated.failed)
        info["skipped_scans"] += generated.skipped_scans
        _say(console, f"{cat.category}: {len(generated.objects)} generated objects, {len(generated.samples)} "
                      f"scans ({cfg.synth_as})" if generated.samples
                      else f"{cat.category}: no generated objects: {generated.skipped}")
    info.update(generated.info())
    # semi-weakly without a pseudo-labelled scan trains on exactly the supervised run's scans
    # (labelled and generated), with the same seeds: given that run (init), its weights are
    # this run's; with pseudo-labelled scans init is not used
    reuse = setting == "semi-weakly" and init is not None and not info["pseudo_labeled_scans"]
    if setting == "semi-weakly" and not reuse:
        init = None
    pre = pretrain_epochs(cfg) if generated.samples and cfg.synth_as == "pretrain" else 0
    mixing = bool(generated.samples) and cfg.synth_as == "mix"
    real = samples
    if mixing:
        samples = mix(real, generated.samples, cfg.synth_share)

    # model and training
    with training_session(cfg.device, cfg.seed, cfg.threads) as (_, device):
        model = build_model(cfg, structure).to(device)
        history: list[dict[str, Any]] = []

        def on_epoch(row: dict[str, Any]) -> None:
            history.append(row)
            if main:
                write_text(out / "metrics.csv", metrics_csv(history))
                save_checkpoint(out / "model.pt", model, cfg, structure, len(history))

        ds = ANCSHFrames(samples, cfg.n_points, cfg.seed, cfg.jitter)
        if reuse:
            model.load_state_dict(_init_weights(init, cfg, structure, labeled_ids, same_training=True))
            history.extend(_metric_rows(Path(init) / "metrics.csv"))
            if main:
                write_text(out / "metrics.csv", metrics_csv(history))
                save_checkpoint(out / "model.pt", model, cfg, structure, len(history))
            info["weights_of"] = str(Path(init).resolve())
            _say(console, f"semi-weakly: no pseudo-labelled scan fits {structure.signature()}, so the "
                          f"supervised run's training: its weights ({init})")
        elif init is not None:
            model.load_state_dict(_init_weights(init, cfg, structure, labeled_ids))
            info["init"] = str(Path(init).resolve())
            _say(console, f"supervised stage: weights of {init}")
        else:
            if pre:
                fit(model, ANCSHFrames(generated.samples, cfg.n_points, cfg.seed, cfg.jitter), cfg, pre, device,
                    "pretrain", 2, on_epoch, progress)
            fit(model, ds, cfg, cfg.epochs - pre, device, "train", 0, on_epoch, progress)

        if setting == "semi":
            with distributed.main_first():
                psamples, records = semi_pseudo_targets(model, cat, structure, Path(partnet), test_ids,
                                                         out, scans_dir, cfg, device, progress)
            if main:
                write_text(out / "pseudo_targets.csv", records_csv(records))
            info["unlabeled_objects"] = sorted({r["id"] for r in records})
            info["unlabeled_scans"] = len(records)
            info["pseudo_target_scans"] = len(psamples)
            _say(console, f"semi: {len(psamples)} of {len(records)} scans of "
                          f"{len(info['unlabeled_objects'])} unlabelled {cat.category} shapes kept as pseudo-targets")
            both = real + psamples  # generated scans (mix) stay at their share of the draws
            ds = ANCSHFrames(mix(both, generated.samples, cfg.synth_share) if mixing else both,
                             cfg.n_points, cfg.seed, cfg.jitter)
            fit(model, ds, cfg, cfg.semi_epochs, device, "semi", 1, on_epoch, progress)
    info["seconds"] = round(time.perf_counter() - t_start, 2)
    info["training_scans"] = len(real) + len(generated.samples) + info["pseudo_target_scans"]
    if main:
        write_json(out / "data.json", info)
    return TrainResult(out, cfg, structure, history, info, info["seconds"])


#: Configuration fields that do not change what a run trains (a reused run may differ in them).
_NOT_TRAINING = frozenset({"setting", "render_workers", "device"})


def _metric_rows(path: Path) -> list[dict[str, Any]]:
    """The rows of a run's ``metrics.csv`` with numbers as numbers (``nan`` as NaN)."""
    import csv

    def value(k: str, v: str) -> Any:
        if k == "stage":
            return v
        return int(v) if k in ("epoch", "scans") else float(v)

    try:
        with open(path, newline="") as f:
            return [{k: value(k, v) for k, v in row.items()} for row in csv.DictReader(f)]
    except (OSError, ValueError) as e:
        raise KinmoDataError(f"{path}: unreadable metrics ({e})") from e


def _init_weights(init: str | Path, cfg: ANCSHConfig, structure: KinematicStructure,
                  labeled_ids: list[str], same_training: bool = False) -> dict[str, torch.Tensor]:
    """The state dict of a supervised run that matches this run (else a clear error); with
    ``same_training`` its whole training configuration must be this run's (fields outside
    :data:`_NOT_TRAINING`)."""
    import json

    run = load_run(init, device="cpu")
    same = (tuple(k for k in type(cfg).model_fields if k not in _NOT_TRAINING) if same_training
            else ("category", "width", "n_centers", "radii", "n_points", "theta"))
    bad = [k for k in same if getattr(run.config, k) != getattr(cfg, k)]
    if run.setting != "supervised" or run.structure != structure or bad:
        raise KinmoError(f"{init}: not a supervised run of {cfg.category} with this network "
                         f"(setting {run.setting}, differing: {bad or 'structure'})")
    info = run.path / "data.json"
    used = json.loads(info.read_text()).get("labeled_objects", []) if info.is_file() else []
    if sorted(used) != sorted(labeled_ids):
        raise KinmoError(f"{init}: trained on objects {sorted(used)}, this run labels {sorted(labeled_ids)} "
                         "(another split or labelled fraction)")
    return run.model.state_dict()
