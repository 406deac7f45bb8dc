"""Table 2 of Liu et al. CVPR 2023: ANCSH on partial scans of held-out objects (``kinmo eval``).

For one category, :func:`evaluate_category` renders (or reuses) scans of the test objects of
the runs' split (:mod:`kinmo.ancsh.train`; models loaded by :mod:`kinmo.ancsh.inference`), runs every trained model (one row per setting:
``supervised``, ``semi``, ``semi-weakly``), post-processes each prediction
(:func:`kinmo.ancsh.postprocess.estimate`) and compares it with the rendered ground truth
(:func:`frame_truth`). Per frame (:func:`frame_errors`):

- per part ``k`` (ANCSH order, part 0 the base): **rotation error** (degrees, geodesic),
  **translation error** (distance between the predicted and true centres of the part's NPCS
  box in the camera frame, mesh units; ANCSH's code compares the images of the NPCS origin,
  which mixes in the rotation error), **3D IoU** of the amodal boxes (predicted box: the
  estimator's, from the NPCS extent of the part's points; true box: the part's full rest box);
- per joint ``j`` (child part ``j + 1``): **joint state error** (degrees for revolute joints,
  mesh units for prismatic ones; the predicted state is negated when the predicted axis
  direction opposes the true one, as an axis and its reverse describe the same line),
  **axis angle error** (degrees in [0, 90], :func:`kinmo.metrics.axis.axis_angle_deg`) and
  **axis distance** (revolute joints: distance between the axis lines,
  :func:`kinmo.metrics.axis.line_distance`, mesh units; prismatic axes have no position).

Parts with a continuous rotational symmetry (a bucket's body, a safe's dial) are evaluated up
to it, as in NOCS and ANCSH (:mod:`kinmo.ancsh.symmetry`): the predicted pose is replaced by
its symmetric equivalent closest to the truth before the part errors are computed
(``symmetric=False`` turns this off).

Interchangeable parts (leaf siblings of one parent with joints of one type, e.g. the two
temples of eyeglasses or two cabinet doors; :mod:`kinmo.ancsh.interchangeable` for the rule and its
limits) are scored a second way: per scan, the predicted parts of each group are assigned to
its true parts by the permutation of least summed rotation error, and the rotation,
translation, axis angle and axis distance errors under that assignment are reported beside
the raw ones (``<metric>_matched_*`` columns of ``table2.csv`` and ``frames.csv``, a second
table in ``table2.md`` and on the console, ``permutation_matched`` in ``eval.json``). The raw
errors stay the Table 2 metric.

Table entries are means over frames; the "mean" columns average the parts (or joints).
Outputs in the evaluation folder: ``table2.csv`` (one row per run), ``table2.md``,
``frames.csv`` (every frame's errors) and ``eval.json`` (test objects, frames, runs).
"""

from __future__ import annotations

import time
import zlib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from kinmo.ancsh.frame_metrics import (
    FrameErrors,
    FrameTruth,
    frame_errors,
    frame_truth,
    ground_truth_estimate,
    ground_truth_predictions,
)
from kinmo.ancsh.inference import load_run, predict_scans, quiet_estimate
from kinmo.ancsh.interchangeable import describe_groups, interchangeable_groups, matched_frame_errors
from kinmo.ancsh.objects import category_key, scan_category
from kinmo.ancsh.scans import render_objects
from kinmo.ancsh.structure import KinematicStructure, structure_slug
from kinmo.ancsh.table2 import (
    MATCHED_METRICS,
    METRICS,
    SETTING_ORDER,
    Table2Row,
    matched_rich_table,
    num,
    paper_table,
    rich_table,
    structures_markdown,
    summarize,
    table2_csv,
    table2_markdown,
)
from kinmo.errors import KinmoDataError, KinmoError
from kinmo.io import write_json, write_text
from kinmo.render.dataset import load_frame
from kinmo.parallel import torch_threads
from kinmo.progress import print_table
from kinmo.train.loop import rows_csv
from kinmo.train.split import Split

#: ``table2.csv`` text (:func:`kinmo.ancsh.table2.table2_csv`; this name is kept for the
#: report's test fixtures).
_table2_csv = table2_csv

__all__ = [
    "FrameErrors",
    "FrameTruth",
    "Table2Row",
    "evaluate_category",
    "find_runs",
    "frame_errors",
    "frame_truth",
    "ground_truth_estimate",
    "ground_truth_predictions",
    "paper_table",
    "rich_table",
    "summarize",
    "table2_markdown",
]


# ------------------------------------------------------------------------------ the runs


def find_runs(paths: Sequence[str | Path], category: str | None = None) -> list[Path]:
    """ANCSH run folders at or below ``paths`` (two levels), optionally of one category.

    A run folder holds ``model.pt`` and ``config.json`` of ``kinmo train ancsh``. Sorted by
    setting (supervised, semi, semi-weakly), then path.
    """
    import json

    found: list[tuple[int, str, Path]] = []
    seen: set[Path] = set()

    def consider(d: Path) -> bool:
        cfg = d / "config.json"
        if not ((d / "model.pt").is_file() and cfg.is_file()):
            return False
        try:
            c = json.loads(cfg.read_text())
        except (OSError, ValueError):
            return False
        if not isinstance(c, dict) or "setting" not in c or "width" not in c:
            return False  # another model's run
        if category is not None and category_key(c.get("category", "")) != category_key(category):
            return True
        if d.resolve() not in seen:
            seen.add(d.resolve())
            found.append((SETTING_ORDER.get(c["setting"], 9), str(d), d))
        return True

    for p in map(Path, paths):
        if not p.is_dir():
            raise KinmoDataError(p, "run folder does not exist")
        if consider(p):
            continue
        for d in sorted(x for x in p.iterdir() if x.is_dir()):
            if not consider(d):
                for e in sorted(x for x in d.iterdir() if x.is_dir()):
                    consider(e)
    return [d for _, _, d in sorted(found)]


@dataclass
class _StructureEval:
    """The evaluation of the runs of one structure (:func:`_evaluate_structure`)."""

    structure: KinematicStructure
    runs: list[Any]
    rows: list[Table2Row]
    errors: list[list[FrameErrors]]  # per run, per frame
    matched: list[list[FrameErrors]]  # per run, per frame: permutation-matched
    groups: list[tuple[int, ...]]  # interchangeable parts
    frame_lines: list[dict[str, Any]]
    test_ids: list[str]
    n_frames: int
    failed: dict[str, str]
    sym: dict[str, list[np.ndarray | None]]
    notes: list[str]
    refused: list[str]


def _trained_ids(info: Mapping[str, Any]) -> set[str]:
    return set(info.get("labeled_objects", [])) | set(info.get("pseudo_labeled_objects", [])) | set(
        info.get("unlabeled_objects", []))


def _same_folder(a: str | Path | None, b: str | Path | None) -> bool:
    if a is None or b is None:
        return False
    try:
        return Path(a).resolve() == Path(b).resolve()
    except OSError:
        return False


def evaluate_category(
    category: str,
    runs: Sequence[str | Path],
    data: str | Path | None = None,
    out: str | Path | None = None,
    scans: str | Path | None = None,
    frames: int | None = None,
    seed: int = 0,
    device: str = "auto",
    workers: int = 0,
    progress: bool = True,
    console: Any = None,
    symmetric: bool = True,
) -> tuple[list[Table2Row], dict[str, Path]]:
    """Table 2 for one category (module docstring).

    Runs of several kinematic structures (``kinmo train all`` trains one model per structure
    of a category with several, :func:`kinmo.pipeline.ancsh_plan`) are evaluated structure by
    structure, each test object with the model of its structure; the category's row of each
    setting is then the mean over all its test scans of the per-scan mean over parts (joints),
    and ``table2.md`` adds one table per structure.

    Parameters
    ----------
    category : str
        Any spelling (``refrigerator``, ``storage_furniture``).
    runs : sequence of path
        Run folders of ``kinmo train ancsh``, or folders holding them (:func:`find_runs`).
    data : str or Path, optional
        PartNet-Mobility dataset folder; default: the one the first run trained on, whose
        test objects of the runs' split are evaluated. Another folder: every object there that
        fits a run's structure and is not a training object of the runs (of their split, or
        pseudo-labelled / unlabelled shapes they used) is evaluated; the others are left out
        and listed.
    out : str or Path, optional
        Evaluation folder; default ``<first runs path>/eval-<category>``.
    scans : str or Path, optional
        Render cache of the test scans; default ``out/scans``.
    frames : int, optional
        Scans per test object; default the first run's ``test_frames_per_object``.
    seed : int
        Seed of the test renders and point sampling.
    device : str
    workers : int
        Rendering processes (0: one per CPU, 1: in this process).
    progress : bool
    console : rich.console.Console, optional
        When given, the table is printed on it.
    symmetric : bool
        Evaluate parts with a continuous rotational symmetry up to that symmetry
        (:mod:`kinmo.ancsh.symmetry`; which parts are symmetric is listed in ``eval.json``
        and the Markdown notes).

    Returns
    -------
    rows : list of Table2Row
        One per setting (several structures: rows whose per-part arrays hold the one mean).
    paths : dict of str to Path
        ``csv``, ``markdown``, ``frames``, ``json``.

    Raises
    ------
    KinmoError
        No run of the category, two runs of one setting and structure, a test object a run
        trained on, no test object.
    """
    import json

    t0 = time.perf_counter()
    if not runs:
        raise KinmoError("no run folder given (--runs)")
    run_dirs = find_runs(runs, category)
    if not run_dirs:
        raise KinmoError(f"no ANCSH run of category {category!r} under {', '.join(map(str, runs))} "
                         "(train one with `kinmo train ancsh`)")
    loaded = [load_run(d, device) for d in run_dirs]
    infos = []
    for r in loaded:
        p = r.path / "data.json"
        infos.append(json.loads(p.read_text()) if p.is_file() else {})
    own_data = infos[0].get("data")
    if data is None:
        data = own_data
        if not data:
            raise KinmoError(f"{loaded[0].path}: no data.json naming the dataset; give --data")
    data = Path(data)
    foreign = own_data is not None and not _same_folder(data, own_data)
    # the runs of each structure, in order of appearance
    by_structure: dict[KinematicStructure, list[int]] = {}
    for i, r in enumerate(loaded):
        by_structure.setdefault(r.structure, []).append(i)
    for st, idx in by_structure.items():
        settings = [loaded[i].setting for i in idx]
        dup = sorted({x for x in settings if settings.count(x) > 1})
        if dup:
            raise KinmoError(f"several {', '.join(dup)} runs of structure {st.signature()}: "
                             f"{', '.join(str(loaded[i].path) for i in idx if loaded[i].setting in dup)}; "
                             "give --runs")
    cfg0 = loaded[0].config
    frames = frames or cfg0.test_frames_per_object
    out = Path(out) if out is not None else Path(runs[0]) / f"eval-{category_key(category)}"
    out.mkdir(parents=True, exist_ok=True)
    scans_dir = Path(scans) if scans is not None else out / "scans"
    trained = set().union(*(_trained_ids(i) for i in infos))
    multi = len(by_structure) > 1
    evals: list[_StructureEval] = []
    missing: list[str] = []
    refused: list[str] = []
    name = category
    for st, idx in by_structure.items():
        try:
            ev, name = _evaluate_structure(
                category, st, [loaded[i] for i in idx], [infos[i] for i in idx], data, foreign, trained,
                out / structure_slug(st) if multi else out, scans_dir, frames, seed, workers, progress, symmetric)
        except _NoTestObject as e:
            if not multi:
                raise KinmoError(str(e)) from None
            missing.append(str(e))
            refused += e.refused
            continue
        evals.append(ev)
        refused += ev.refused
    if not evals:
        raise KinmoError("; ".join(missing))

    paths = {"csv": out / "table2.csv", "markdown": out / "table2.md", "frames": out / "frames.csv",
             "json": out / "eval.json"}
    frame_lines = [{**ln, **({"structure": e.structure.signature()} if multi else {})}
                   for e in evals for ln in e.frame_lines]
    if not multi:
        e = evals[0]
        rows, structure = e.rows, e.structure
        write_text(paths["csv"], table2_csv(rows, structure.n_parts, structure.n_joints))
        write_text(paths["markdown"], table2_markdown(rows, name, structure, e.notes))
    else:
        rows = _aggregate(evals)
        write_text(paths["csv"], table2_csv(rows, 1, 1))
        write_text(paths["markdown"], structures_markdown(
            rows, name, [(e.structure, e.rows, e.notes, len(e.test_ids)) for e in evals], missing))
    head = ["setting", "run", "id", "frame"]
    cols = head + sorted({k for ln in frame_lines for k in ln} - set(head))
    write_text(paths["frames"], rows_csv(frame_lines, cols, digits=None, nan="nan"))
    test_ids = [i for e in evals for i in e.test_ids]
    sym = {k: v for e in evals for k, v in e.sym.items()}
    matched_json = []
    for e in evals:
        for r in e.rows:
            matched_json.append({
                "structure": e.structure.signature(), "setting": r.setting, "run": r.run, "frames": r.frames,
                "swapped_scans": r.swapped,
                **{f"{n}_mean": _json_num(r.mean(n)) for n in MATCHED_METRICS},
                **{f"{n}_matched_mean": _json_num(r.matched_mean(n)) for n in MATCHED_METRICS},
                **{f"{n}_matched": [_json_num(float(x)) for x in r.matched.get(n, ())] for n in MATCHED_METRICS},
            })
    write_json(paths["json"], {
        "category": name, "structure": "; ".join(e.structure.signature() for e in evals), "data": str(data),
        "structures": {e.structure.signature(): e.test_ids for e in evals},
        "objects": "runs' test split" if not foreign else "every fitting object no run trained on",
        "refused_trained": sorted(refused),
        "test_objects": test_ids, "scans": sum(e.n_frames for e in evals), "frames_per_object": frames,
        "seed": seed, "render_failed": {k: v for e in evals for k, v in e.failed.items()},
        "runs": [str(r.path) for e in evals for r in e.runs], "symmetry_aware": symmetric,
        "symmetric_parts": {i: [None if a is None else [float(x) for x in a] for a in v] for i, v in sym.items()},
        "interchangeable_parts": {e.structure.signature(): [list(g) for g in e.groups] for e in evals},
        "permutation_matched": matched_json,
        "seconds": round(time.perf_counter() - t0, 2),
    })
    if console is not None:
        for e in evals if multi else []:
            print_table(console, rich_table(e.rows, name, e.structure))
            if e.groups:
                print_table(console, matched_rich_table(e.rows, name, e.structure,
                                                        describe_groups(e.groups, e.structure)))
        if multi:
            print_table(console, rich_table(rows, name, None))
            if any(e.groups for e in evals):
                print_table(console, matched_rich_table(rows, name, None, "; ".join(
                    f"{e.structure.signature()}: {describe_groups(e.groups, e.structure)}" for e in evals if e.groups)))
        else:
            print_table(console, rich_table(rows, name, evals[0].structure))
            if evals[0].groups:
                print_table(console, matched_rich_table(rows, name, evals[0].structure,
                                                 describe_groups(evals[0].groups, evals[0].structure)))
    return rows, paths


def _json_num(x: float) -> float | None:
    """A JSON number (None for NaN / infinity)."""
    return float(x) if np.isfinite(x) else None


class _NoTestObject(Exception):
    """No object to evaluate for one structure (``refused``: its objects a run trained on)."""

    def __init__(self, message: str, refused: Sequence[str] = ()) -> None:
        super().__init__(message)
        self.refused = list(refused)


def _aggregate(evals: Sequence[_StructureEval]) -> list[Table2Row]:
    """One row per setting over the scans of every structure: per scan the mean over its parts
    (joints), then the mean over scans (NaNs ignored)."""
    settings = sorted({r.setting for e in evals for r in e.rows}, key=lambda x: SETTING_ORDER.get(x, 9))
    rows = []

    def scan_mean(errs: Sequence[FrameErrors], n: str) -> np.ndarray:
        per = np.array([np.nanmean(v) if np.isfinite(v := np.asarray(getattr(fe, n), float)).any() else np.nan
                        for fe in errs])
        return np.array([np.nanmean(per) if np.isfinite(per).any() else np.nan])

    for setting in settings:
        errs = [fe for e in evals for r, fes in zip(e.rows, e.errors) if r.setting == setting for fe in fes]
        matched = [fe for e in evals for r, fes in zip(e.rows, e.matched) if r.setting == setting for fe in fes]
        vals = {n: scan_mean(errs, n) for n in METRICS}
        training: dict[str, Any] = {}
        for e in evals:
            for r in e.rows:
                if r.setting == setting:
                    for k, v in r.training.items():
                        training[k] = training.get(k, 0) + v
        rows.append(Table2Row(setting, ", ".join(r.run for e in evals for r in e.rows if r.setting == setting),
                              len(errs), *(vals[n] for n in METRICS), ("mean",), training,
                              {n: scan_mean(matched, n) for n in MATCHED_METRICS},
                              sum(r.swapped for e in evals for r in e.rows if r.setting == setting)))
    return rows


def _evaluate_structure(
    category: str, structure: KinematicStructure, loaded: list[Any], infos: list[dict[str, Any]], data: Path,
    foreign: bool, trained: set[str], out: Path, scans_dir: Path, frames: int, seed: int, workers: int,
    progress: bool, symmetric: bool,
) -> tuple[_StructureEval, str]:
    """Evaluate the runs of one structure on its test objects (:func:`evaluate_category`).

    Raises
    ------
    _NoTestObject
        No object to evaluate.
    KinmoError
        A test object a run trained on.
    """

    cat = scan_category(data, category, structure)
    refused: list[str] = []
    if foreign:  # the training objects of the runs' split count as trained on
        trained = trained.union(*(Split.load(r.path / "split.json").train for r in loaded
                                  if (r.path / "split.json").is_file()))
        refused = [i for i in cat.fitting if i in trained]
        test_ids = [i for i in cat.fitting if i not in trained]
        if not test_ids:
            raise _NoTestObject(f"category {cat.category}: no object under {data} fits {structure.signature()} "
                                f"and was not trained on (trained on: {refused})", refused)
    else:
        sp = Split.load(loaded[0].path / "split.json")
        test_ids = [i for i in cat.fitting if i in set(sp.test)]
        if not test_ids:
            raise _NoTestObject(f"category {cat.category}: no test object of the split fits {structure.signature()}")
        for r, info in zip(loaded, infos):
            leak = sorted(_trained_ids(info) & set(test_ids))
            if leak:
                raise KinmoError(f"{r.path}: trained on test objects {leak}; evaluate with that run's split")
    cfg0 = loaded[0].config
    out.mkdir(parents=True, exist_ok=True)
    rcfg = cfg0.model_copy(update={"seed": seed, "render_workers": workers})
    files, failed = render_objects({i: cat.folders[i] for i in test_ids}, out / "objects" / "test",
                                   scans_dir / "test", frames, rcfg, progress)
    sym: dict[str, list[np.ndarray | None]] = {}
    if symmetric:
        from kinmo.ancsh.objects import object_parts_of
        from kinmo.ancsh.symmetry import part_symmetry_axes

        for i in test_ids:
            shape, parts_i = object_parts_of(cat.folders[i])
            sym[i] = part_symmetry_axes(shape, parts_i, seed=seed) if parts_i is not None else []
    if not files:
        raise KinmoError(f"no test scan could be rendered: {failed}")
    frames_data = []
    for f in files:
        fr = load_frame(f)
        if len(fr["points"]) < 32:
            continue
        key = str(fr["meta"]["key"])
        frames_data.append((f, fr, frame_truth(fr, cat.parts[key])))  # type: ignore[arg-type]
    seeds = [zlib.crc32(f"{seed}:{fr['meta']['key']}:{fr['meta']['frame']}".encode()) for _, fr, _ in frames_data]

    groups = interchangeable_groups(structure)
    rows: list[Table2Row] = []
    all_errs: list[list[FrameErrors]] = []
    all_matched: list[list[FrameErrors]] = []
    frame_lines: list[dict[str, Any]] = []
    for r, info in zip(loaded, infos):
        with torch_threads(r.config.threads):
            preds = predict_scans(r.model, [fr["points"] for _, fr, _ in frames_data], r.config.n_points,
                                  r.device, seeds)
        errs: list[FrameErrors] = []
        matched: list[FrameErrors] = []
        swapped = 0
        for (f, fr, truth), (pts, pred) in zip(frames_data, preds):
            est = quiet_estimate(pts, pred, structure, theta=r.config.theta, seed=seed)
            axes = sym.get(str(fr["meta"]["key"])) or None
            e = frame_errors(est, truth, axes)
            em, perm = matched_frame_errors(est, truth, groups, axes)
            errs.append(e)
            matched.append(em)
            swapped += int((perm != np.arange(len(perm))).any())
            line: dict[str, Any] = {"setting": r.setting, "run": str(r.path), "id": fr["meta"]["key"],
                                    "frame": int(fr["meta"]["frame"]), "permutation": " ".join(map(str, perm))}
            for n in METRICS:
                for i, x in enumerate(getattr(e, n)):
                    line[f"{n}_{i}"] = num(float(x))
                if n in MATCHED_METRICS:
                    for i, x in enumerate(getattr(em, n)):
                        line[f"{n}_matched_{i}"] = num(float(x))
            frame_lines.append(line)
        training = {k: info.get(k, 0) for k in ("labeled_scans", "pseudo_labeled_scans", "pseudo_target_scans")}
        training.update({f"{k}_count": len(info.get(k, [])) for k in
                         ("labeled_objects", "pseudo_labeled_objects", "unlabeled_objects")})
        rows.append(summarize(r.setting, str(r.path), errs, structure.joint_types, training, matched, swapped))
        all_errs.append(errs)
        all_matched.append(matched)

    source = "objects no run trained on" if foreign else "test objects"
    notes = [f"{source}: {', '.join(test_ids)}; {len(frames_data)} scans "
             f"({frames} per object, render seed {seed})",
             f"runs: {', '.join(f'{r.setting} = {r.path}' for r in loaded)}"]
    if refused:
        notes.append(f"left out, training objects of the runs: {', '.join(refused)}")
    sym_parts = {i: [k for k, a in enumerate(v) if a is not None] for i, v in sym.items()}
    if not symmetric:
        notes.append("symmetry-aware errors off: every part's rotation is compared as is")
    elif any(sym_parts.values()):
        notes.append("rotationally symmetric parts, evaluated up to their symmetry axis (NPCS axis): "
                     + "; ".join(f"{i}: " + ", ".join(f"part {k} about {np.round(sym[i][k], 3).tolist()}"
                                                      for k in ks) for i, ks in sym_parts.items() if ks))
    else:
        notes.append("no test part is rotationally symmetric (symmetry-aware errors change nothing)")
    if groups:
        notes.append(f"permutation-matched errors: interchangeable {describe_groups(groups, structure)} matched "
                     "by least summed rotation error per scan; swapped in "
                     + ", ".join(f"{r.swapped} of {r.frames} scans ({r.setting})" for r in rows))
    else:
        notes.append("no interchangeable parts (leaf siblings with one joint type): permutation-matched errors "
                     "equal the raw ones")
    return _StructureEval(structure, loaded, rows, all_errs, all_matched, groups, frame_lines, test_ids,
                          len(frames_data), failed, sym, notes, refused), cat.category
