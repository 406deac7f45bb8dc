"""The artefacts ``kinmo report`` shows (:func:`kinmo.report.collect.collect_run` finds
them): CSV tables of the pipeline's stages (Table 1, Table 2, training curves, pseudo-label
and prediction summaries), the images of the gallery, and a run's generated-shapes variants.
A malformed file is a :class:`~kinmo.errors.KinmoDataError` naming the file.
"""

from __future__ import annotations

import csv
import math
import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

from kinmo.errors import KinmoDataError
from kinmo.evaluate.pre_segmented import METRICS
from kinmo.evaluate.settings import PAPER_MEANS
from kinmo.paper import PAPER_TABLE2

__all__ = [
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
    "combine_table2",
    "paper_setting",
    "read_csv",
    "to_float",
]


def _table1_metrics() -> tuple[tuple[str, str, bool], ...]:
    return METRICS


def _paper_table1() -> dict[str, dict[str, float]]:
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
    synth_extra : list of SynthExtra
        Generated-shapes runs inside the run.
    table2_seeds : dict of int to Table2
        Table 2 of every ANCSH seed of ``kinmo train all --ancsh-seeds K`` (K >= 2), the run's
        own seed included, by seed; empty for a run of one seed.
    ancsh_synth : dict or None
        ``pipeline_result.json``'s ``ancsh_synth`` (``kinmo train all --ancsh-synth N``): the
        generated objects in ANCSH's training data.
    timings : dict of str to dict
        Stage → ``wall_s``, ``cpu_s``, ``ran`` of the last ``kinmo train all`` call.
    from_result : bool
        Found from the stages of ``pipeline_result.json`` (else by walking the folder).
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
    table2_seeds: dict[int, Table2] = field(default_factory=dict)
    ancsh_synth: dict | None = None
    timings: dict[str, dict] = field(default_factory=dict)
    from_result: bool = False

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



def _unique(seq) -> list[str]:
    out: list[str] = []
    for s in seq:
        if s not in out:
            out.append(s)
    return out

