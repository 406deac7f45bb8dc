"""Table 2 metrics: ground truth fed as predictions scores zero, axis sign ambiguity, angle
wrapping, perfect per-point predictions through the post-processing, and the end-to-end
``kinmo train ancsh`` + ``kinmo eval --category`` commands."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from kinmo.ancsh.config import preset
from kinmo.ancsh.dataset import frame_sample, scan_category
from kinmo.ancsh.evaluate import (
    FrameTruth,
    find_runs,
    frame_errors,
    frame_truth,
    ground_truth_estimate,
    ground_truth_predictions,
    summarize,
    table2_markdown,
)
from kinmo.ancsh.interchangeable import interchangeable_groups, matched_frame_errors
from kinmo.ancsh.postprocess import JointEstimate, estimate
from kinmo.ancsh.scans import render_objects
from kinmo.render.dataset import load_frame

CABINET = "45463"  # two revolute doors
POT = "100028"  # prismatic lid


@pytest.fixture(scope="module")
def frames(tmp_path_factory, mobility_root: Path):
    tmp = tmp_path_factory.mktemp("ancsh_eval")
    cfg = preset("quick", image_size=112, render_workers=1, seed=11)
    out = {}
    for cat_name, oid in (("StorageFurniture", CABINET), ("KitchenPot", POT)):
        cat = scan_category(mobility_root, cat_name)
        files, failed = render_objects({oid: cat.folders[oid]}, tmp / "o" / oid, tmp / "s", 1, cfg, progress=False)
        assert not failed
        out[oid] = (cat, load_frame(files[0]), files[0])
    return out


def _flip(truth: FrameTruth, j: int, state: bool) -> FrameTruth:
    est = ground_truth_estimate(truth)
    jj = est.joints[j]
    est.joints[j] = JointEstimate(jj.origin, -jj.direction, -jj.state if state else jj.state, jj.type)
    return est


@pytest.mark.exactdata
@pytest.mark.parametrize("oid", [CABINET, POT])
def test_ground_truth_as_prediction_scores_zero(frames, oid):
    cat, fr, _ = frames[oid]
    truth = frame_truth(fr, cat.parts[oid])
    own = cat.parts[oid].structure  # the object's structure (not always its category's most common)
    assert len(truth.parts) == own.n_parts and len(truth.joints) == own.n_joints
    e = frame_errors(ground_truth_estimate(truth), truth)
    assert np.abs(e.rotation_deg).max() < 1e-4
    assert np.abs(e.translation).max() < 1e-9
    np.testing.assert_allclose(e.iou, 1.0, atol=1e-6)
    assert np.abs(e.state).max() < 1e-9 and np.abs(e.angle_deg).max() < 1e-6
    for t, d in zip(truth.joints, e.distance):
        assert (d < 1e-9) if t.type == "revolute" else np.isnan(d)
    # the reversed axis with the negated state is the same joint
    e2 = frame_errors(_flip(truth, 0, state=True), truth)
    assert e2.state[0] < 1e-9 and e2.angle_deg[0] < 1e-6
    # reversing the axis alone is a state error of twice the state
    e3 = frame_errors(_flip(truth, 0, state=False), truth)
    s = abs(truth.joints[0].state)
    want = np.degrees(2 * s) if truth.joints[0].type == "revolute" else 2 * s
    assert e3.state[0] == pytest.approx(want, rel=1e-6, abs=1e-9)


@pytest.mark.exactdata
def test_revolute_state_errors_wrap_around(frames):
    cat, fr, _ = frames[CABINET]
    truth = frame_truth(fr, cat.parts[CABINET])
    est = ground_truth_estimate(truth)
    j = est.joints[0]
    est.joints[0] = JointEstimate(j.origin, j.direction, j.state + 2 * np.pi + np.radians(3), j.type)
    assert frame_errors(est, truth).state[0] == pytest.approx(3.0, abs=1e-6)


@pytest.mark.exactdata
@pytest.mark.parametrize("oid", [CABINET, POT])
def test_perfect_per_point_predictions_recover_poses_and_joints(frames, oid):
    cat, fr, f = frames[oid]
    own = cat.parts[oid].structure  # the object's structure (not always its category's most common)
    s = frame_sample(fr, cat.parts[oid], own, cache_points=1024, path=f)
    truth = frame_truth(fr, cat.parts[oid])
    est = estimate(s.points, ground_truth_predictions(s, own), own)
    e = frame_errors(est, truth)
    seen = np.array([p.n_points >= 30 for p in truth.parts])
    assert e.rotation_deg[seen].max() < 1.0
    assert e.translation[seen].max() < 0.01 * truth.parts[0].scale
    assert e.angle_deg.max() < 1.0
    assert e.iou[0] > 0.5


@pytest.mark.exactdata
def test_swapped_cabinet_doors_are_matched_back(frames):
    """The two revolute doors of a real cabinet frame: the perfect estimate with the doors
    swapped has large raw errors and zero permutation-matched ones."""
    cat, fr, _ = frames[CABINET]
    parts = cat.parts[CABINET]
    truth = frame_truth(fr, parts)
    groups = interchangeable_groups(parts.structure)
    assert groups == [(1, 2)]
    est = ground_truth_estimate(truth)
    est.parts[1], est.parts[2] = est.parts[2], est.parts[1]
    est.joints[0], est.joints[1] = est.joints[1], est.joints[0]
    raw = frame_errors(est, truth)
    m, perm = matched_frame_errors(est, truth, groups)
    assert perm.tolist() == [0, 2, 1]
    assert raw.translation[1:].min() > 0.05 * truth.parts[0].scale and m.translation.max() < 1e-9
    assert m.rotation_deg.max() < 1e-4 and m.angle_deg.max() < 1e-6 and m.state.max() < 1e-9
    # the unswapped estimate is left alone
    m0, perm0 = matched_frame_errors(ground_truth_estimate(truth), truth, groups)
    assert perm0.tolist() == [0, 1, 2] and m0.translation.max() < 1e-9


@pytest.mark.exactdata
def test_table_rows_and_markdown(frames):
    cat, fr, _ = frames[POT]
    truth = frame_truth(fr, cat.parts[POT])
    e = frame_errors(ground_truth_estimate(truth), truth)
    row = summarize("semi-weakly", "run", [e, e], cat.structure.joint_types,
                    {"labeled_scans": 4, "pseudo_labeled_scans": 6, "pseudo_target_scans": 0})
    assert row.frames == 2 and row.mean("iou") == pytest.approx(1.0) and np.isnan(row.mean("distance"))
    md = table2_markdown([row], cat.category, cat.structure)
    assert "| semi-weakly | 2 | 4 / 6 / 0 |" in md and "KitchenPot" in md and "0<P-1" in md


@pytest.mark.exactdata
def test_train_and_eval_commands_end_to_end(mobility_root, tmp_path, monkeypatch):
    from kinmo.cli import app

    data = tmp_path / "mobility"
    data.mkdir()
    for oid in ["10040", "10306", "9968", "11405"]:  # Laptop (0<R-1)
        (data / oid).symlink_to(mobility_root / oid, target_is_directory=True)
    monkeypatch.chdir(tmp_path)
    for var in ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):  # the commands set them by default
        monkeypatch.setenv(var, "1")
    runner = CliRunner()
    common = ["--data", str(data), "--epochs", "1", "--steps-per-epoch", "2", "--frames-per-object", "1",
              "--batch-size", "2", "--workers", "1", "--threads", "1", "-q"]
    res = runner.invoke(app, ["train", "ancsh", "--category", "laptop", "--setting", "supervised", *common])
    assert res.exit_code == 0, res.output
    run = tmp_path / "runs" / "ancsh" / "laptop" / "supervised"
    assert "trained ANCSH (quick, supervised) for Laptop [0<R-1]" in res.output and "run folder" in res.output
    for name in ("model.pt", "config.json", "split.json", "metrics.csv", "data.json"):
        assert (run / name).is_file(), name
    cfg = json.loads((run / "config.json").read_text())
    assert cfg["category"] == "Laptop" and cfg["setting"] == "supervised"
    assert find_runs([tmp_path / "runs" / "ancsh"], "LAPTOP") == [run]
    assert find_runs([tmp_path / "runs" / "ancsh"], "bucket") == []

    res = runner.invoke(app, ["eval", "--category", "Laptop", "--frames", "2", "-q"])
    assert res.exit_code == 0, res.output
    out = tmp_path / "runs" / "ancsh" / "laptop" / "eval-laptop"
    rows = list(csv.DictReader((out / "table2.csv").open()))
    split = json.loads((run / "split.json").read_text())
    assert [r["setting"] for r in rows] == ["supervised"]
    assert int(rows[0]["frames"]) == 2 * len(split["test"])
    assert 0 <= float(rows[0]["iou_mean"]) <= 1 and float(rows[0]["angle_deg_mean"]) <= 90
    assert "| supervised |" in (out / "table2.md").read_text()
    assert "Table 2" in res.output
    info = json.loads((out / "eval.json").read_text())
    assert info["symmetry_aware"] is True and info["symmetric_parts"] == {"10040": [None, None]}
    # no interchangeable parts in 0<R-1: the matched columns repeat the raw ones, nothing swapped
    assert info["interchangeable_parts"] == {"0<R-1": []}
    assert [m["swapped_scans"] for m in info["permutation_matched"]] == [0]
    for n in ("rotation_deg", "translation", "angle_deg", "distance"):
        assert rows[0][f"{n}_matched_mean"] == rows[0][f"{n}_mean"], n
    assert rows[0]["swapped_scans"] == "0"
    assert "no interchangeable parts" in (out / "table2.md").read_text()
    # --no-symmetry: recorded, and identical numbers for a category without symmetric parts
    res = runner.invoke(app, ["eval", "--category", "Laptop", "--frames", "2", "-q", "--no-symmetry",
                              "--out", str(tmp_path / "plain"), "--scans", str(out / "scans")])
    assert res.exit_code == 0, res.output
    assert json.loads((tmp_path / "plain" / "eval.json").read_text())["symmetry_aware"] is False
    assert list(csv.DictReader((tmp_path / "plain" / "table2.csv").open())) == rows
    # the subcommand of the other evaluation is not shadowed; a bad category is a clear error
    res = runner.invoke(app, ["eval", "--category", "spaceship", "--runs", str(run), "-q"])
    assert res.exit_code == 1 and "no ANCSH run of category 'spaceship'" in res.output
    res = runner.invoke(app, ["eval", "pre-segmented", "--help"])
    assert res.exit_code == 0 and "--model" in res.output
