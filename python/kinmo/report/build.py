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

The overview also lists the time of every pipeline stage (``pipeline_result.json``). The
Table 1 and Table 2 sections are composed in :mod:`kinmo.report.paper_tables`, the shared
formatting in :mod:`kinmo.report.blocks`.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from datetime import datetime, timezone

import kinmo
from kinmo.report.blocks import chart_block, file_slug, fmt_value
import kinmo.report.charts as charts
from kinmo.report.collect import (
    Curves,
    PAPER_TABLE1,
    PAPER_TABLE2,
    RunArtefacts,
    SynthExtra,
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
from kinmo.report.paper_tables import t2_fmt, t2_label, table1_blocks, table2_blocks, table2_seed_blocks

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
        chart_block(lambda c=c: charts.curves_chart(c.epochs, c.series, c.rel, c.stages),
                    f"curves_{file_slug(c.rel)}.png", f"Training curves of {c.rel}",
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
            chart_block(lambda p=p, cats=cats: charts.stacked_chart(
                            [r["category"] for r in cats],
                            {s: [to_float(r.get(s)) if not math.isnan(to_float(r.get(s))) else 0.0
                                 for r in cats] for s in p.statuses},
                            "Pseudo-labelling outcome per category"),
                        f"pseudo_{file_slug(p.rel)}.png", f"Pseudo-label statuses ({p.rel})",
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
        name = "gallery/" + file_slug(im.rel.rsplit(".", 1)[0]) + ".png"
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
        ran, parallel = bool(t.get("ran", True)), bool(t.get("parallel", False))
        rows.append([name, f"{w:.1f}" if ran else "–", f"{c:.1f}" if ran else "–",
                     ("ran, in parallel" if parallel else "ran") if ran else "up to date"])
        if ran and not parallel and not math.isnan(w):
            wall += w
        if ran and not parallel and not math.isnan(c):
            cpu += c
    bold = {len(rows)}
    rows.append(["total", f"{wall:.1f}", f"{cpu:.1f}", ""])
    return Table(["stage", "wall (s)", "CPU (s)", ""], rows, align="lrrl", bold_rows=bold, caption=(
        "Time of each stage of the last `kinmo train all` / `kinmo demo` call (CPU: user + system "
        "seconds of the process and its workers; stages up to date were skipped; stages run in "
        "parallel show their own worker's time, and the total counts them once, in their pool's row)."))


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


def _ancsh_synth_note(info: dict) -> Note:
    """What ``kinmo train all --ancsh-synth N`` added to ANCSH's training data."""
    without = info.get("without") or {}
    how = ("mixed into the batches (half of the draws)" if info.get("as") == "mix" else
           "pretrained on for the first half of the epochs, then fine-tuned on the real scans")
    text = (f"ANCSH's labelled scans include {info.get('objects')} generated objects (`kinmo synth`) of "
            f"each trained structure that `kinmo synth` makes, {how}; the test objects are real.")
    if without:
        text += " Trained without them: " + "; ".join(f"{k} ({why})" for k, why in sorted(without.items())) + "."
    return Note(text, "info")


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
            chart_block(lambda panels=panels: charts.bar_chart(panels, "Without vs with generated shapes"),
                        f"synth_extra_{file_slug(bt.rel)}.png", "Table 1 without vs with generated shapes",
                        "Table 1 means on the real test objects, without and with the generated shapes.",
                        blocks)
    # Table 2
    bt2, vt2 = art.table2, sub.table2
    if bt2 is not None and vt2 is not None:
        rows, marks, tally = [], {}, [0, 0]
        for s in [x for x in bt2.settings if x in vt2.settings]:
            for col in [c for c in bt2.metric_columns if c in vt2.metric_columns]:
                higher = "iou" in col.lower()
                _compare_rows(rows, marks, s, t2_label(col), bt2.value(s, "mean", col),
                              vt2.value(s, "mean", col), higher,
                              lambda label, x, col=col: t2_fmt(col, x), tally)
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

    sections = [Section("overview", "Overview", _overview(art))]
    t1: list[Block] = [Text(
        "Motion prediction on pre-segmented shapes (paper Table 1): motion-type accuracy, "
        "mobile-part detection and axis errors per category. Paper means: "
        + ", ".join(f"{m} {v['angle']:.2f}° / {v['distance']:.3f}"
                    for m, v in PAPER_TABLE1.items()) + ".")]
    if not art.table1:
        t1.append(_missing("table1"))
    for t in art.table1:
        t1 += table1_blocks(t)
    sections.append(Section("table1", "Table 1: pre-segmented shapes", t1))
    t2: list[Block] = [Text(
        "ANCSH on partial scans (paper Table 2): part rotation error and joint axis angle error "
        "per category. Paper means (rotation / axis angle): "
        + ", ".join(f"{s} {v['rotation']:.2f}° / {v['angle']:.2f}°"
                    for s, v in PAPER_TABLE2.items()) + ".")]
    if art.table2 is None:
        t2.append(_missing("table2"))
    else:
        t2 += table2_blocks(art.table2)
    t2 += table2_seed_blocks(art.table2_seeds)
    if art.ancsh_synth and art.table2 is not None:
        t2.append(_ancsh_synth_note(art.ancsh_synth))
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
