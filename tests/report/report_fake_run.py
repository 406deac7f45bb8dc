"""A small but realistic pipeline run folder, written by kinmo's own writers where cheap.

Layout (as a full pipeline writes it)::

    run/
      gnn_fine/   config.json, metrics.csv          (kinmo train gnn, METRIC_COLUMNS)
      gnn_coarse/ config.json, metrics.csv
      axis/       config.json, metrics.csv          (kinmo train axis)
      eval/       table1.csv, table1.md, shapes.csv (kinmo.evaluate.pre_segmented.write_report)
      eval/renders/<model>/<id>.png                 (eval --render)
      pseudo/     summary.csv, shapes.csv           (kinmo.pseudo_label)
      predict/    predictions.csv, <id>/prediction.png
      ancsh/semi/ config.json, metrics.csv          (kinmo train ancsh, two stages)
      ancsh/eval-<category>/ table2.csv, table2.md, frames.csv, eval.json
                                                    (kinmo eval --category C, Table 2)
"""

from __future__ import annotations

import json
import math
from pathlib import Path

#: Categories and shapes per category of the fake evaluation.
CATEGORIES = ("Door", "StorageFurniture", "Table")
SHAPE_IDS = ("7119", "45132", "19179")

#: Partial-scan evaluations: category -> (joint types, {setting: (rotation errors of the
#: parts, axis angle errors of the joints)}); other errors follow from these.
TABLE2 = {
    "Laptop": (("revolute",), {"supervised": ((14.5, 31.25), (3.5,)),
                               "semi-weakly": ((10.25, 22.5), (2.25,))}),
    "StorageFurniture": (("revolute", "prismatic"),
                         {"supervised": ((20.0, 28.5, 22.75), (3.0, 2.5)),
                          "semi": ((21.5, 30.0, 24.25), (3.25, 3.75)),
                          "semi-weakly": ((12.5, 19.75, 16.0), (2.5, 1.75))}),
}


def table2_means(category: str, setting: str) -> tuple[float, float]:
    """Mean rotation and axis angle errors of a setting on a category (over parts / joints)."""
    rot, ang = TABLE2[category][1][setting]
    return sum(rot) / len(rot), sum(ang) / len(ang)


def _shape_evals(model: str, offset: float):
    from kinmo.evaluate.pre_segmented import ShapeEval

    rows = []
    for k, (cat, sid) in enumerate(zip(CATEGORIES, SHAPE_IDS)):
        r = ShapeEval(sid, cat, n_edges=10 + k, edges_correct=8 + k, n_moving_edges=4,
                      moving_edges_correct=3, angle_edge=[offset + 2.0 * k, offset + 1.0],
                      dist_edge=[0.05 * (k + 1) + offset / 100], n_pred=3, n_true=3 + (k == 2),
                      n_matched=2 + (k == 0), joint_type_correct=2,
                      angle_joint=[offset + 0.5 * k], dist_joint=[0.01 * (k + 2)],
                      matches=[(1, 1, 0.9)])
        rows.append(r)
    return rows


def write_table1(out: Path):
    """Evaluate fake shape results with the real aggregation and writer; returns the report."""
    from kinmo.evaluate.pre_segmented import build_report, write_report

    report = build_report({"GNN_coarse": _shape_evals("GNN_coarse", 11.0),
                           "GNN_fine": _shape_evals("GNN_fine", 7.5),
                           "OBB_fine": _shape_evals("OBB_fine", 3.25)})
    write_report(report, out)
    return report


def write_gnn_metrics(run: Path, types: str, epochs: int = 6) -> None:
    """``metrics.csv`` + ``config.json`` as ``kinmo train gnn`` writes them."""
    from kinmo.io import write_json, write_text
    from kinmo.train.config import preset
    from kinmo.train.gnn import METRIC_COLUMNS, _metrics_csv

    cfg = preset("quick", types=types, epochs=epochs)
    write_json(run / "config.json", cfg.model_dump())
    rows = []
    for e in range(epochs):
        d = math.exp(-0.4 * e)
        rows.append({"epoch": e + 1, "lr": 2e-3 * d, "loss": 2.0 * d + 0.3, "loss_type": 1.2 * d,
                     "loss_dir": 0.5 * d, "loss_pos": 0.3 * d, "train_acc": 0.9 - 0.5 * d,
                     "test_loss": 2.2 * d + 0.4, "test_acc": 0.85 - 0.45 * d,
                     "test_moving_recall": 0.8 - 0.4 * d, "test_angle_deg": 40 * d + 6,
                     "test_pos_dist": 0.3 * d + 0.05, "seconds": 1.5})
    assert set(rows[0]) == set(METRIC_COLUMNS)
    write_text(run / "metrics.csv", _metrics_csv(rows))


def write_axis_metrics(run: Path, epochs: int = 4) -> None:
    """``metrics.csv`` as ``kinmo train axis`` writes it."""
    from kinmo.io import write_json, write_text
    from kinmo.refine.train import METRIC_COLUMNS, _metrics_csv

    write_json(run / "config.json", {"epochs": epochs, "seed": 0})
    rows = [{"epoch": e + 1, "train_loss": 0.7 / (e + 1), "train_acc": 0.6 + 0.08 * e,
             "val_loss": 0.75 / (e + 1), "val_acc": 0.55 + 0.08 * e,
             "val_select_acc": 0.4 + 0.1 * e, "val_select_chance": 0.2,
             "val_select_coverage": 0.9, "lr": 1e-3, "seconds": 2.0} for e in range(epochs)]
    assert set(rows[0]) == set(METRIC_COLUMNS)
    write_text(run / "metrics.csv", _metrics_csv(rows))


def write_pseudo(out: Path) -> None:
    """``summary.csv`` and ``shapes.csv`` with kinmo.pseudo_label's own writer."""
    from kinmo.pseudo_label import ShapeRecord, _write_tables

    recs = [ShapeRecord("a1", "Door", "kept", n_moving=1, min_score=0.9),
            ShapeRecord("a2", "Door", "below_threshold", "score 0.2 < 0.5", 1, 0.2),
            ShapeRecord("a3", "Table", "kept", n_moving=2, min_score=0.8),
            ShapeRecord("a4", "Table", "kept", n_moving=3, min_score=0.7),
            ShapeRecord("a5", "Table", "no_moving_joint", "no moving joint"),
            ShapeRecord("a6", "StorageFurniture", "failed", "bad mesh")]
    out.mkdir(parents=True, exist_ok=True)
    _write_tables(out, recs)


def write_table2(root: Path) -> None:
    """``eval-<category>/`` folders as ``kinmo eval --category C`` writes them: table2.csv and
    table2.md (kinmo.ancsh.evaluate's writers), frames.csv (per frame) and eval.json."""
    import numpy as np
    from kinmo.ancsh.dataset import category_key
    from kinmo.ancsh.evaluate import FrameErrors, _table2_csv, summarize, table2_markdown
    from kinmo.ancsh.structure import KinematicStructure
    from kinmo.io import write_json, write_text

    for cat, (types, settings) in TABLE2.items():
        out = root / f"eval-{category_key(cat)}"
        structure = KinematicStructure((-1, *([0] * len(types))), types)
        rows = []
        for setting, (rot, ang) in settings.items():
            k = len(rot)
            # two frames whose errors average to the tabulated values
            errs = [FrameErrors(np.asarray(rot) + d, np.full(k, 0.05 + d / 100),
                                np.full(k, 0.6 - d / 100), np.full(len(ang), 4.0 + d),
                                np.asarray(ang) + d / 10,
                                np.array([0.08 + d / 100 if t == "revolute" else np.nan
                                          for t in types]))
                    for d in (-1.0, 1.0)]
            # permutation-matched errors, as kinmo eval writes them beside the raw ones
            matched = [FrameErrors(e.rotation_deg - 5.0, e.translation / 2, e.iou, e.state, e.angle_deg / 2,
                                   e.distance / 2) for e in errs]
            rows.append(summarize(setting, str(root / setting), errs, types,
                                  {"labeled_scans": 40, "pseudo_labeled_scans": 20}, matched, 1))
        write_text(out / "table2.csv", _table2_csv(rows, structure.n_parts, structure.n_joints))
        write_text(out / "table2.md", table2_markdown(rows, cat, structure))
        write_text(out / "frames.csv", "setting,run,id,frame,rotation_deg_0,angle_deg_0\n"
                   "supervised,r,100,0,12.5,3.0\n")
        write_json(out / "eval.json", {"category": cat, "structure": structure.signature(),
                                       "scans": 2, "runs": [str(root / s) for s in settings]})


def write_ancsh_metrics(run: Path) -> None:
    """``metrics.csv`` + ``config.json`` of a two-stage ``kinmo train ancsh --setting semi``."""
    from kinmo.ancsh.train import METRIC_COLUMNS, _metrics_csv
    from kinmo.io import write_json, write_text

    write_json(run / "config.json", {"category": "Laptop", "setting": "semi", "preset": "quick",
                                     "seed": 0, "width": 64})
    rows = []
    for stage, n in (("supervised", 4), ("semi", 3)):
        for e in range(n):
            row = {c: 0.1 for c in METRIC_COLUMNS}
            row.update(stage=stage, epoch=e + 1, lr=1e-3, loss=1.5 / (len(rows) + 1),
                       seg_acc=0.5 + 0.05 * len(rows), scans=40, seconds=3.0)
            rows.append(row)
    write_text(run / "metrics.csv", _metrics_csv(rows))


def write_png(path: Path, colour: str = "tab:blue", label: str = "") -> None:
    """A small real PNG (matplotlib)."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    path.parent.mkdir(parents=True, exist_ok=True)
    fig, ax = plt.subplots(figsize=(2, 2))
    ax.add_patch(plt.Rectangle((0.2, 0.2), 0.6, 0.5, color=colour))
    ax.arrow(0.2, 0.2, 0.0, 0.6, width=0.02, color="k")
    ax.set_title(label, fontsize=8)
    ax.set_xlim(0, 1)
    ax.set_ylim(0, 1)
    fig.savefig(path, dpi=60)
    plt.close(fig)


def write_predictions(out: Path) -> None:
    """``predictions.csv`` of kinmo predict (its columns) and a rendered prediction."""
    out.mkdir(parents=True, exist_ok=True)
    (out / "predictions.csv").write_text(
        "id,status,n_links,n_moving,error\n7119,ok,3,2,\n45132,ok,2,1,\n"
        "19179,failed,0,0,19179/result.json: missing\n")
    write_png(out / "7119" / "prediction.png", "tab:green", "7119")


def make_run(root: Path) -> dict:
    """Write the whole fake run under ``root``; returns what the tests check against."""
    write_gnn_metrics(root / "gnn_fine", "fine")
    write_gnn_metrics(root / "gnn_coarse", "coarse")
    write_axis_metrics(root / "axis")
    report = write_table1(root / "eval")
    for k, model in enumerate(("GNN_fine", "OBB_fine")):
        for sid in SHAPE_IDS:
            write_png(root / "eval" / "renders" / model / f"{sid}.png", f"C{k}", f"{model} {sid}")
    write_pseudo(root / "pseudo")
    write_table2(root / "ancsh")
    write_ancsh_metrics(root / "ancsh" / "semi")
    write_predictions(root / "predict")
    (root / "synth").mkdir()
    (root / "synth" / "objects.json").write_text(json.dumps({"n": 3}))
    return {"table1": report, "n_curves": 4, "n_gallery": 7}
