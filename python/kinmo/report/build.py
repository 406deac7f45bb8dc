"""Compose the report :class:`~kinmo.report.document.Document` of a run's artefacts.

Sections, always present (a section whose artefacts are missing says so):

1. **Overview**: what was found, what is missing (and which command makes it), unreadable files;
2. **Table 1** (pre-segmented shapes): per evaluation CSV, the means next to the paper's
   (:data:`~kinmo.report.collect.PAPER_TABLE1`), per-model tables and bar charts per category;
3. **Table 2** (partial scans): the same against :data:`~kinmo.paper.PAPER_TABLE2`;
4. **Generated shapes: with vs without**: for a run of ``kinmo train all --synth-extra N``,
   Table 1 and Table 2 means on the real test objects without and with the generated shapes
   (the paper's study with generated DSG-Net shapes, Sec. 4.3);
5. **Training**: curves of every ``metrics.csv`` and a table of the final values;
6. **Pseudo-labels**: the summary of ``kinmo pseudo-label`` and its chart;
7. **Predictions**: status counts of ``kinmo predict``;
8. **Gallery**: the PNGs of the run (the Table 1 renders: moving parts coloured, predicted
   axes solid, true axes dashed).

The overview also lists the time of every pipeline stage (``pipeline_result.json``).
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable
from datetime import datetime, timezone
from pathlib import Path

import kinmo.report.charts as charts
from kinmo.report.collect import (
    PAPER_TABLE1,
    PAPER_TABLE2,
    Curves,
    RunArtefacts,
    SynthExtra,
    Table1,
    Table2,
    paper_setting,
    png_size,
    to_float,
)
from kinmo.report.document import (
    Block,
    Document,
    Figure,
    Gallery,
    Heading,
    Note,
    Section,
    Table,
    Text,
)

__all__ = ["build_document", "fmt_value"]

#: What makes each kind of artefact (shown when it is missing).
HINTS: dict[str, tuple[str, str]] = {
    "table1": ("Table 1 evaluation (pre-segmented shapes)",
               "kinmo eval pre-segmented --model RUN --data CACHE"),
    "table2": ("Table 2 evaluation (partial scans)",
               "kinmo train ancsh, then kinmo eval --category C"),
    "curves": ("training metrics (metrics.csv)", "kinmo train gnn / axis / ancsh"),
    "pseudo": ("pseudo-label summary (summary.csv)", "kinmo pseudo-label"),
    "predictions": ("predictions (predictions.csv)", "kinmo predict"),
    "gallery": ("shape renders (PNG)", "kinmo eval pre-segmented --render"),
}
_EDGE_PANELS = (("angle_edge", "angle"), ("dist_edge", "distance"))


def fmt_value(column: str, v: float) -> str:
    """Format a metric for a table: angles and rotations 2 decimals, distances, accuracies
    and other scores 3, counts as integers, NaN as an en dash."""
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return "–"
    c = column.lower()
    if re.search(r"(^|_)(n|count|shapes|joints|frames|epoch)s?($|_)", c) and float(v).is_integer():
        return str(int(v))
    if any(w in c for w in ("angle", "rot", "deg")):
        return f"{v:.2f}"
    if any(w in c for w in ("dist", "trans", "acc", "recall", "precision", "iou", "loss",
                            "coverage", "chance")):
        return f"{v:.3f}"
    return f"{v:.3f}" if v == 0 or 1e-3 <= abs(v) < 1e4 else f"{v:.4g}"


def _slug(text: str) -> str:
    s = re.sub(r"[^A-Za-z0-9]+", "_", text).strip("_").lower()
    return s or "run"


def _figure(name: str, png: bytes, alt: str, caption: str = "") -> Figure:
    w, h = png_size(png) or (0, 0)
    return Figure(name, png, alt, caption, w, h)


def _delta(value: float, ref: float | None, decimals: int = 2) -> tuple[str, str | None]:
    """``value - ref`` formatted, and its mark (lower is better)."""
    if ref is None or math.isnan(value):
        return "–", None
    d = value - ref
    return f"{d:+.{decimals}f}", ("better" if d <= 0 else "worse")


def _safe_chart(make: Callable[[], bytes], name: str, alt: str, caption: str,
                blocks: list[Block]) -> None:
    try:
        png = make()
    except Exception as e:  # noqa: BLE001 - a chart must never sink the report
        blocks.append(Note(f"chart {name} could not be drawn: {type(e).__name__}: {e}", "problem"))
        return
    blocks.append(_figure(name, png, alt, caption))


# --- Table 1 ------------------------------------------------------------------------------


def _table1_paper(t: Table1) -> Table:
    cols = ["model", "angle err edges (deg)", "paper angle (deg)", "Δ angle",
            "dist edges (/diag)", "paper distance", "Δ distance",
            "angle err joints (deg)", "line dist joints (/diag)"]
    rows: list[list[str]] = []
    marks: dict[tuple[int, int], str] = {}
    for m in [*t.models, *[p for p in PAPER_TABLE1 if p not in t.models]]:
        ref = PAPER_TABLE1.get(m, {})
        if m not in t.models:
            rows.append([f"{m} (not in this run)", "–", f"{ref['angle']:.2f}", "–", "–",
                         f"{ref['distance']:.3f}", "–", "–", "–"])
            continue
        a, d = t.value(m, "mean", "angle_edge"), t.value(m, "mean", "dist_edge")
        da, ma = _delta(a, ref.get("angle"))
        dd, md = _delta(d, ref.get("distance"), 3)
        i = len(rows)
        if ma:
            marks[(i, 3)] = ma
        if md:
            marks[(i, 6)] = md
        rows.append([m, fmt_value("angle", a),
                     f"{ref['angle']:.2f}" if "angle" in ref else "–", da,
                     fmt_value("dist", d),
                     f"{ref['distance']:.3f}" if "distance" in ref else "–", dd,
                     fmt_value("angle", t.value(m, "mean", "angle_joint")),
                     fmt_value("dist", t.value(m, "mean", "dist_joint"))])
    return Table(cols, rows, marks=marks, caption=(
        "Means over categories next to the paper's Table 1 (Liu et al. 2023). Δ = this run − "
        "paper (green: lower error). kinmo's distances are divided by the shape's bounding-box "
        "diagonal; the paper's are in PartNet-Mobility mesh units (shapes roughly unit-sized)."))


def _table1_model(t: Table1, model: str) -> Table:
    cols = ["category", "shapes", "joints", *[h for _, h, _ in t.metrics]]
    rows, bold = [], set()
    for c in [*t.categories, "mean"]:
        r = t.row(model, c)
        if r is None:
            continue
        if c == "mean":
            bold.add(len(rows))
        rows.append([c, fmt_value("n_shapes", to_float(r.get("n_shapes"))),
                     fmt_value("n_joints", to_float(r.get("n_joints"))),
                     *[fmt_value(k, to_float(r.get(k))) for k, _, _ in t.metrics]])
    higher = ", ".join(h for _, h, hi in t.metrics if hi)
    return Table(cols, rows, bold_rows=bold,
                 caption=f"{model}: higher is better for {higher}; lower for the errors.")


def _table1_blocks(t: Table1) -> list[Block]:
    n = t.value(t.models[0], "mean", "n_shapes") if t.models else math.nan
    blocks: list[Block] = [
        Heading(f"{t.rel}"),
        Text(f"Models {', '.join(t.models)} on {len(t.categories)} categories"
             + (f", {fmt_value('n_shapes', n)} test shapes" if not math.isnan(n) else "")
             + f" (file `{t.rel}`)."),
        _table1_paper(t),
    ]
    keys = {k for k, _, _ in t.metrics}
    groups = [*t.categories, "mean"]
    err_panels = []
    for key, header, _ in t.metrics:
        if key.startswith(("angle", "dist")):
            ref_key = dict(_EDGE_PANELS).get(key)
            ref = ({m: PAPER_TABLE1[m][ref_key] for m in PAPER_TABLE1 if ref_key in PAPER_TABLE1[m]}
                   if ref_key else {})
            err_panels.append(charts.BarPanel(
                header, groups, {m: [t.value(m, c, key) for c in groups] for m in t.models}, ref))
    slug = _slug(t.rel)
    if err_panels:
        _safe_chart(lambda: charts.bar_chart(err_panels,
                                             "Axis errors per category (lower is better)"),
                    f"table1_{slug}_errors.png", f"Table 1 axis errors per category ({t.rel})",
                    "Axis errors per category and model; hatched: the paper's means "
                    "(edge-level protocol).", blocks)
    acc_panels = [charts.BarPanel(h, groups, {m: [t.value(m, c, k) for c in groups]
                                              for m in t.models})
                  for k, h, hi in t.metrics if hi and k in keys]
    if acc_panels:
        _safe_chart(lambda: charts.bar_chart(acc_panels, "Type accuracy and mobile-part "
                                             "detection (higher is better)", ncols=3),
                    f"table1_{slug}_accuracy.png",
                    f"Table 1 type accuracy and detection per category ({t.rel})",
                    "Motion-type accuracy and mobile-part precision/recall per category.", blocks)
    for m in t.models:
        blocks.append(Heading(m, 4))
        blocks.append(_table1_model(t, m))
    return blocks


# --- Table 2 ------------------------------------------------------------------------------


#: Headers of kinmo's Table 2 metrics (:mod:`kinmo.ancsh.evaluate`), by column name without
#: its ``_mean`` suffix.
T2_LABELS: dict[str, str] = {
    "rotation_deg": "rotation err (deg)", "translation": "translation err", "iou": "3D IoU",
    "state": "joint state err", "angle_deg": "axis angle err (deg)",
    "distance": "axis distance",
}


def _t2_label(col: str) -> str:
    base = col[:-5] if col.endswith("_mean") else col
    return T2_LABELS.get(base, base)


def _t2_fmt(col: str, v: float) -> str:
    c = col.lower()
    if not math.isnan(v) and ("trans" in c or "dist" in c):
        return f"{v:.4f}"
    return fmt_value(col, v)


def _table2_paper(t: Table2) -> Table:
    cols = ["setting", "categories", _t2_label(t.rotation_column), "paper rotation (deg)",
            "Δ rotation", _t2_label(t.angle_column), "paper angle (deg)", "Δ angle"]
    rows: list[list[str]] = []
    marks: dict[tuple[int, int], str] = {}
    mapped = {s: paper_setting(s) for s in t.settings}
    for s in t.settings:
        ref = PAPER_TABLE2.get(mapped[s] or "", {})
        r, a = t.value(s, "mean", t.rotation_column), t.value(s, "mean", t.angle_column)
        dr, mr = _delta(r, ref.get("rotation"))
        da, ma = _delta(a, ref.get("angle"))
        i = len(rows)
        if mr:
            marks[(i, 4)] = mr
        if ma:
            marks[(i, 7)] = ma
        label = s if not mapped[s] or mapped[s] == s else f"{s} ({mapped[s]})"
        rows.append([label, str(t.n_categories(s)), fmt_value("rot", r),
                     f"{ref['rotation']:.2f}" if ref else "–", dr, fmt_value("angle", a),
                     f"{ref['angle']:.2f}" if ref else "–", da])
    for p, ref in PAPER_TABLE2.items():
        if p not in mapped.values():
            rows.append([f"{p} (not in this run)", "0", "–", f"{ref['rotation']:.2f}", "–", "–",
                         f"{ref['angle']:.2f}", "–"])
    return Table(cols, rows, marks=marks, caption=(
        "Means over the evaluated categories next to the paper's Table 2 (Liu et al. 2023, "
        "ANCSH on partial scans trained supervised / semi-supervised / semi-weakly "
        "supervised). Δ = this run − paper (green: lower error). The paper's means cover its "
        "own categories."))


def _table2_categories(t: Table2) -> Table:
    cols = ["category", "setting", "frames", *[_t2_label(c) for c in t.metric_columns]]
    rows, bold = [], set()
    for c in t.categories:
        for s in t.settings:
            e = t.entry(s, c)
            if e is not None:
                rows.append([c, s, fmt_value("frames", e["frames"]),
                             *[_t2_fmt(m, e.get(m, math.nan)) for m in t.metric_columns]])
    for s in t.settings:
        bold.add(len(rows))
        rows.append(["mean", s, "–", *[_t2_fmt(m, t.value(s, "mean", m))
                                      for m in t.metric_columns]])
    return Table(cols, rows, align="ll" + "r" * (len(cols) - 2), bold_rows=bold, caption=(
        "Means over the test scans of each category (over parts for part metrics, over joints "
        "for joint metrics); mean rows average the categories. Translation and axis distance "
        "in mesh units."))


def _table2_blocks(t: Table2) -> list[Block]:
    blocks: list[Block] = [
        Text(f"Settings {', '.join(t.settings)} on {len(t.categories)} "
             f"categor{'y' if len(t.categories) == 1 else 'ies'} "
             f"({', '.join(t.categories)}), from "
             + ", ".join(f"`{f.rel}`" for f in t.files) + "."),
        _table2_paper(t),
    ]
    groups = [*t.categories, "mean"]
    panels = []
    for col in t.metric_columns[:6]:
        ref_key = ("rotation" if col == t.rotation_column else
                   "angle" if col == t.angle_column else None)
        ref: dict[str, float] = {}
        if ref_key:
            mapped = {s: paper_setting(s) for s in t.settings}
            for s, p in mapped.items():
                if p:
                    ref[s] = PAPER_TABLE2[p][ref_key]
            for p, vals in PAPER_TABLE2.items():
                if p not in mapped.values():
                    ref[p] = vals[ref_key]
        panels.append(charts.BarPanel(_t2_label(col), groups,
                                      {s: [t.value(s, c, col) for c in groups]
                                       for s in t.settings}, ref))
    if panels:
        _safe_chart(lambda: charts.bar_chart(panels, "Partial-scan metrics per category",
                                             ncols=3 if len(panels) > 4 else 2),
                    "table2.png", "Table 2 metrics per category and setting",
                    "Per category and setting; hatched: the paper's means.", blocks)
    blocks.append(_table2_categories(t))
    details = [f.path.parent / "table2.md" for f in t.files]
    found = [f"`{Path(f.rel).parent.as_posix()}/table2.md`" for f, d in zip(t.files, details)
             if d.is_file()]
    if found:
        blocks.append(Note("Per-part and per-joint errors: " + ", ".join(found) + ".", "info"))
    return blocks


# --- Training -----------------------------------------------------------------------------


def _final_values(c: Curves) -> str:
    panels = charts.split_curves(c.series)
    parts = []
    for kind in ("loss", "scores", "errors"):
        for name, vals in panels.get(kind, {}).items():
            last = next((v for v in reversed(vals) if not math.isnan(v)), math.nan)
            parts.append(f"{name} {fmt_value(name, last)}")
    return ", ".join(parts[:8]) + (" …" if len(parts) > 8 else "")


def _training_blocks(curves: list[Curves]) -> list[Block]:
    rows = []
    for c in curves:
        n = sum(1 for e in c.epochs if not math.isnan(e))
        rows.append([c.rel, c.describe() or "–", str(n), _final_values(c) or "–"])
    blocks: list[Block] = [Table(["metrics.csv", "run", "epochs", "last epoch"], rows,
                                 align="llrl", caption="Every training run found.")]
    for c in curves:
        blocks.append(Heading(c.rel, 4))
        if not c.rows:
            blocks.append(Note(f"{c.rel}: no epoch recorded yet (empty metrics.csv)."))
            continue
        if not charts.split_curves(c.series):
            blocks.append(Note(f"{c.rel}: no loss, score or error column to plot.", "problem"))
            continue
        desc = c.describe()
        _safe_chart(lambda c=c: charts.curves_chart(c.epochs, c.series, c.rel, c.stages),
                    f"curves_{_slug(c.rel)}.png", f"Training curves of {c.rel}",
                    f"Training curves of `{c.rel}`" + (f" ({desc})" if desc else "")
                    + "; dashed: test/validation.", blocks)
    return blocks


# --- Pseudo-labels, predictions, gallery --------------------------------------------------


def _pseudo_blocks(art: RunArtefacts) -> list[Block]:
    blocks: list[Block] = []
    for p in art.pseudo:
        blocks.append(Heading(p.rel, 4))
        cols = ["category", "shapes", *p.statuses, "kept %"]
        rows, bold = [], set()
        for r in p.rows:
            n = to_float(r.get("shapes"))
            kept = to_float(r.get("kept"))
            if r.get("category") == "all":
                bold.add(len(rows))
            rows.append([r.get("category", ""), fmt_value("n_shapes", n),
                         *[fmt_value("count", to_float(r.get(s))) for s in p.statuses],
                         f"{100 * kept / n:.1f}" if n and not math.isnan(kept) else "–"])
        blocks.append(Table(cols, rows, bold_rows=bold,
                            caption="Shapes per category by pseudo-labelling status."))
        cats = [r for r in p.rows if r.get("category") != "all"]
        if cats:
            _safe_chart(lambda p=p, cats=cats: charts.stacked_chart(
                            [r["category"] for r in cats],
                            {s: [to_float(r.get(s)) if not math.isnan(to_float(r.get(s))) else 0.0
                                 for r in cats] for s in p.statuses},
                            "Pseudo-labelling outcome per category"),
                        f"pseudo_{_slug(p.rel)}.png", f"Pseudo-label statuses ({p.rel})",
                        "Shapes kept as pseudo-labels and rejected, per category.", blocks)
    return blocks


def _prediction_blocks(art: RunArtefacts) -> list[Block]:
    rows = []
    statuses: list[str] = []
    for p in art.predictions:
        for s in p.counts():
            if s not in statuses:
                statuses.append(s)
    for p in art.predictions:
        cnt = p.counts()
        moving = [to_float(r.get("n_moving")) for r in p.rows if r.get("status") == "ok"]
        moving = [m for m in moving if not math.isnan(m)]
        rows.append([p.rel, str(len(p.rows)), *[str(cnt.get(s, 0)) for s in statuses],
                     f"{sum(moving) / len(moving):.2f}" if moving else "–"])
    blocks: list[Block] = [Table(["predictions.csv", "shapes", *statuses,
                                  "moving links / shape"], rows)]
    for p in art.predictions:
        failed = [r for r in p.rows if r.get("status") not in ("ok", "")]
        if failed:
            blocks.append(Note(f"{p.rel}: {len(failed)} shape(s) failed, e.g. "
                               + "; ".join(f"{r.get('id')}: {r.get('error', '')}"
                                           for r in failed[:3]), "problem"))
    return blocks


def _gallery_blocks(art: RunArtefacts) -> list[Block]:
    blocks: list[Block] = []
    if art.n_images_found > len(art.images):
        blocks.append(Note(f"{len(art.images)} of the {art.n_images_found} PNGs found are shown "
                           "(spread over their folders; raise --max-images for more).", "info"))
    groups: dict[str, list[Figure]] = {}
    for im in art.images:
        try:
            png = im.path.read_bytes()
        except OSError as e:
            blocks.append(Note(f"{im.rel}: cannot read: {e}", "problem"))
            continue
        name = "gallery/" + _slug(im.rel.rsplit(".", 1)[0]) + ".png"
        groups.setdefault(im.group, []).append(
            Figure(name, png, f"{im.label} ({im.group})", im.label, im.width, im.height))
    for g, figs in groups.items():
        blocks.append(Heading(g if g != "." else "(run folder)", 4))
        blocks.append(Gallery(figs))
    return blocks


# --- Document -----------------------------------------------------------------------------


def _missing(kind: str) -> Note:
    what, cmd = HINTS[kind]
    return Note(f"No {what} in this run (made by `{cmd}`).")


def _overview(art: RunArtefacts) -> list[Block]:
    counts = art.counts()
    files = {
        "table1": [t.rel for t in art.table1], "table2": [t.rel for t in art.table2_files],
        "curves": [c.rel for c in art.curves], "pseudo": [p.rel for p in art.pseudo],
        "predictions": [p.rel for p in art.predictions],
        "gallery": ([f"{art.n_images_found} PNG(s) in "
                     f"{len({im.group for im in art.images})} folder(s)"]
                    if art.images else []),
    }
    rows, marks = [], {}
    for i, kind in enumerate(HINTS):
        found = counts[kind] > 0
        rows.append([HINTS[kind][0], "found" if found else "missing",
                     ", ".join(files[kind][:6]) + (" …" if len(files[kind]) > 6 else "")
                     if found else f"run `{HINTS[kind][1]}`"])
        marks[(i, 1)] = "better" if found else "worse"
    blocks: list[Block] = [Table(["artefact", "status", "files"], rows, align="lll", marks=marks,
                                 caption=("Artefacts are the outputs of the stages named in "
                                          "pipeline_result.json." if art.from_result else
                                          "Artefacts are recognised by file name and columns "
                                          "anywhere under the run folder."))]
    for rel, problem in art.problems:
        blocks.append(Note(f"{rel}: {problem}", "problem"))
    if art.timings:
        blocks.append(_timings_table(art.timings))
    return blocks


def _timings_table(timings: dict[str, dict]) -> Table:
    rows, wall, cpu = [], 0.0, 0.0
    for name, t in timings.items():
        w, c = to_float(str(t.get("wall_s", ""))), to_float(str(t.get("cpu_s", "")))
        ran = bool(t.get("ran", True))
        rows.append([name, f"{w:.1f}" if ran else "–", f"{c:.1f}" if ran else "–",
                     "ran" if ran else "up to date"])
        if ran and not math.isnan(w):
            wall += w
        if ran and not math.isnan(c):
            cpu += c
    bold = {len(rows)}
    rows.append(["total", f"{wall:.1f}", f"{cpu:.1f}", ""])
    return Table(["stage", "wall (s)", "CPU (s)", ""], rows, align="lrrl", bold_rows=bold, caption=(
        "Time of each stage of the last `kinmo train all` / `kinmo demo` call (CPU: user + system "
        "seconds of the process and its workers; stages up to date were skipped)."))


# --- Generated shapes: with vs without ----------------------------------------------------


def _compare_rows(rows: list[list[str]], marks: dict[tuple[int, int], str], name: str,
                  metric: str, without: float, with_: float, higher: bool,
                  fmt: Callable[[str, float], str], tally: list[int]) -> None:
    d = with_ - without
    better = None
    if not (math.isnan(d) or d == 0):
        better = (d > 0) == higher
        tally[0 if better else 1] += 1
    i = len(rows)
    if better is not None:
        marks[(i, 4)] = "better" if better else "worse"
    rows.append([name, metric, fmt(metric, without), fmt(metric, with_),
                 "–" if math.isnan(d) else ("+" if d >= 0 else "−") + fmt(metric, abs(d))])


def _verdict(tally: list[int], what: str) -> str:
    b, w = tally
    if b + w == 0:
        return f"{what}: no difference."
    word = ("helped" if b > w else "hurt" if w > b else "neither helped nor hurt (as many metrics "
            "better as worse)")
    return (f"{what}: the generated shapes {word}: {b} of {b + w} changed metrics better, "
            f"{w} worse.")


def _synth_extra_blocks(art: RunArtefacts, v: SynthExtra) -> list[Block]:
    info = v.info
    n, how = info.get("n", "?"), info.get("as", "?")
    cats = ", ".join(info.get("categories", []))
    n_test = len(info.get("test", []))
    used_by = info.get("used_by") or ["motion GNN", "axis network", "ANCSH"]
    used = ", ".join(used_by[:-1]) + (" and " if len(used_by) > 1 else "") + used_by[-1]
    use = (f"as labelled training objects of the {used}"
           if how == "labeled" else
           "as unlabelled shapes: pseudo-labelled by the baseline's GNN and axis network, then "
           "used by ANCSH semi and semi-weakly")
    blocks: list[Block] = [Text(
        f"`{v.rel}`: {n} generated objects ({cats}; seed {info.get('seed', '?')}) added {use}. "
        f"Everything else is the same as the run above (seed, presets, split); both are evaluated "
        f"on the same {n_test} real test objects. Green: the generated shapes lowered an error "
        f"or raised a score. With few test objects, small differences are noise.")]
    # Table 1
    sub = v.artefacts
    base_t1 = {t.rel: t for t in art.table1}
    pairs = [(base_t1[t.rel], t) for t in sub.table1 if t.rel in base_t1]
    if not pairs:
        blocks.append(Note("Table 1 is the same without and with the generated shapes: the motion "
                           "GNN and the axis network never see unlabelled shapes." if how == "unlabeled"
                           else f"No Table 1 evaluation in both the run and `{v.rel}`.", "info"))
    for bt, vt in pairs:
        rows: list[list[str]] = []
        marks: dict[tuple[int, int], str] = {}
        tally = [0, 0]
        for m in [x for x in bt.models if x in vt.models]:
            for key, header, higher in bt.metrics:
                _compare_rows(rows, marks, m, header, bt.value(m, "mean", key),
                              vt.value(m, "mean", key), higher, fmt_value, tally)
        blocks.append(Heading(f"Table 1 ({bt.rel})", 4))
        blocks.append(Text(_verdict(tally, "Table 1")))
        blocks.append(Table(["model", "metric", "without", "with generated", "Δ"], rows, align="llrrr",
                            marks=marks, caption="Means over categories on the real test objects."))
        models = [x for x in bt.models if x in vt.models]
        panels = [charts.BarPanel(h, models, {"without": [bt.value(m, "mean", k) for m in models],
                                              "with generated": [vt.value(m, "mean", k) for m in models]})
                  for k, h, _ in bt.metrics if k in ("angle_edge", "dist_edge", "edge_acc", "recall")]
        if panels:
            _safe_chart(lambda panels=panels: charts.bar_chart(panels, "Without vs with generated shapes"),
                        f"synth_extra_{_slug(bt.rel)}.png", "Table 1 without vs with generated shapes",
                        "Table 1 means on the real test objects, without and with the generated shapes.",
                        blocks)
    # Table 2
    bt2, vt2 = art.table2, sub.table2
    if bt2 is not None and vt2 is not None:
        rows, marks, tally = [], {}, [0, 0]
        for s in [x for x in bt2.settings if x in vt2.settings]:
            for col in [c for c in bt2.metric_columns if c in vt2.metric_columns]:
                higher = "iou" in col.lower()
                _compare_rows(rows, marks, s, _t2_label(col), bt2.value(s, "mean", col),
                              vt2.value(s, "mean", col), higher,
                              lambda label, x, col=col: _t2_fmt(col, x), tally)
        blocks.append(Heading("Table 2", 4))
        blocks.append(Text(_verdict(tally, "Table 2")))
        blocks.append(Table(["setting", "metric", "without", "with generated", "Δ"], rows, align="llrrr",
                            marks=marks, caption="Means over categories ("
                            + ", ".join(c for c in bt2.categories if c in vt2.categories)
                            + ") on scans of the real test objects."))
    elif bt2 is not None or vt2 is not None:
        blocks.append(Note(f"Table 2 is in only one of the run and `{v.rel}`.", "info"))
    return blocks


def build_document(art: RunArtefacts, title: str | None = None) -> Document:
    """The report of a run's artefacts (module docstring for its sections).

    Parameters
    ----------
    art : RunArtefacts
        From :func:`kinmo.report.collect.collect_run`.
    title : str, optional
        Default ``"kinmo report: <run folder name>"``.

    Returns
    -------
    Document
    """
    import kinmo

    sections = [Section("overview", "Overview", _overview(art))]
    t1: list[Block] = [Text(
        "Motion prediction on pre-segmented shapes (paper Table 1): motion-type accuracy, "
        "mobile-part detection and axis errors per category. Paper means: "
        + ", ".join(f"{m} {v['angle']:.2f}° / {v['distance']:.3f}"
                    for m, v in PAPER_TABLE1.items()) + ".")]
    if not art.table1:
        t1.append(_missing("table1"))
    for t in art.table1:
        t1 += _table1_blocks(t)
    sections.append(Section("table1", "Table 1: pre-segmented shapes", t1))
    t2: list[Block] = [Text(
        "ANCSH on partial scans (paper Table 2): part rotation error and joint axis angle error "
        "per category. Paper means (rotation / axis angle): "
        + ", ".join(f"{s} {v['rotation']:.2f}° / {v['angle']:.2f}°"
                    for s, v in PAPER_TABLE2.items()) + ".")]
    if art.table2 is None:
        t2.append(_missing("table2"))
    else:
        t2 += _table2_blocks(art.table2)
    sections.append(Section("table2", "Table 2: partial scans", t2))
    gen: list[Block] = []
    for v in art.synth_extra:
        gen += _synth_extra_blocks(art, v)
    sections.append(Section("synth-extra", "Generated shapes: with vs without", gen or [Note(
        "No run with generated shapes added (made by `kinmo train all --synth-extra N "
        "--synth-as labeled|unlabeled`).", "info")]))
    sections.append(Section("training", "Training",
                            _training_blocks(art.curves) if art.curves else [_missing("curves")]))
    sections.append(Section("pseudo", "Pseudo-labels",
                            _pseudo_blocks(art) if art.pseudo else [_missing("pseudo")]))
    sections.append(Section("predictions", "Predictions",
                            _prediction_blocks(art) if art.predictions
                            else [_missing("predictions")]))
    sections.append(Section("gallery", "Gallery",
                            _gallery_blocks(art) if art.images else [_missing("gallery")]))

    used: set[str] = set()
    for s in sections:  # unique image file names (slugs of different paths may clash)
        for b in s.blocks:
            for fig in (b.figures if isinstance(b, Gallery) else [b] if isinstance(b, Figure)
                        else []):
                stem, k = fig.name[:-4], 2
                while fig.name in used:
                    fig.name = f"{stem}_{k}.png"
                    k += 1
                used.add(fig.name)
    meta = [("run", str(art.run)),
            ("generated", datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M UTC")),
            ("kinmo", getattr(kinmo, "__version__", "?"))]
    return Document(title or f"kinmo report: {art.run.name}", meta, sections)
