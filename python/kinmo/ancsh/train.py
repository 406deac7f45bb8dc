"""Training of ANCSH on rendered partial scans of one category (``kinmo train ancsh``).

Liu et al. CVPR 2023, Sec. 3.4 and 4.3 (Table 2). :func:`train_ancsh` runs one of the three
settings of :data:`kinmo.ancsh.config.SETTINGS` for a category:

1. the category's PartNet-Mobility objects under ``data`` are mapped onto the category's
   kinematic structure (:func:`kinmo.ancsh.dataset.scan_category`); objects with another
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
5. ANCSH (:class:`kinmo.ancsh.model.ANCSH`) is trained for ``epochs x steps_per_epoch``
   batches;
6. ``semi``: the PartNet shapes of the category are rendered at rest
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

import csv
import io
import math
import time
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch

from kinmo.ancsh.config import ANCSHConfig
from kinmo.ancsh.dataset import (
    ANCSHFrames,
    CategoryObjects,
    FrameSample,
    category_key,
    load_samples,
    normalize_points,
    object_parts_of,
    scan_category,
    subsample_indices,
)
from kinmo.ancsh.model import ANCSH, ancsh_loss
from kinmo.ancsh.structure import KinematicStructure, ObjectParts
from kinmo.errors import KinmoDataError, KinmoError
from kinmo.io import atomic_path, read_checkpoint, write_json, write_text
from kinmo.train import distributed

__all__ = [
    "METRIC_COLUMNS",
    "ANCSHRun",
    "TrainResult",
    "load_run",
    "predict_scans",
    "quiet_estimate",
    "render_objects",
    "save_checkpoint",
    "train_ancsh",
]

METRIC_COLUMNS: tuple[str, ...] = (
    "stage", "epoch", "lr", "loss", "loss_seg", "loss_npcs", "loss_naocs", "loss_heatmap",
    "loss_unitvec", "loss_axis", "loss_joint_cls", "seg_acc", "scans", "seconds",
)
_TERMS = ("seg", "npcs", "naocs", "heatmap", "unitvec", "axis", "joint_cls")
CHECKPOINT_FORMAT = "kinmo-ancsh"


# ------------------------------------------------------------------------------ run I/O


@dataclass
class ANCSHRun:
    """A trained ANCSH model loaded from a run folder.

    Attributes
    ----------
    model : ANCSH
        In eval mode, on ``device``.
    config : ANCSHConfig
    structure : KinematicStructure
    device : torch.device
    path : Path
        The run folder.
    """

    model: ANCSH
    config: ANCSHConfig
    structure: KinematicStructure
    device: torch.device
    path: Path

    @property
    def category(self) -> str:
        return self.config.category

    @property
    def setting(self) -> str:
        return self.config.setting


def _build_model(config: ANCSHConfig, structure: KinematicStructure) -> ANCSH:
    return ANCSH(structure.n_parts, structure.n_joints, config.width, tuple(config.n_centers),
                 tuple(config.radii))


def save_checkpoint(path: str | Path, model: ANCSH, config: ANCSHConfig, structure: KinematicStructure,
                    epoch: int) -> None:
    """Write ``model.pt`` atomically: state dict, config, structure, epoch."""
    payload = {
        "format": CHECKPOINT_FORMAT,
        "version": 1,
        "state_dict": {k: v.detach().cpu() for k, v in model.state_dict().items()},
        "config": config.model_dump(mode="json"),
        "structure": {"parents": list(structure.parents), "joint_types": list(structure.joint_types)},
        "epoch": int(epoch),
    }
    with atomic_path(path) as tmp:
        torch.save(payload, tmp)


def load_run(run: str | Path, device: str = "auto") -> ANCSHRun:
    """Load a trained ANCSH from a run folder (or its ``model.pt``).

    Parameters
    ----------
    run : str or Path
    device : str
        ``"auto"``, ``"cpu"``, ``"cuda"`` ...

    Returns
    -------
    ANCSHRun

    Raises
    ------
    KinmoDataError
        Missing or unreadable checkpoint, or not a kinmo ANCSH checkpoint.
    """
    from kinmo.train.config import resolve_device

    run = Path(run)
    ckpt = run / "model.pt" if run.is_dir() else run
    if not ckpt.is_file():
        raise KinmoDataError(ckpt, "checkpoint is missing (train with `kinmo train ancsh`)")
    payload = read_checkpoint(ckpt, CHECKPOINT_FORMAT, "ANCSH")
    if payload.get("format") != CHECKPOINT_FORMAT:
        raise KinmoDataError(ckpt, "not a kinmo ANCSH checkpoint")
    try:
        config = ANCSHConfig.model_validate(payload["config"])
        st = payload["structure"]
        structure = KinematicStructure(tuple(st["parents"]), tuple(st["joint_types"]))
        model = _build_model(config, structure)
        model.load_state_dict(payload["state_dict"])
    except Exception as e:
        raise KinmoDataError(ckpt, f"checkpoint does not match the model: {e}") from None
    dev = resolve_device(device)
    model.to(dev).eval()
    return ANCSHRun(model, config, structure, dev, ckpt.parent)


@torch.no_grad()
def predict_scans(
    model: ANCSH,
    scans: Sequence[np.ndarray],
    n_points: int,
    device: torch.device | str = "cpu",
    seeds: Sequence[int] | None = None,
    batch_size: int = 16,
) -> list[tuple[np.ndarray, dict[str, np.ndarray]]]:
    """Run ANCSH on partial scans.

    Each scan is subsampled to ``n_points`` (:func:`kinmo.ancsh.dataset.subsample_indices`,
    generator seeded by ``seeds[i]``) and normalised (:func:`normalize_points`) as in training.

    Parameters
    ----------
    model : ANCSH
    scans : sequence of (M_i, 3) float
        Camera-frame points.
    n_points : int
    device : torch.device or str
    seeds : sequence of int, optional
        Per scan (default ``0, 1, ...``).
    batch_size : int

    Returns
    -------
    list of (points, pred)
        ``points`` (n_points, 3) float64: the camera-frame points the network saw; ``pred``:
        numpy arrays of :class:`~kinmo.ancsh.model.ANCSH` output without the batch dimension
        (the input of :func:`kinmo.ancsh.postprocess.estimate`).
    """
    was_training = model.training
    model.eval()
    seeds = list(range(len(scans))) if seeds is None else list(seeds)
    out: list[tuple[np.ndarray, dict[str, np.ndarray]]] = []
    try:
        for b0 in range(0, len(scans), batch_size):
            pts, xyz = [], []
            for s, seed in zip(scans[b0:b0 + batch_size], seeds[b0:b0 + batch_size]):
                s = np.asarray(s, dtype=np.float64)
                p = s[subsample_indices(len(s), n_points, np.random.default_rng(seed))]
                pts.append(p)
                xyz.append(normalize_points(p)[0])
            pred = model(torch.from_numpy(np.stack(xyz)).to(device))
            pred = {k: v.detach().cpu().numpy() for k, v in pred.items()}
            for i, p in enumerate(pts):
                out.append((p, {k: v[i] for k, v in pred.items()}))
    finally:
        model.train(was_training)
    return out


def quiet_estimate(points: np.ndarray, pred: dict[str, np.ndarray], structure: KinematicStructure,
                   **kwargs: Any) -> Any:
    """:func:`kinmo.ancsh.postprocess.estimate` without numpy / scipy overflow warnings
    (expected for the wild predictions of an undertrained network)."""
    import warnings

    from kinmo.ancsh.postprocess import estimate

    with warnings.catch_warnings(), np.errstate(all="ignore"):
        warnings.simplefilter("ignore", RuntimeWarning)
        return estimate(points, pred, structure, **kwargs)


# ----------------------------------------------------------------------------- rendering


def _link_objects(folders: dict[str, Path], objects_dir: Path) -> None:
    """``objects_dir/<key>`` -> folder symbolic links, exactly ``folders``."""
    objects_dir.mkdir(parents=True, exist_ok=True)
    for p in objects_dir.iterdir():
        if p.is_symlink() and p.name not in folders:
            p.unlink()
    for key, f in folders.items():
        link = objects_dir / key
        target = Path(f).resolve()
        if link.is_symlink():
            if link.resolve() == target:
                continue
            link.unlink()
        elif link.exists():
            continue  # a real folder (e.g. a wrapper written there): render it as is
        link.symlink_to(target, target_is_directory=True)


def render_objects(
    folders: dict[str, Path],
    objects_dir: str | Path,
    scans_dir: str | Path,
    frames: int,
    config: ANCSHConfig,
    progress: bool = True,
    seed_offset: int = 0,
) -> tuple[list[Path], dict[str, str]]:
    """Render ``frames`` partial scans of each object (resuming up-to-date frames).

    Parameters
    ----------
    folders : dict of str to Path
        Object key -> PartNet-Mobility-format folder.
    objects_dir : str or Path
        Folder of symbolic links to the objects (the render root).
    scans_dir : str or Path
        Output of :func:`kinmo.render.dataset.render_dataset` (``<key>/<frame>.npz``).
    frames : int
    config : ANCSHConfig
        ``image_size``, ``seed``, ``render_workers``.
    progress : bool
    seed_offset : int
        Added to ``config.seed`` for the render seed.

    Returns
    -------
    files : list of Path
        The frames rendered or up to date, sorted.
    failed : dict of str to str
        Object key -> reason for objects that failed.
    """
    from kinmo.render.dataset import RenderConfig, render_dataset

    objects_dir, scans_dir = Path(objects_dir), Path(scans_dir)
    if not folders:
        return [], {}
    _link_objects(folders, objects_dir)
    rc = RenderConfig(width=config.image_size, height=config.image_size, seed=config.seed + seed_offset)
    res = render_dataset(objects_dir, scans_dir, frames, rc, workers=config.render_workers,
                         progress=progress)
    files: list[Path] = []
    failed: dict[str, str] = {}
    for r in res.rows:
        if r.id not in folders:
            continue
        if r.status in ("ok", "skipped"):
            files.append(scans_dir / r.file)
        else:
            failed.setdefault(r.id, r.error)
    return sorted(files), failed


# ---------------------------------------------------------------------------- training


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


def _metrics_csv(rows: list[dict[str, Any]]) -> str:
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=list(METRIC_COLUMNS), lineterminator="\n")
    w.writeheader()
    for r in rows:
        w.writerow({k: r.get(k, "") for k in METRIC_COLUMNS})
    return buf.getvalue()


def _lr_at(config: ANCSHConfig, step: int, total: int, epoch: int) -> float:
    if config.schedule == "cosine":
        return config.lr * 0.5 * (1.0 + math.cos(math.pi * step / max(1, total)))
    if config.schedule == "step":
        return config.lr * config.step_gamma ** (epoch // config.step_size)
    return config.lr


class _Progress:
    """A rich progress bar over optimisation steps (no-op when disabled)."""

    def __init__(self, enabled: bool) -> None:
        self.enabled = enabled
        self._p: Any = None

    def __enter__(self) -> _Progress:
        if self.enabled:
            from rich.console import Console
            from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn, TimeRemainingColumn

            self._p = Progress(TextColumn("[bold]ancsh[/] {task.description}"), BarColumn(),
                               MofNCompleteColumn(), TextColumn("loss {task.fields[loss]}"),
                               TimeElapsedColumn(), TimeRemainingColumn(), console=Console(stderr=True))
            self._p.__enter__()
        return self

    def task(self, label: str, total: int) -> Any:
        return None if self._p is None else self._p.add_task(label, total=total, loss="-")

    def advance(self, task: Any, loss: float) -> None:
        if self._p is not None:
            self._p.update(task, advance=1, loss=f"{loss:.3f}")

    def __exit__(self, *exc: Any) -> None:
        if self._p is not None:
            self._p.__exit__(*exc)


def fit(
    model: ANCSH,
    dataset: ANCSHFrames,
    config: ANCSHConfig,
    epochs: int,
    device: torch.device,
    stage: str = "train",
    stage_index: int = 0,
    on_epoch: Callable[[dict[str, Any]], None] | None = None,
    progress: bool = True,
) -> list[dict[str, Any]]:
    """Train ``model`` on ``dataset`` for ``epochs`` epochs (Adam, ``config`` schedule).

    Parameters
    ----------
    model : ANCSH
        Trained in place (on ``device``).
    dataset : ANCSHFrames
    config : ANCSHConfig
        ``steps_per_epoch``, ``batch_size``, ``lr``, ``weight_decay``, ``schedule``,
        ``grad_clip``, ``seed``.
    epochs : int
    device : torch.device
    stage : str
        Label of the rows (``"train"``, ``"semi"``).
    stage_index : int
        Seeds the batch order of this stage (``[seed, stage_index]``).
    on_epoch : callable, optional
        Called with each epoch's metrics row.
    progress : bool

    Returns
    -------
    list of dict
        One row per epoch (:data:`METRIC_COLUMNS`).
    """
    with _torch_threads(config.threads):
        return _fit(model, dataset, config, epochs, device, stage, stage_index, on_epoch, progress)


@contextmanager
def _torch_threads(n: int) -> Iterator[None]:
    """torch's CPU threads set to ``n`` (0: unchanged) for the duration."""
    old = torch.get_num_threads()
    if n > 0:
        torch.set_num_threads(n)
    try:
        yield
    finally:
        torch.set_num_threads(old)


def _fit(model: ANCSH, dataset: ANCSHFrames, config: ANCSHConfig, epochs: int, device: torch.device,
         stage: str, stage_index: int, on_epoch: Callable[[dict[str, Any]], None] | None,
         progress: bool) -> list[dict[str, Any]]:
    from torch.utils.data import default_collate

    steps = config.steps_per_epoch or max(1, math.ceil(len(dataset) / config.batch_size))
    total = steps * epochs
    opt = torch.optim.Adam(model.parameters(), lr=config.lr, weight_decay=config.weight_decay)
    rng = np.random.default_rng([config.seed, stage_index])
    order: list[int] = []
    rows: list[dict[str, Any]] = []
    step = 0
    model.to(device)
    ddp = distributed.wrap(model)  # torchrun: DistributedDataParallel (kinmo.train.distributed)
    dist_info = distributed.info()
    with _Progress(progress and dist_info.is_main) as bar:
        task = bar.task(f"{config.category} {config.setting} [{stage}]", total)
        for epoch in range(epochs):
            model.train()
            t0 = time.perf_counter()
            sums = dict.fromkeys(("total", *_TERMS), 0.0)
            correct = seen = 0
            lr = config.lr
            for _ in range(steps):
                idx = []
                while len(idx) < config.batch_size:
                    if not order:
                        order = [int(i) for i in rng.permutation(len(dataset))]
                    idx.append(order.pop())
                lr = _lr_at(config, step, total, epoch)
                for g in opt.param_groups:
                    g["lr"] = lr
                # every rank draws the whole global batch (same random stream), keeps its shard
                items, weight = distributed.shard([dataset.sample(i, rng) for i in idx])
                batch = default_collate(items)
                batch = {k: v.to(device) for k, v in batch.items()}
                pred = ddp(batch["xyz"])
                terms = ancsh_loss(pred, batch)
                opt.zero_grad(set_to_none=True)
                (terms["total"] * weight).backward()
                if config.grad_clip > 0:
                    torch.nn.utils.clip_grad_norm_(model.parameters(), config.grad_clip)
                opt.step()
                step += 1
                share = weight / dist_info.world_size  # this rank's share of the global batch
                for k in sums:
                    sums[k] += share * float(terms[k].detach())
                if weight > 0:
                    with torch.no_grad():
                        correct += int((pred["seg_logits"].argmax(-1) == batch["seg"]).sum())
                        seen += batch["seg"].numel()
                bar.advance(task, float(terms["total"].detach()))
            if dist_info.enabled:  # the epoch's figures over all ranks
                *totals, correct, seen = distributed.all_sum([*sums.values(), correct, seen])
                sums = dict(zip(sums, totals))
            row = {"stage": stage, "epoch": epoch + 1, "lr": round(lr, 8),
                   "loss": round(sums["total"] / steps, 6),
                   **{f"loss_{k}": round(sums[k] / steps, 6) for k in _TERMS},
                   "seg_acc": round(correct / max(1, seen), 6), "scans": len(dataset),
                   "seconds": round(time.perf_counter() - t0, 3)}
            rows.append(row)
            if on_epoch is not None:
                on_epoch(row)
    return rows


def _all_categories(root: Path) -> tuple[list[str], list[str]]:
    """Ids and categories of every PartNet-Mobility object under ``root``."""
    from kinmo.data.readers import find_shapes, read_meta

    ids, cats = [], []
    for f in find_shapes(root):
        if not (f / "mobility_v2.json").is_file():
            continue
        try:
            cats.append(read_meta(f)[0])
        except KinmoDataError:
            cats.append("unknown")
        ids.append(f.name)
    return ids, cats


def _category_folders(root: Path, category: str) -> dict[str, Path]:
    """Shape folders of ``category`` under ``root`` (either format), by folder name."""
    from kinmo.data.readers import find_shapes, read_meta

    out: dict[str, Path] = {}
    for f in find_shapes(root):
        try:
            cat = read_meta(f)[0]
        except KinmoDataError:
            continue
        if category_key(cat) == category_key(category):
            out[f.name] = f
    return out


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
        ``semi``: a finished ``supervised`` run of the same category, split and network size
        whose weights replace the supervised stage (which it would reproduce).
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
        folder, nothing rendered.
    KinmoDataError
        Unreadable split or data.
    ValueError
        Unknown setting.
    """
    from kinmo.ancsh.config import SETTINGS, preset
    from kinmo.train.config import resolve_device
    from kinmo.train.split import Split, make_split

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
    if init is not None and setting != "semi":
        raise KinmoError("--init only applies to the semi setting (its supervised stage)")
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
        ids, cats = _all_categories(data)
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
        pfolders = {k: f for k, f in _category_folders(proot, cat.category).items()
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

    # model and training
    _, device = distributed.setup(resolve_device(cfg.device))
    with _torch_threads(cfg.threads):
        torch.manual_seed(cfg.seed)
        model = _build_model(cfg, structure).to(device)
        history: list[dict[str, Any]] = []

        def on_epoch(row: dict[str, Any]) -> None:
            history.append(row)
            if main:
                write_text(out / "metrics.csv", _metrics_csv(history))
                save_checkpoint(out / "model.pt", model, cfg, structure, len(history))

        ds = ANCSHFrames(samples, cfg.n_points, cfg.seed, cfg.jitter)
        if init is not None:
            model.load_state_dict(_init_weights(init, cfg, structure, labeled_ids))
            info["init"] = str(Path(init).resolve())
            _say(console, f"supervised stage: weights of {init}")
        else:
            fit(model, ds, cfg, cfg.epochs, device, "train", 0, on_epoch, progress)

        if setting == "semi":
            with distributed.main_first():
                psamples, records = _semi_pseudo_targets(model, cat, structure, Path(partnet), test_ids,
                                                         out, scans_dir, cfg, device, progress)
            if main:
                write_text(out / "pseudo_targets.csv", _records_csv(records))
            info["unlabeled_objects"] = sorted({r["id"] for r in records})
            info["unlabeled_scans"] = len(records)
            info["pseudo_target_scans"] = len(psamples)
            _say(console, f"semi: {len(psamples)} of {len(records)} scans of "
                          f"{len(info['unlabeled_objects'])} unlabelled {cat.category} shapes kept as pseudo-targets")
            ds = ANCSHFrames(samples + psamples, cfg.n_points, cfg.seed, cfg.jitter)
            fit(model, ds, cfg, cfg.semi_epochs, device, "semi", 1, on_epoch, progress)
    info["seconds"] = round(time.perf_counter() - t_start, 2)
    info["training_scans"] = len(samples) + info["pseudo_target_scans"]
    if main:
        write_json(out / "data.json", info)
    return TrainResult(out, cfg, structure, history, info, info["seconds"])


def _init_weights(init: str | Path, cfg: ANCSHConfig, structure: KinematicStructure,
                  labeled_ids: list[str]) -> dict[str, torch.Tensor]:
    """The state dict of a supervised run that matches this run (else a clear error)."""
    import json

    run = load_run(init, device="cpu")
    same = ("category", "width", "n_centers", "radii", "n_points", "theta")
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


_RECORD_COLUMNS = ("id", "frame", "n_points", "seg_confidence", "inlier_ratio", "parts_seen", "in_cube", "kept")


def _records_csv(records: list[dict[str, Any]]) -> str:
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=list(_RECORD_COLUMNS), lineterminator="\n", extrasaction="ignore")
    w.writeheader()
    for r in records:
        w.writerow(r)
    return buf.getvalue()


def _semi_pseudo_targets(
    model: ANCSH, cat: CategoryObjects, structure: KinematicStructure, partnet: Path, test_ids: set[str],
    out: Path, scans_dir: Path, cfg: ANCSHConfig, device: torch.device, progress: bool,
) -> tuple[list[FrameSample], list[dict[str, Any]]]:
    """Render the category's PartNet shapes at rest, label them with ``model``, keep the
    confident scans (:mod:`kinmo.ancsh.semi`)."""
    from kinmo.ancsh.semi import MIN_IN_CUBE, pseudo_sample, scan_confidence, unlabeled_object
    from kinmo.render.dataset import load_frame

    shapes = {k: f for k, f in _category_folders(partnet, cat.category).items()
              if (f / "objs").is_dir() and k not in test_ids}
    wrappers: dict[str, Path] = {}
    for k, f in sorted(shapes.items()):
        try:
            wrappers[k] = unlabeled_object(f, out / "objects" / "unlabeled" / k)
        except KinmoDataError:
            continue
    files, _ = render_objects(wrappers, out / "objects" / "unlabeled", scans_dir / "unlabeled",
                              cfg.unlabeled_frames_per_object, cfg, progress)
    frames = [load_frame(f) for f in files]
    frames = [fr for fr in frames if len(fr["points"]) >= 32]
    seeds = [int(fr["meta"]["frame"]) + 1000 * i for i, fr in enumerate(frames)]
    preds = predict_scans(model, [fr["points"] for fr in frames], cfg.n_points, device, seeds)
    kept: list[FrameSample] = []
    records: list[dict[str, Any]] = []
    candidates: list[tuple[float, int, np.ndarray, dict[str, np.ndarray], Any]] = []
    for fr, (pts, pred) in zip(frames, preds):
        key, index = str(fr["meta"]["key"]), int(fr["meta"]["frame"])
        rec: dict[str, Any] = {"id": key, "frame": index, "n_points": len(fr["points"])}
        try:
            est = quiet_estimate(pts, pred, structure, theta=cfg.theta, seed=cfg.seed)
        except (ValueError, np.linalg.LinAlgError):
            rec.update(seg_confidence="", inlier_ratio="", parts_seen=0, kept=False)
            records.append(rec)
            continue
        conf = scan_confidence(pts, pred, est)
        ok = (conf["seg_confidence"] >= cfg.min_seg_confidence and conf["inlier_ratio"] >= cfg.min_inlier_ratio
              and conf["parts_seen"] >= 2 and conf["in_cube"] >= MIN_IN_CUBE)
        rec.update(seg_confidence=round(conf["seg_confidence"], 4), inlier_ratio=round(conf["inlier_ratio"], 4),
                   parts_seen=conf["parts_seen"], in_cube=round(conf["in_cube"], 4), kept=False)
        records.append(rec)
        if ok:
            candidates.append((conf["inlier_ratio"], len(records) - 1, pts, pred, est))
    # the most consistent share of the confident scans (ties: scan order)
    candidates.sort(key=lambda c: (-c[0], c[1]))
    n_keep = int(math.ceil(cfg.pseudo_keep_fraction * len(candidates)))
    for _, i, pts, pred, est in sorted(candidates[:n_keep], key=lambda c: c[1]):
        records[i]["kept"] = True
        kept.append(pseudo_sample(str(records[i]["id"]), int(records[i]["frame"]), pts, pred, est, structure,
                                  cfg.theta))
    return kept, records
