"""Which artefact a CSV or PNG file of a run is, from its name and columns
(:func:`kinmo.report.collect.collect_run` without ``pipeline_result.json``, and to read the
files that the pipeline's stages name).

The mapping (:data:`ARTEFACTS`, one line per kind):


=============== ======================= ===================================================
kind            file                    recognised by (writer)
=============== ======================= ===================================================
``table1``      ``*.csv`` (table1.csv)  columns ``model``, ``category``, ``n_shapes``, one
                                        metric of :data:`kinmo.evaluate.pre_segmented.METRICS`
                                        (``kinmo eval pre-segmented``; paper Table 1)
``table2``      ``*.csv`` (table2.csv)  a ``setting`` or ``category`` column, a rotation
                                        error column (name holding ``rot``), an axis-angle
                                        column (``angle``), no per-shape/frame id column
                                        (:mod:`kinmo.ancsh.evaluate`, ``kinmo eval
                                        --category C``; paper Table 2). The category is
                                        its column, else ``eval.json``'s ``category``
                                        next to the file, else the folder name
                                        (``eval-<category>``); all files are merged
                                        (:func:`combine_table2`). Permutation-matched
                                        columns (``*_matched*``) are left out: the
                                        report compares the raw errors with the paper.
``curves``      ``metrics.csv``         an ``epoch`` column (``kinmo train gnn``,
                                        ``kinmo train axis``, ``kinmo train ancsh``)
``pseudo``      ``summary.csv``         columns ``category``, ``shapes``, ``kept``
                                        (``kinmo pseudo-label``)
``predictions`` ``predictions.csv``     columns ``id``, ``status``, ``n_links``, ``n_moving``
                                        (``kinmo predict``)
``gallery``     ``*.png``               any PNG image (``kinmo eval pre-segmented --render``,
                                        ``kinmo predict --render``)
=============== ======================= ===================================================
"""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

from kinmo.errors import KinmoDataError
from kinmo.report.artefacts import (
    MEAN_ROWS,
    SETTING_COLUMNS,
    TABLE1_METRICS,
    CsvTable,
    Curves,
    GalleryImage,
    PredictionSummary,
    PseudoSummary,
    Table1,
    Table2File,
    _unique,
    to_float,
)

__all__ = ["ARTEFACTS", "CONVERTERS", "gallery", "png_size"]

#: Kind of artefact -> (file pattern, how it is recognised). Documentation of
#: :func:`collect_run`, shown in the report's overview.
ARTEFACTS: dict[str, tuple[str, str]] = {
    "table1": ("*.csv",
               "columns model, category, n_shapes + Table 1 metrics (kinmo eval pre-segmented)"),
    "table2": ("*.csv",
               "columns setting or category, *rot*, *angle* (kinmo eval --category)"),
    "curves": ("metrics.csv", "column epoch (kinmo train gnn / axis / ancsh)"),
    "pseudo": ("summary.csv", "columns category, shapes, kept (kinmo pseudo-label)"),
    "predictions": ("predictions.csv", "columns id, status, n_links, n_moving (kinmo predict)"),
    "gallery": ("*.png", "any PNG (eval --render, predict --render)"),
}


#: Folders never searched.
SKIP_DIRS: frozenset[str] = frozenset({"__pycache__", "node_modules"})
#: Folders of dataset images that are not results (PartNet-Mobility's part thumbnails).
SKIP_IMAGE_DIRS: frozenset[str] = frozenset({"parts_render", "parts_render_after_merging"})
#: Folder names of kinmo's renders: shown first in the gallery.
RENDER_DIRS: frozenset[str] = frozenset({"renders", "render", "viz", "gallery"})
#: Largest PNG (bytes) put in the gallery.
MAX_IMAGE_BYTES = 4 * 1024 * 1024
_PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def _rel(p: Path, run: Path) -> str:
    return p.relative_to(run).as_posix()



def _as_table1(t: CsvTable) -> Table1 | None:
    cols = set(t.columns)
    if not {"model", "category", "n_shapes"} <= cols:
        return None
    metrics = [m for m in TABLE1_METRICS if m[0] in cols]
    if not metrics:
        return None
    if not t.rows:
        raise KinmoDataError(t.path, "Table 1 CSV has no rows")
    return Table1(t.path, t.rel, t.columns, t.rows,
                  models=_unique(r["model"] for r in t.rows),
                  categories=_unique(r["category"] for r in t.rows
                                     if r["category"].lower() not in MEAN_ROWS),
                  metrics=metrics)


#: Columns of per-shape or per-frame tables (never an aggregate Table 2).
_PER_ITEM_COLUMNS = frozenset({"id", "shape_id", "object_id", "frame", "frame_id", "scan_id"})
_COUNT_COLUMN = re.compile(r"^(n|num|count)(_|$)|^(n_?)?(shapes|frames|objects|parts|joints|scans)$"
                           r"|_(scans|count)$")
_FRAMES_COLUMNS = ("frames", "n_frames", "scans", "n_scans")


def _category_of(path: Path) -> str:
    """A per-category evaluation folder's category: ``eval.json`` or the folder name."""
    meta = path.parent / "eval.json"
    if meta.is_file():
        try:
            cat = json.loads(meta.read_text(encoding="utf-8")).get("category")
            if isinstance(cat, str) and cat:
                return cat
        except (OSError, ValueError, AttributeError):
            pass
    return re.sub(r"^eval[-_]", "", path.parent.name) or path.parent.name


def _as_table2(t: CsvTable) -> Table2File | None:
    cols = t.columns
    low = {c: c.lower() for c in cols}
    setting_col = next((c for c in SETTING_COLUMNS if c in cols), None)
    if ("category" not in cols and setting_col is None) or _PER_ITEM_COLUMNS & set(low.values()):
        return None  # not a table of settings, or a per-shape / per-frame table
    if not any("rot" in low[c] for c in cols) or not any("angle" in low[c] for c in cols):
        return None
    if not t.rows:
        raise KinmoDataError(t.path, "Table 2 CSV has no rows")
    skip = {"category", setting_col}
    numeric = [c for c in cols if c not in skip and not _COUNT_COLUMN.search(low[c])
               and any(not math.isnan(to_float(r.get(c))) for r in t.rows)]
    numeric = [c for c in numeric if "_matched" not in low[c]]  # beside the raw protocol, not the paper's
    means = [c for c in numeric if low[c].endswith("_mean")]
    metric_cols = means or numeric
    if not any("rot" in low[c] for c in metric_cols):
        raise KinmoDataError(t.path, "Table 2 CSV has no numeric rotation error")
    return Table2File(t.path, t.rel, t.columns, t.rows,
                      category="" if "category" in cols else _category_of(t.path),
                      setting_column=setting_col, metric_columns=metric_cols,
                      frames_column=next((c for c in _FRAMES_COLUMNS if c in cols), None))


def _as_curves(t: CsvTable) -> Curves | None:
    if t.path.name != "metrics.csv" or "epoch" not in t.columns:
        return None
    epochs = [to_float(r.get("epoch")) for r in t.rows]
    stages: list[tuple[float, str]] = []
    names = [r.get("stage", "") for r in t.rows]
    restarts = any(not b > a for a, b in zip(epochs, epochs[1:]))
    if restarts or len(set(names)) > 1:
        epochs = [float(i + 1) for i in range(len(t.rows))] if restarts else epochs
        stages = [(epochs[i], n) for i, n in enumerate(names)
                  if n and (i == 0 or names[i - 1] != n)]
    series = {}
    for c in t.columns:
        if c == "epoch":
            continue
        vals = [to_float(r.get(c)) for r in t.rows]
        if any(not math.isnan(v) for v in vals):
            series[c] = vals
    config: dict = {}
    cfg = t.path.parent / "config.json"
    if cfg.is_file():
        try:
            loaded = json.loads(cfg.read_text(encoding="utf-8"))
            config = loaded if isinstance(loaded, dict) else {}
        except (OSError, ValueError):
            config = {}
    return Curves(t.path, t.rel, t.columns, t.rows, epochs=epochs, series=series, config=config,
                  stages=stages)


def _as_pseudo(t: CsvTable) -> PseudoSummary | None:
    if not {"category", "shapes", "kept"} <= set(t.columns):
        return None
    i = t.columns.index("shapes")
    return PseudoSummary(t.path, t.rel, t.columns, t.rows, statuses=t.columns[i + 1:])


def _as_predictions(t: CsvTable) -> PredictionSummary | None:
    if not {"id", "status", "n_links", "n_moving"} <= set(t.columns):
        return None
    return PredictionSummary(t.path, t.rel, t.columns, t.rows)


def png_size(data: bytes) -> tuple[int, int] | None:
    """Width and height of a PNG from its header, or None when ``data`` is not a PNG."""
    if len(data) < 24 or not data.startswith(_PNG_MAGIC) or data[12:16] != b"IHDR":
        return None
    w, h = int.from_bytes(data[16:20], "big"), int.from_bytes(data[20:24], "big")
    return (w, h) if w > 0 and h > 0 else None


def gallery(pngs: list[Path], run: Path, max_images: int,
             problems: list[tuple[str, str]]) -> tuple[list[GalleryImage], int]:
    groups: dict[str, list[GalleryImage]] = {}
    for p in pngs:
        rel = _rel(p, run)
        try:
            size = p.stat().st_size
            if size > MAX_IMAGE_BYTES:
                problems.append((rel, f"PNG of {size / 2**20:.1f} MiB left out of the gallery "
                                      f"(limit {MAX_IMAGE_BYTES / 2**20:.0f} MiB)"))
                continue
            with open(p, "rb") as f:
                head = f.read(24)
        except OSError as e:
            problems.append((rel, f"cannot read PNG: {e}"))
            continue
        wh = png_size(head)
        if wh is None:
            problems.append((rel, "not a valid PNG file"))
            continue
        folder, label = p.parent, p.stem
        if p.stem == "prediction" and p.parent != run:  # kinmo predict: OUT/<id>/prediction.png
            folder, label = p.parent.parent, p.parent.name
        group = _rel(folder, run) if folder != run else "."
        render = p.name == "prediction.png" or bool(RENDER_DIRS & set(Path(rel).parts[:-1]))
        groups.setdefault(group, []).append(GalleryImage(p, rel, group, label, *wh, render))
    found = sum(len(v) for v in groups.values())
    # kinmo's renders first, then other PNGs; round robin over the folders, so that every
    # model's renders show the same first shapes
    chosen: list[GalleryImage] = []
    for tier in (True, False):
        sel = [g for g in groups.values() if g[0].render == tier]
        k = 0
        while len(chosen) < max_images and any(k < len(g) for g in sel):
            for g in sel:
                if k < len(g) and len(chosen) < max_images:
                    chosen.append(g[k])
            k += 1
    chosen.sort(key=lambda im: (not im.render, im.group, im.rel))
    return chosen, found


#: Kind (attribute of :class:`~kinmo.report.artefacts.RunArtefacts`) -> converter, tried in
#: this order on every CSV of a run walked without ``pipeline_result.json``.
CONVERTERS = (("table1", _as_table1), ("table2_files", _as_table2), ("curves", _as_curves),
              ("pseudo", _as_pseudo), ("predictions", _as_predictions))
