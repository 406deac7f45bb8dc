"""Find the artefacts of a kinmo run folder (``kinmo report``).

A *run* is any folder written by the kinmo pipeline: one training run, an evaluation folder,
or the root of a whole pipeline holding all of them. :func:`collect_run` walks it (hidden
folders and earlier reports skipped) and recognises files by **name and columns**, never by
their place in the tree, so any layout works.

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
                                        (:func:`combine_table2`)
``curves``      ``metrics.csv``         an ``epoch`` column (``kinmo train gnn``,
                                        ``kinmo train axis``, ``kinmo train ancsh``)
``pseudo``      ``summary.csv``         columns ``category``, ``shapes``, ``kept``
                                        (``kinmo pseudo-label``)
``predictions`` ``predictions.csv``     columns ``id``, ``status``, ``n_links``, ``n_moving``
                                        (``kinmo predict``)
``gallery``     ``*.png``               any PNG image (``kinmo eval pre-segmented --render``,
                                        ``kinmo predict --render``)
=============== ======================= ===================================================

A file that looks like an artefact but cannot be read is listed in
:attr:`RunArtefacts.problems` (file and reason); collecting never raises for a partial or
damaged run, only for a run folder that does not exist.
"""

from __future__ import annotations

import csv
import json
import math
import os
import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

from kinmo.errors import KinmoDataError
from kinmo.paper import PAPER_TABLE2
from kinmo.runs import SYNTH_EXTRA_FILE  # the file of a generated-shapes run

__all__ = [
    "ARTEFACTS",
    "PAPER_TABLE1",
    "PAPER_TABLE2",
    "TABLE1_METRICS",
    "CsvTable",
    "Curves",
    "GalleryImage",
    "PredictionSummary",
    "PseudoSummary",
    "RunArtefacts",
    "SynthExtra",
    "Table1",
    "Table2",
    "Table2File",
    "collect_run",
    "combine_table2",
    "paper_setting",
    "read_csv",
]

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


def _table1_metrics() -> tuple[tuple[str, str, bool], ...]:
    from kinmo.evaluate.pre_segmented import METRICS

    return METRICS


def _paper_table1() -> dict[str, dict[str, float]]:
    from kinmo.refine.table import PAPER_MEANS

    return {k: dict(v) for k, v in PAPER_MEANS.items()}


#: Table 1 metrics: (column, header, higher is better), from the evaluation's writer.
TABLE1_METRICS: tuple[tuple[str, str, bool], ...] = _table1_metrics()

#: The paper's Table 1 means (Liu et al. 2023): axis angle error (degrees) and distance, per
#: setting (``GNN_fine``, ``GNN_coarse``, ``OBB_fine``).
PAPER_TABLE1: dict[str, dict[str, float]] = _paper_table1()


#: Columns of a Table 2 CSV naming the training setting, in order of preference.
SETTING_COLUMNS: tuple[str, ...] = ("setting", "supervision", "training", "method", "model",
                                    "variant")
#: Category names of a table's aggregate row.
MEAN_ROWS: tuple[str, ...] = ("mean", "all", "average", "avg")
#: Folders never searched.
SKIP_DIRS: frozenset[str] = frozenset({"__pycache__", "node_modules"})
#: Folders of dataset images that are not results (PartNet-Mobility's part thumbnails).
SKIP_IMAGE_DIRS: frozenset[str] = frozenset({"parts_render", "parts_render_after_merging"})
#: Folder names of kinmo's renders: shown first in the gallery.
RENDER_DIRS: frozenset[str] = frozenset({"renders", "render", "viz", "gallery"})
#: Largest PNG (bytes) put in the gallery.
MAX_IMAGE_BYTES = 4 * 1024 * 1024
_PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def read_csv(path: Path) -> tuple[list[str], list[dict[str, str]]]:
    """Read a CSV file: its header and rows (dicts of strings, missing cells empty).

    Raises
    ------
    KinmoDataError
        The file cannot be read or has no header.
    """
    try:
        with open(path, newline="", encoding="utf-8") as f:
            r = csv.reader(f)
            header = next(r, None)
            if not header:
                raise KinmoDataError(path, "empty CSV file (no header)")
            header = [h.strip() for h in header]
            rows = [dict(zip(header, [c.strip() for c in row] + [""] * (len(header) - len(row))))
                    for row in r if any(c.strip() for c in row)]
    except (OSError, UnicodeDecodeError, csv.Error) as e:
        raise KinmoDataError(path, f"cannot read CSV: {e}") from None
    return header, rows


def to_float(s: str | None) -> float:
    """A CSV cell as a float (NaN when empty or not a number)."""
    if s is None:
        return math.nan
    try:
        return float(s)
    except ValueError:
        return math.nan


@dataclass
class CsvTable:
    """A CSV file found in the run.

    Attributes
    ----------
    path : Path
        Absolute path.
    rel : str
        Path relative to the run folder (POSIX separators), used in the report.
    columns : list of str
    rows : list of dict of str to str
    """

    path: Path
    rel: str
    columns: list[str]
    rows: list[dict[str, str]]


@dataclass
class Table1(CsvTable):
    """A pre-segmented evaluation (paper Table 1), long format: one row per model and category.

    Attributes
    ----------
    models : list of str
        In file order (``GNN_coarse``, ``GNN_fine``, ``OBB_coarse``, ``OBB_fine``...).
    categories : list of str
        In file order, without the ``mean`` row.
    metrics : list of (str, str, bool)
        The :data:`TABLE1_METRICS` present in the file.
    """

    models: list[str] = field(default_factory=list)
    categories: list[str] = field(default_factory=list)
    metrics: list[tuple[str, str, bool]] = field(default_factory=list)

    def value(self, model: str, category: str, key: str) -> float:
        """The metric of a model on a category (``"mean"`` for the mean row); NaN when absent."""
        for r in self.rows:
            if r.get("model") == model and r.get("category") == category:
                return to_float(r.get(key))
        return math.nan

    def row(self, model: str, category: str) -> dict[str, str] | None:
        """The CSV row of a model and category, or None."""
        for r in self.rows:
            if r.get("model") == model and r.get("category") == category:
                return r
        return None


@dataclass
class Table2File(CsvTable):
    """A partial-scan evaluation CSV (``table2.csv`` of ``kinmo eval --category C``: one row per
    setting, columns ``setting``, ``run``, ``frames``, ``<metric>_mean`` and per part/joint).

    Attributes
    ----------
    category : str
        The category of the whole file when it has no ``category`` column: ``eval.json``'s
        ``category`` next to it, else the folder name without its ``eval-`` prefix.
    setting_column : str or None
        Column naming the setting; without one, the folder name is the setting.
    metric_columns : list of str
        Numeric metric columns in file order: the ``*_mean`` columns when there are any
        (per-part and per-joint columns are left to the file's own ``table2.md``).
    frames_column : str or None
        Column counting the evaluated scans.
    """

    category: str = ""
    setting_column: str | None = None
    metric_columns: list[str] = field(default_factory=list)
    frames_column: str | None = None

    def setting_of(self, row: dict[str, str]) -> str:
        """The setting of a row."""
        if self.setting_column is None:
            return self.path.parent.name
        return row.get(self.setting_column, "") or self.path.parent.name


@dataclass
class Table2:
    """Every partial-scan evaluation of the run merged: one entry per setting and category.

    Attributes
    ----------
    files : list of Table2File
    entries : list of dict
        ``setting``, ``category``, ``source`` (relative path), ``frames`` (float) and one
        float per metric column. Aggregate rows of the files (``mean``/``all``) are left out:
        :meth:`value` averages the categories, as the paper's mean does.
    settings, categories : list of str
        In order of appearance (settings in the paper's order when they are its own).
    metric_columns : list of str
    rotation_column, angle_column : str
        The columns compared with the paper's rotation error and axis angle error.
    """

    files: list[Table2File]
    entries: list[dict]
    settings: list[str]
    categories: list[str]
    metric_columns: list[str]
    rotation_column: str
    angle_column: str

    def entry(self, setting: str, category: str) -> dict | None:
        """The entry of a setting on a category, or None."""
        for e in self.entries:
            if e["setting"] == setting and e["category"] == category:
                return e
        return None

    def value(self, setting: str, category: str, key: str) -> float:
        """A metric of a setting on a category; ``"mean"``: the mean over the categories that
        have it. NaN when absent."""
        if category == "mean":
            vals = [self.value(setting, c, key) for c in self.categories]
            vals = [v for v in vals if not math.isnan(v)]
            return sum(vals) / len(vals) if vals else math.nan
        e = self.entry(setting, category)
        return math.nan if e is None else float(e.get(key, math.nan))

    def n_categories(self, setting: str) -> int:
        """Categories evaluated with ``setting``."""
        return sum(1 for e in self.entries if e["setting"] == setting)


def paper_setting(name: str) -> str | None:
    """The paper's Table 2 setting a setting name stands for (None when it matches none).

    ``semi-weakly``/``semi_weak``/``swmp``/``ours`` -> ``"semi-weakly"``;
    ``semi``/``semi-supervised`` -> ``"semi"``; ``supervised``/``sup`` -> ``"supervised"``.
    """
    n = re.sub(r"[\s_]+", "-", name.strip().lower())
    if "weak" in n or n in ("swmp", "ours"):
        return "semi-weakly"
    if n.startswith("semi"):
        return "semi"
    if n.startswith("sup") or n in ("full", "fully-supervised"):
        return "supervised"
    return None


def combine_table2(files: Sequence[Table2File]) -> Table2 | None:
    """Merge partial-scan evaluation files into one :class:`Table2` (None without files).

    A category evaluated twice for the same setting (two evaluation folders) keeps both,
    the second labelled ``"<category> (<folder>)"``.
    """
    if not files:
        return None
    metrics: list[str] = []
    for f in files:
        metrics += [c for c in f.metric_columns if c not in metrics]
    low = {c: c.lower() for c in metrics}

    def pick(word: str, prefer: Sequence[str]) -> str:
        cands = [c for c in metrics if word in low[c]]
        for w in prefer:
            for c in cands:
                if w in low[c]:
                    return c
        return cands[0] if cands else ""

    entries: list[dict] = []
    for f in files:
        for r in f.rows:
            cat = r.get("category", "") if "category" in f.columns else f.category
            if cat.lower() in MEAN_ROWS:
                continue
            setting = f.setting_of(r)
            if any(e["setting"] == setting and e["category"] == cat for e in entries):
                cat = f"{cat} ({Path(f.rel).parent.as_posix()})"
            e = {"setting": setting, "category": cat, "source": f.rel,
                 "frames": to_float(r.get(f.frames_column)) if f.frames_column else math.nan}
            e.update({c: to_float(r.get(c)) for c in f.metric_columns})
            entries.append(e)
    order = {"supervised": 0, "semi": 1, "semi-weakly": 2}
    seen = _unique(e["setting"] for e in entries)
    settings = sorted(seen, key=lambda s: (order.get(s, 9), seen.index(s)))
    return Table2(list(files), entries, settings, _unique(e["category"] for e in entries),
                  metrics, pick("rot", ("mean", "err", "deg")), pick("angle", ("mean", "axis")))


@dataclass
class Curves(CsvTable):
    """Per-epoch training metrics (a ``metrics.csv``).

    Attributes
    ----------
    epochs : list of float
        The x axis: the ``epoch`` column, or the row number (1, 2, ...) when the epochs
        restart (training in stages, e.g. ANCSH's supervised then semi-supervised epochs).
    series : dict of str to list of float
        Every numeric column except ``epoch`` (NaN for empty cells), in file order.
    config : dict
        The ``config.json`` next to it (empty when absent or unreadable).
    stages : list of (float, str)
        Where each training stage starts on the x axis and its name (``stage`` column; empty
        for single-stage runs).
    """

    epochs: list[float] = field(default_factory=list)
    series: dict[str, list[float]] = field(default_factory=dict)
    config: dict = field(default_factory=dict)
    stages: list[tuple[float, str]] = field(default_factory=list)

    def describe(self) -> str:
        """A short description of the run from its config (types, preset, epochs, seed)."""
        c = self.config
        parts = []
        model = c.get("model") if isinstance(c.get("model"), dict) else {}
        for key, val in (("category", c.get("category")), ("setting", c.get("setting")),
                         ("types", c.get("types", model.get("types"))),
                         ("preset", c.get("preset")), ("epochs", c.get("epochs")),
                         ("seed", c.get("seed"))):
            if val is not None and not isinstance(val, (dict, list)):
                parts.append(f"{key}={val}")
        return ", ".join(parts)


@dataclass
class PseudoSummary(CsvTable):
    """A pseudo-labelling summary (``summary.csv``): counts per category and status.

    Attributes
    ----------
    statuses : list of str
        Count columns after ``shapes`` (``kept``, ``no_moving_joint``...).
    """

    statuses: list[str] = field(default_factory=list)


@dataclass
class PredictionSummary(CsvTable):
    """A ``predictions.csv`` of ``kinmo predict``: status per shape."""

    def counts(self) -> dict[str, int]:
        """Number of shapes per status."""
        out: dict[str, int] = {}
        for r in self.rows:
            out[r.get("status", "")] = out.get(r.get("status", ""), 0) + 1
        return out


@dataclass
class GalleryImage:
    """A PNG found in the run.

    Attributes
    ----------
    path : Path
    rel : str
        Path relative to the run.
    group : str
        Its folder relative to the run (``"."`` at the top); for ``<id>/prediction.png``
        (``kinmo predict --render``) the folder above.
    label : str
        Shape id or file stem (the parent folder's name for ``prediction.png``).
    width, height : int
        From the PNG header.
    render : bool
        A render of kinmo (in a ``renders``/``render``/``viz``/``gallery`` folder, or a
        ``prediction.png``): shown before other PNGs.
    """

    path: Path
    rel: str
    group: str
    label: str
    width: int
    height: int
    render: bool = False


@dataclass
class RunArtefacts:
    """Everything :func:`collect_run` found in a run folder.

    Attributes
    ----------
    run : Path
    table1, table2_files, curves, pseudo, predictions : lists
        Recognised CSV files (sorted by path).
    table2 : Table2 or None
        The partial-scan evaluations merged (:func:`combine_table2`).
    images : list of GalleryImage
        Selected PNGs (at most ``max_images``, spread evenly over their folders).
    n_images_found : int
        All usable PNGs before the selection.
    problems : list of (str, str)
        ``(relative path, problem)`` of files that looked like artefacts but could not be used.
    """

    run: Path
    table1: list[Table1] = field(default_factory=list)
    table2_files: list[Table2File] = field(default_factory=list)
    table2: Table2 | None = None
    curves: list[Curves] = field(default_factory=list)
    pseudo: list[PseudoSummary] = field(default_factory=list)
    predictions: list[PredictionSummary] = field(default_factory=list)
    images: list[GalleryImage] = field(default_factory=list)
    n_images_found: int = 0
    problems: list[tuple[str, str]] = field(default_factory=list)
    synth_extra: list[SynthExtra] = field(default_factory=list)
    timings: dict[str, dict] = field(default_factory=dict)

    def counts(self) -> dict[str, int]:
        """Number of artefacts per kind of :data:`ARTEFACTS`."""
        return {"table1": len(self.table1), "table2": len(self.table2_files),
                "curves": len(self.curves), "pseudo": len(self.pseudo),
                "predictions": len(self.predictions), "gallery": len(self.images)}


@dataclass
class SynthExtra:
    """A run of ``kinmo train all --synth-extra N`` inside the run: the same models trained
    again with generated shapes added (a folder holding :data:`SYNTH_EXTRA_FILE`).

    Attributes
    ----------
    path : Path
    rel : str
        Folder relative to the run.
    info : dict
        The file's content: ``n``, ``as`` (``labeled``/``unlabeled``), ``seed``,
        ``categories``, ``test`` (the real test ids)...
    artefacts : RunArtefacts
        What the folder holds (its own Table 1 / Table 2 evaluations).
    """

    path: Path
    rel: str
    info: dict
    artefacts: RunArtefacts



def _synth_extra_dirs(run: Path) -> list[Path]:
    """Generated-shapes runs one or two levels below ``run``."""
    return sorted({p.parent for pat in ("*/" + SYNTH_EXTRA_FILE, "*/*/" + SYNTH_EXTRA_FILE)
                   for p in run.glob(pat) if not any(q.startswith(".") for q in p.relative_to(run).parts)})


def _timings(run: Path, problems: list[tuple[str, str]]) -> dict[str, dict]:
    """The stage timings of ``run/pipeline_result.json`` (``kinmo train all``), if any."""
    p = run / "pipeline_result.json"
    if not p.is_file():
        return {}
    try:
        t = json.loads(p.read_text(encoding="utf-8")).get("timings", {})
    except (OSError, ValueError, AttributeError) as e:
        problems.append(("pipeline_result.json", f"cannot read: {e}"))
        return {}
    return {str(k): v for k, v in t.items() if isinstance(v, dict)} if isinstance(t, dict) else {}


def _is_report_dir(names: Sequence[str]) -> bool:
    return "index.html" in names and "report.md" in names


def _walk(run: Path, exclude: Sequence[Path]) -> tuple[list[Path], list[Path]]:
    """CSV and PNG files below ``run`` (sorted), skipping hidden folders and reports."""
    excl = {os.path.realpath(p) for p in exclude}
    csvs: list[Path] = []
    pngs: list[Path] = []
    for root, dirs, files in os.walk(run):
        if os.path.realpath(root) in excl or (Path(root) != run and _is_report_dir(files)):
            dirs[:] = []
            continue
        dirs[:] = sorted(d for d in dirs if not d.startswith(".") and d not in SKIP_DIRS)
        for f in files:
            if f.startswith("."):
                continue
            low = f.lower()
            if low.endswith(".csv"):
                csvs.append(Path(root) / f)
            elif low.endswith(".png") and Path(root).name not in SKIP_IMAGE_DIRS:
                pngs.append(Path(root) / f)
    return sorted(csvs), sorted(pngs)


def _rel(p: Path, run: Path) -> str:
    return p.relative_to(run).as_posix()


def _unique(seq) -> list[str]:
    out: list[str] = []
    for s in seq:
        if s not in out:
            out.append(s)
    return out


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


def _gallery(pngs: list[Path], run: Path, max_images: int,
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


def collect_run(run: str | Path, exclude: Sequence[str | Path] = (),
                max_images: int = 48) -> RunArtefacts:
    """Find the artefacts of a run folder (module docstring for the mapping).

    Parameters
    ----------
    run : str or Path
        The run folder.
    exclude : sequence of str or Path
        Folders not searched (the report's own output folder). Folders holding both
        ``index.html`` and ``report.md`` (earlier reports) are always skipped.
    max_images : int
        Most PNGs kept for the gallery (spread over their folders).

    Returns
    -------
    RunArtefacts

    Raises
    ------
    KinmoDataError
        ``run`` does not exist or is not a folder.
    """
    run = Path(run)
    if not run.exists():
        raise KinmoDataError(run, "run folder does not exist")
    if not run.is_dir():
        raise KinmoDataError(run, "not a folder (give the run folder)")
    run = run.resolve()
    out = RunArtefacts(run)
    variants = _synth_extra_dirs(run)
    csvs, pngs = _walk(run, [Path(e) for e in exclude] + variants)
    for p in csvs:
        rel = _rel(p, run)
        try:
            header, rows = read_csv(p)
        except KinmoDataError as e:
            if p.name in ("metrics.csv", "table1.csv", "table2.csv", "summary.csv"):
                out.problems.append((rel, e.problem))
            continue
        t = CsvTable(p, rel, header, rows)
        try:
            for kind, conv in (("table1", _as_table1), ("table2_files", _as_table2),
                               ("curves", _as_curves), ("pseudo", _as_pseudo),
                               ("predictions", _as_predictions)):
                found = conv(t)
                if found is not None:
                    getattr(out, kind).append(found)
                    break
        except KinmoDataError as e:
            out.problems.append((rel, e.problem))
    out.table2 = combine_table2(out.table2_files)
    out.images, out.n_images_found = _gallery(pngs, run, max_images, out.problems)
    out.timings = _timings(run, out.problems)
    for v in variants:
        rel = _rel(v, run)
        try:
            info = json.loads((v / SYNTH_EXTRA_FILE).read_text(encoding="utf-8"))
            if not isinstance(info, dict):
                raise ValueError("not a JSON object")
        except (OSError, ValueError) as e:
            out.problems.append((f"{rel}/{SYNTH_EXTRA_FILE}", f"cannot read: {e}"))
            continue
        sub = collect_run(v, exclude=exclude, max_images=0)
        out.problems += [(f"{rel}/{r}", p) for r, p in sub.problems]
        out.synth_extra.append(SynthExtra(v, rel, info, sub))
    return out
