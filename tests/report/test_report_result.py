"""``kinmo report`` on a run with ``pipeline_result.json``: the stages' outputs are read from
it, files the stages do not name are left out, and without it the folder is walked."""

from __future__ import annotations

import json
import shutil

from kinmo.report import write_report
from kinmo.report.collect import collect_run

from .report_fake_run import SHAPE_IDS, make_run, write_png


def _result(root, out: str) -> dict:
    """A ``pipeline_result.json`` naming the fake run's stages, its paths starting with ``out``
    (the run folder as ``kinmo train all`` was given it, from another working folder)."""
    stages = {
        "split": [f"{out}/split.json"], "prepare": [f"{out}/cache/labeled"],
        "gnn": [f"{out}/gnn_fine", f"{out}/gnn_coarse"], "axis": [f"{out}/axis"], "ranker": [f"{out}/ranker"],
        "table1": [f"{out}/eval"], "pseudo": [f"{out}/pseudo"], "ancsh": [f"{out}/ancsh/semi"],
        "table2": [f"{out}/ancsh/eval-laptop", f"{out}/ancsh/eval-storagefurniture"],
    }
    return {"out": out, "stages": stages, "split": f"{out}/split.json", "selector": "learned",
            "timings": {"train gnn (fine)": {"wall_s": 2.5, "cpu_s": 2.0, "ran": True}}}


def test_stages_of_pipeline_result_are_the_artefacts(tmp_path):
    root = tmp_path / "run"
    make_run(root)
    # files that look like artefacts but no stage names: the ranker's fold GNNs, a stray copy
    # of Table 1, a PNG in the cache
    shutil.copytree(root / "gnn_fine", root / "ranker" / "folds" / "fine_0")
    shutil.copy(root / "eval" / "table1.csv", tmp_path / "table1.csv")
    (root / "old").mkdir()
    shutil.copy(root / "eval" / "table1.csv", root / "old" / "table1.csv")
    write_png(root / "cache" / "labeled" / "thumb.png")

    walked = collect_run(root)
    assert not walked.from_result
    assert len(walked.curves) == 5 and len(walked.table1) == 2 and walked.predictions

    (root / "pipeline_result.json").write_text(json.dumps(_result(root, "runs/all")))
    art = collect_run(root)
    assert art.from_result
    assert [c.rel for c in art.curves] == ["gnn_fine/metrics.csv", "gnn_coarse/metrics.csv", "axis/metrics.csv",
                                           "ancsh/semi/metrics.csv"]
    assert [t.rel for t in art.table1] == ["eval/table1.csv"]
    assert [p.rel for p in art.pseudo] == ["pseudo/summary.csv"]
    assert not art.predictions  # `kinmo predict` is no stage of the pipeline
    assert art.table2 is not None and sorted(art.table2.categories) == ["Laptop", "StorageFurniture"]
    # the gallery: the Table 1 renders only (not the cache's PNG, nor kinmo predict's)
    assert {im.rel.split("/")[0] for im in art.images} == {"eval"} and len(art.images) == 2 * len(SHAPE_IDS)
    assert art.timings["train gnn (fine)"]["wall_s"] == 2.5 and not art.problems

    # absolute paths of another place (the run folder moved) are found below the run too
    (root / "pipeline_result.json").write_text(json.dumps(_result(root, "/somewhere/else/run")))
    assert [c.rel for c in collect_run(root).curves][:1] == ["gnn_fine/metrics.csv"]

    rep = write_report(root)
    md = rep.markdown.read_text(encoding="utf-8")
    assert "outputs of the stages named in pipeline_result.json" in md
    assert "old/table1.csv" not in md and "folds" not in md


def test_damaged_or_stageless_result_falls_back_to_walking(tmp_path):
    root = tmp_path / "run"
    make_run(root)
    (root / "pipeline_result.json").write_text("{not json")
    art = collect_run(root)
    assert not art.from_result and len(art.curves) == 4 and art.predictions
    assert art.problems == [("pipeline_result.json", art.problems[0][1])]
    assert "cannot read" in art.problems[0][1]
    # timings only (an older pipeline): walked, the times still shown
    (root / "pipeline_result.json").write_text(json.dumps({"timings": {"report": {"wall_s": 1.0, "cpu_s": 1.0}}}))
    art = collect_run(root)
    assert not art.from_result and len(art.curves) == 4 and art.timings == {"report": {"wall_s": 1.0, "cpu_s": 1.0}}
