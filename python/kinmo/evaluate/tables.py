"""The tables of the evaluation on pre-segmented shapes (Liu et al. 2023, Table 1).

An :class:`~kinmo.evaluate.shape_metrics.EvalReport` as a long-format CSV
(:func:`report_csv`), Markdown tables with the paper's means (:func:`report_markdown`), the
files of ``kinmo eval pre-segmented`` (:func:`write_report`: ``table1.csv``, ``table1.md``,
``shapes.csv``, written atomically) and rich tables in the terminal (:func:`print_report`).
"""

from __future__ import annotations

import csv
import io
import math
from pathlib import Path

from kinmo.evaluate.cells import cell
from kinmo.evaluate.shape_metrics import METRICS, EvalReport, nanmean
from kinmo.io import write_text

__all__ = ["PAPER_MEANS", "SHORT", "print_report", "report_csv", "report_markdown",
           "write_report"]

#: Short column names of the printed (terminal) tables.
SHORT = {
    "edge_acc": "acc", "moving_edge_acc": "acc mov", "joint_type_acc": "acc jnt",
    "precision": "prec", "recall": "rec", "angle_edge": "ang e°", "dist_edge": "dist e",
    "angle_joint": "ang j°", "dist_joint": "dist j",
    "range_iou_hinge": "rIoU h", "range_ok_hinge": "r≥.5 h", "range_end_hinge": "rEnd h°",
    "range_iou_slider": "rIoU s", "range_ok_slider": "r≥.5 s", "range_end_slider": "rEnd s",
    "range_cont_acc": "cont",
}

#: The paper's Table 1 means of its GNN (fine / coarse types): angle error (degrees) and
#: distance.
PAPER_MEANS = {
    "GNN_fine": {"angle": 8.93, "distance": 0.205},
    "GNN_coarse": {"angle": 12.23, "distance": 0.220},
    "OBB_fine": {"angle": 4.78, "distance": 0.112},
}


def _fmt(key: str, v: float) -> str:
    """A Table 1 figure as a cell (:func:`~kinmo.evaluate.cells.cell`): angles 2 decimals, the
    hinge range end 1, everything else 3; a mean over nothing an en dash."""
    return cell(v, 2 if key.startswith("angle") else 1 if key == "range_end_hinge" else 3)


def report_csv(report: EvalReport) -> str:
    """Long-format CSV: ``model, category, n_shapes, n_joints, <metrics>`` (empty for NaN)."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    keys = [k for k, _, _ in METRICS]
    w.writerow(["model", "category", "n_shapes", "n_joints", *keys])
    for m in report.models:
        for c in [*report.categories, "mean", "all"]:
            row = report.table.get((m, c))
            if row is None:
                continue
            vals = ["" if (isinstance(row[k], float) and math.isnan(row[k])) else f"{row[k]:.6g}"
                    for k in keys]
            w.writerow([m, c, int(row["n_shapes"]), int(row["n_joints"]), *vals])
    return buf.getvalue()


def report_markdown(report: EvalReport, paper: bool = True) -> str:
    """One Markdown table per metric: categories as rows, models as columns.

    With ``paper``, a final table sets the models' mean angle and distance errors next to
    the paper's (:data:`PAPER_MEANS`).
    """
    lines: list[str] = []
    cats = [*report.categories, "mean", "all"]
    for key, header, higher in METRICS:
        lines += [f"### {header} ({'higher' if higher else 'lower'} is better)", ""]
        lines.append("| category | n | " + " | ".join(report.models) + " |")
        lines.append("|---|---:|" + "---:|" * len(report.models))
        for c in cats:
            n = report.table.get((report.models[0], c), {}).get("n_shapes", 0)
            cells = [_fmt(key, report.table[(m, c)][key]) if (m, c) in report.table else "–"
                     for m in report.models]
            name = f"**{c}**" if c in ("mean", "all") else c
            lines.append(f"| {name} | {int(n)} | " + " | ".join(cells) + " |")
        lines.append("")
    if paper:
        lines += ["### Means next to the paper (Liu et al. 2023, Table 1)", "",
                  "| model | rows | angle err edges (deg) | angle err joints (deg) "
                  "| dist edges (/diag) | line dist joints (/diag) | paper angle (deg) "
                  "| paper distance |",
                  "|---|---|---:|---:|---:|---:|---:|---:|"]
        for m in report.models:
            ref = PAPER_MEANS.get(m, {})
            for agg in ("mean", "all"):
                row = report.table[(m, agg)]
                lines.append(
                    f"| {m} | {agg} | {_fmt('angle', row['angle_edge'])} "
                    f"| {_fmt('angle', row['angle_joint'])} | {_fmt('dist', row['dist_edge'])} "
                    f"| {_fmt('dist', row['dist_joint'])} | {ref.get('angle', '–')} "
                    f"| {ref.get('distance', '–')} |"
                )
        lines.append("")
    return "\n".join(lines)


def write_report(report: EvalReport, out: str | Path) -> dict[str, Path]:
    """Write ``table1.csv``, ``table1.md`` and ``shapes.csv`` (per shape) into ``out``."""
    out = Path(out)
    write_text(out / "table1.csv", report_csv(report))
    write_text(out / "table1.md", report_markdown(report))
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["model", "shape_id", "category", "n_edges", "edges_correct", "n_true", "n_pred",
                "n_matched", "angle_joint", "dist_joint"])
    for m, rows in report.shapes.items():
        for r in rows:
            w.writerow([m, r.shape_id, r.category, r.n_edges, r.edges_correct, r.n_true,
                        r.n_pred, r.n_matched, _fmt("angle", nanmean(r.angle_joint)),
                        _fmt("dist", nanmean(r.dist_joint))])
    write_text(out / "shapes.csv", buf.getvalue())
    return {"csv": out / "table1.csv", "markdown": out / "table1.md", "shapes": out / "shapes.csv"}


def print_report(report: EvalReport, console) -> None:
    """Print one rich table per model (categories as rows, metrics as columns)."""
    from rich.table import Table

    for m in report.models:
        t = Table(title=f"{m}: pre-segmented motion prediction (Table 1)",
                  caption="acc: type accuracy over sibling edges / moving edges / matched joints; "
                          "prec, rec: mobile-part detection (IoU >= 0.5); ang: axis angle error "
                          "(deg); dist: axis distance / bbox diagonal; e: edges, j: joints; rIoU: "
                          "joint range IoU, r≥.5: share of ranges with IoU >= 0.5, rEnd: median "
                          "worst end-point error (h: hinges, degrees; s: sliders, / true travel), "
                          "cont: continuous-or-not accuracy of hinges (matched joints of the right "
                          "type within 20° of the true axis)")
        t.add_column("category", no_wrap=True)
        t.add_column("n", justify="right")
        for key, _, _ in METRICS:
            t.add_column(SHORT[key], justify="right", no_wrap=True)
        for c in [*report.categories, "mean", "all"]:
            row = report.table.get((m, c))
            if row is None:
                continue
            t.add_row(c if c not in ("mean", "all") else f"[bold]{c}[/]", str(int(row["n_shapes"])),
                      *[_fmt(k, row[k]) for k, _, _ in METRICS])
        console.print(t)
