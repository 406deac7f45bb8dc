"""The report's Table 1 and Table 2 sections: a run's evaluations next to the paper's.

Table 1 (pre-segmented shapes, :mod:`kinmo.evaluate.pre_segmented`) against
:data:`~kinmo.report.collect.PAPER_TABLE1`; Table 2 (partial scans, :mod:`kinmo.ancsh.evaluate`)
against :data:`~kinmo.paper.PAPER_TABLE2` (Liu et al. 2023, Tables 1 and 2): the means with
their differences to the paper, per-model / per-category tables, and bar charts per category.
"""

from __future__ import annotations

import math
from pathlib import Path

import kinmo.report.charts as charts
from kinmo.report.blocks import chart_block, file_slug, fmt_value, paper_delta
from kinmo.report.collect import (
    PAPER_TABLE1,
    PAPER_TABLE2,
    Table1,
    Table2,
    paper_setting,
    to_float,
)
from kinmo.report.document import Block, Heading, Note, Table, Text

__all__ = ["T2_LABELS", "seed_spread", "t2_fmt", "t2_label", "table1_blocks", "table2_blocks", "table2_seed_blocks"]

_EDGE_PANELS = (("angle_edge", "angle"), ("dist_edge", "distance"))


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
        da, ma = paper_delta(a, ref.get("angle"))
        dd, md = paper_delta(d, ref.get("distance"), 3)
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


def table1_blocks(t: Table1) -> list[Block]:
    """The blocks of one Table 1 evaluation CSV: paper table, charts, per-model tables."""
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
    slug = file_slug(t.rel)
    if err_panels:
        chart_block(lambda: charts.bar_chart(err_panels,
                                             "Axis errors per category (lower is better)"),
                    f"table1_{slug}_errors.png", f"Table 1 axis errors per category ({t.rel})",
                    "Axis errors per category and model; hatched: the paper's means "
                    "(edge-level protocol).", blocks)
    acc_panels = [charts.BarPanel(h, groups, {m: [t.value(m, c, k) for c in groups]
                                              for m in t.models})
                  for k, h, hi in t.metrics if hi and k in keys]
    if acc_panels:
        chart_block(lambda: charts.bar_chart(acc_panels, "Type accuracy and mobile-part "
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


def t2_label(col: str) -> str:
    """The header of Table 2 metric column ``col`` (:data:`T2_LABELS`; the name itself else)."""
    base = col[:-5] if col.endswith("_mean") else col
    return T2_LABELS.get(base, base)


def t2_fmt(col: str, v: float) -> str:
    """A Table 2 value: translations and distances 4 decimals, else :func:`fmt_value`."""
    c = col.lower()
    if not math.isnan(v) and ("trans" in c or "dist" in c):
        return f"{v:.4f}"
    return fmt_value(col, v)


def _table2_paper(t: Table2) -> Table:
    cols = ["setting", "categories", t2_label(t.rotation_column), "paper rotation (deg)",
            "Δ rotation", t2_label(t.angle_column), "paper angle (deg)", "Δ angle"]
    rows: list[list[str]] = []
    marks: dict[tuple[int, int], str] = {}
    mapped = {s: paper_setting(s) for s in t.settings}
    for s in t.settings:
        ref = PAPER_TABLE2.get(mapped[s] or "", {})
        r, a = t.value(s, "mean", t.rotation_column), t.value(s, "mean", t.angle_column)
        dr, mr = paper_delta(r, ref.get("rotation"))
        da, ma = paper_delta(a, ref.get("angle"))
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
    cols = ["category", "setting", "frames", *[t2_label(c) for c in t.metric_columns]]
    rows, bold = [], set()
    for c in t.categories:
        for s in t.settings:
            e = t.entry(s, c)
            if e is not None:
                rows.append([c, s, fmt_value("frames", e["frames"]),
                             *[t2_fmt(m, e.get(m, math.nan)) for m in t.metric_columns]])
    for s in t.settings:
        bold.add(len(rows))
        rows.append(["mean", s, "–", *[t2_fmt(m, t.value(s, "mean", m))
                                      for m in t.metric_columns]])
    return Table(cols, rows, align="ll" + "r" * (len(cols) - 2), bold_rows=bold, caption=(
        "Means over the test scans of each category (over parts for part metrics, over joints "
        "for joint metrics); mean rows average the categories. Translation and axis distance "
        "in mesh units."))


def table2_blocks(t: Table2) -> list[Block]:
    """The blocks of the Table 2 evaluations: paper table, chart, per-category table."""
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
        panels.append(charts.BarPanel(t2_label(col), groups,
                                      {s: [t.value(s, c, col) for c in groups]
                                       for s in t.settings}, ref))
    if panels:
        chart_block(lambda: charts.bar_chart(panels, "Partial-scan metrics per category",
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


def seed_spread(values: list[float]) -> tuple[float, float, float, float]:
    """Mean, sample standard deviation, minimum and maximum of per-seed values (NaN left out;
    all NaN when none is left; standard deviation 0 for one value)."""
    v = [x for x in values if not math.isnan(x)]
    if not v:
        return (math.nan,) * 4  # type: ignore[return-value]
    m = sum(v) / len(v)
    sd = math.sqrt(sum((x - m) ** 2 for x in v) / (len(v) - 1)) if len(v) > 1 else 0.0
    return m, sd, min(v), max(v)


def table2_seed_blocks(seeds: dict[int, Table2]) -> list[Block]:
    """Table 2 over ANCSH seeds (``kinmo train all --ancsh-seeds K``, issue 38): per setting,
    each seed's raw mean over the categories (not permutation-matched) of the rotation and
    axis-angle errors, and their mean ± sample standard deviation (min–max) next to the
    paper's; per category, the rotation error's mean over the seeds (min–max); then
    semi-weakly's change against supervised per seed. Empty for < 2 seeds."""
    if len(seeds) < 2:
        return []
    order = list(seeds)
    first = seeds[order[0]]
    settings = [s for s in first.settings if all(s in t.settings for t in seeds.values())]
    cols = ["setting", "metric", *[f"seed {k}" for k in order], "mean ± sd", "min–max", "paper"]
    rows: list[list[str]] = []
    per: dict[tuple[str, str], list[float]] = {}
    for s in settings:
        ref = PAPER_TABLE2.get(paper_setting(s) or "", {})
        for key, label, col in (("rotation", "rotation err (deg)", first.rotation_column),
                                ("angle", "axis angle err (deg)", first.angle_column)):
            vals = [seeds[k].value(s, "mean", col) for k in order]
            per[(s, key)] = vals
            m, sd, lo, hi = seed_spread(vals)
            rows.append([s, label, *[fmt_value("rot", x) for x in vals],
                         f"{m:.2f} ± {sd:.2f}" if not math.isnan(m) else "–",
                         f"{lo:.2f}–{hi:.2f}" if not math.isnan(m) else "–",
                         f"{ref[key]:.2f}" if key in ref else "–"])
    blocks: list[Block] = [
        Heading(f"Table 2 over {len(order)} ANCSH seeds", 3),
        Table(cols, rows, align="ll" + "r" * (len(cols) - 2), caption=(
            "Each seed trains every setting again (its own training renders; the same split, "
            "pseudo-labels and test scans). Values: means over the categories evaluated in "
            "each seed, raw (not permutation-matched); sd: sample standard deviation over "
            "seeds."))]
    cats = [c for c in first.categories if all(c in t.categories for t in seeds.values())]
    crow: list[list[str]] = []
    for c in cats:
        cells = []
        for s in settings:
            m, _, lo, hi = seed_spread([seeds[k].value(s, c, first.rotation_column) for k in order])
            cells.append(f"{m:.2f} ({lo:.2f}–{hi:.2f})" if not math.isnan(m) else "–")
        crow.append([c, *cells])
    if crow:
        blocks.append(Table(["category", *[f"{s}: rotation err (deg)" for s in settings]], crow,
                            align="l" + "r" * len(settings), caption=(
                                "Per category: mean over the seeds (min–max) of the rotation error.")))
    if ("supervised", "rotation") in per and ("semi-weakly", "rotation") in per:
        rel = [100.0 * (w - u) / u if u and not (math.isnan(u) or math.isnan(w)) else math.nan
               for u, w in zip(per[("supervised", "rotation")], per[("semi-weakly", "rotation")])]
        m, sd, lo, hi = seed_spread(rel)
        blocks.append(Text("Semi-weakly against supervised, rotation error: "
                           + ", ".join(f"seed {k} {x:+.1f} %" for k, x in zip(order, rel))
                           + (f"; mean {m:+.1f} % ± {sd:.1f}" if not math.isnan(m) else "")
                           + " (paper: −26.3 %)."))
    return blocks
