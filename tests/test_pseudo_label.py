"""Pseudo-labelling PartNet shapes into PartNet-Mobility folders (kinmo.pseudo_label)."""

from __future__ import annotations

import csv
import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch
from conftest import write_untrained_models

from kinmo.data.model import FINE_INDEX, JointType, ShapeFormat
from kinmo.data.readers import read_shape
from kinmo.pseudo_label import PseudoLabelConfig, pseudo_label_dataset
from kinmo.ranges import RangeEntry, RangePrior
from kinmo.refine.config import RefineConfig
from kinmo.render.scene import Scene, sample_joint_state

torch.set_num_threads(1)

#: Small real PartNet shapes (2-4 meshes each).
SHAPES = ("100664", "7304", "12249")


@pytest.fixture(scope="module")
def runs(tmp_path_factory) -> tuple[Path, Path]:
    """An (untrained) motion-GNN run and axis-network run, saved by the project's own savers."""
    return write_untrained_models(tmp_path_factory.mktemp("runs"))


@pytest.fixture(scope="module")
def data(partnet_root: Path, tmp_path_factory) -> Path:
    """A dataset folder of links to a few real PartNet shapes (the data is never copied)."""
    d = tmp_path_factory.mktemp("partnet")
    for s in SHAPES:
        (d / s).symlink_to(partnet_root / s)
    return d


def _hinge_on_largest_leaf(monkeypatch, second: str = "R_V_S"):
    """Make the GNN predict: the first sibling edge of the deepest-first order is a hinge.
    A run saved in a folder named ``check`` (the second model) predicts type ``second``
    there instead, with the same axis."""
    import kinmo.inference.gnn
    from kinmo.mobility_tree import EdgePrediction
    from kinmo.refine.selector import GNNPriors

    def fake(run, graphs, batch_size=8):
        out = []
        for g in graphs:
            e = len(g.sibling_edges)
            p = np.zeros((e, 10))
            p[:, FINE_INDEX["None"]] = 1.0
            d = np.tile([0.0, 1.0, 0.0], (e, 1))
            o = np.zeros((e, 3))
            if e:
                i = int(g.sibling_edges[0, 0])
                p[0] = 0.0
                p[0, FINE_INDEX[second if "check" in Path(run.path).parts else "R_V_S"]] = 1.0
                o[0] = g.obb_center[i] + g.obb_half_extents[i] @ np.abs(g.obb_axes[i])
            out.append(EdgePrediction(p, d, o))
        return out

    def fake_with_priors(run, graphs, batch_size=8, turns="unnamed"):
        out = fake(run, graphs, batch_size)
        names = tuple(run.config.model.type_names)
        return out, [GNNPriors(e.probs.copy(), names) for e in out]

    monkeypatch.setattr(kinmo.inference.gnn, "infer_edges_with_priors", fake_with_priors)


def _hinge_prior(folder: Path) -> Path:
    """A range prior whose only group is every hinge: 0 to 135 degrees (issue 35)."""
    f = folder / "ranges.json"
    RangePrior([RangeEntry("hinge", None, None, 10, 0.0, 0.0, 135.0)]).save(f)
    return f


@pytest.mark.exactdata
def test_kept_shapes_read_back_as_partnet_mobility_objects(data, runs, tmp_path, monkeypatch):
    _hinge_on_largest_leaf(monkeypatch)
    out = tmp_path / "out"
    cfg = PseudoLabelConfig(threshold=0.0, refine=RefineConfig(ranges=str(_hinge_prior(tmp_path))))
    res = pseudo_label_dataset(data, *runs, out, cfg, progress=False)
    assert [r.status for r in res.records] == ["kept"] * len(SHAPES), res.records
    for rec in res.records:
        folder = out / rec.id
        shape = read_shape(folder)
        assert shape.format is ShapeFormat.PARTNET_MOBILITY
        src = read_shape(data / rec.id)
        assert shape.category == src.category
        assert set(shape.hierarchy.nodes) == set(src.hierarchy.nodes)
        moving = [lk for lk in shape.links if lk.joint.is_moving]
        assert len(moving) == 1 and moving[0].joint.type is JointType.HINGE
        assert abs(moving[0].joint.direction[1]) > 0.7  # a vertical hinge, as predicted
        # the predicted range: the prior's 0-135 degrees, clipped by the sweep where the part
        # would pass through the rest of the shape; never the old constant 0-90
        lo, hi = moving[0].joint.limit
        assert 0.0 <= lo < hi <= 135.0 and (lo, hi) != (0.0, 90.0)
        # ANCSH's scans of this shape sample states inside that range only
        with Scene(shape) as scene:
            rng = np.random.default_rng(0)
            (j,) = scene.joints
            sign = float(np.sign(np.dot(j.direction, moving[0].joint.direction)))
            for _ in range(200):
                (_, angle), = sample_joint_state(scene.joints, rng).values()
                assert lo - 1e-6 <= np.degrees(sign * angle) <= hi + 1e-6
        for name in src.hierarchy.mesh_names(src.hierarchy.root):
            p = folder / "textured_objs" / f"{name}.obj"  # self-contained: a hard link or a copy
            assert not p.is_symlink() and p.read_bytes() == src.mesh_path(name).read_bytes()
        assert (folder / "result.json").read_bytes() == (data / rec.id / "result.json").read_bytes()
        assert (folder / "semantics.txt").read_text().count("link_") == len(shape.links)
        urdf = (folder / "mobility.urdf").read_text()
        assert 'type="revolute"' in urdf and "textured_objs/" in urdf
        scores = json.loads((folder / "scores.json").read_text())
        assert scores["threshold"] == 0.0 and len(scores["joints"]) == 1
        j = scores["joints"][0]
        assert 0.0 <= j["score"] <= 1.0 and j["type"] == "R_V_S" and j["candidate"] == "edge"
        assert j["line_confidence"] == pytest.approx(0.5 * j["feasibility"] + 0.3
                                                     * j["direction_agreement"]
                                                     + 0.2 * j["position_agreement"])
        # a joint's score: its line's confidence times its type's probability
        assert 0.0 < j["type_prob"] <= 1.0
        assert j["score"] == pytest.approx(j["line_confidence"] * j["type_prob"])
    with open(out / "summary.csv") as fh:
        summary = list(csv.DictReader(fh))
    assert summary[-1]["category"] == "all" and int(summary[-1]["kept"]) == len(SHAPES)
    assert not (out / ".staging").exists()
    # resume: every record is current, nothing is recomputed
    res2 = pseudo_label_dataset(data, *runs, out, cfg, progress=False)
    assert res2.n_skipped == len(SHAPES) and res2.count("kept") == len(SHAPES)
    # a range prior fitted again at the same path makes every record stale: the ranges it
    # wrote change (0-135 -> 0-60 degrees)
    RangePrior([RangeEntry("hinge", None, None, 10, 0.0, 0.0, 60.0)]).save(tmp_path / "ranges.json")
    res3 = pseudo_label_dataset(data, *runs, out, cfg, progress=False)
    assert res3.n_skipped == 0 and res3.count("kept") == len(SHAPES)
    for rec in res3.records:
        (link,) = [lk for lk in read_shape(out / rec.id).links if lk.joint.type is JointType.HINGE]
        assert link.joint.limit[1] <= 60.0 + 1e-6


@pytest.mark.exactdata
def test_a_second_model_must_agree_on_every_joint(data, runs, tmp_path, monkeypatch):
    """Issue 34: with a second GNN (``check_run``), a shape is kept only when that model gives
    each joint's motion at least ``agree_prob`` and an axis within ``agree_deg``."""
    check, _ = write_untrained_models(tmp_path / "models", gnn="check")
    cfg = PseudoLabelConfig(threshold=0.0)
    # the second model predicts the same hinge: kept, and the record says why
    _hinge_on_largest_leaf(monkeypatch)
    res = pseudo_label_dataset(data, *runs, tmp_path / "same", cfg, progress=False, check_run=check)
    assert [r.status for r in res.records] == ["kept"] * len(SHAPES), res.records
    for r in res.records:
        (j,) = r.joints
        assert j["check_agrees"] is True and j["check_prob"] == pytest.approx(1.0)
        assert j["check_axis_deg"] == pytest.approx(0.0, abs=1e-6)
    # ... a slider there: no shape is kept, each with one line naming the joint
    out = tmp_path / "slider"
    _hinge_on_largest_leaf(monkeypatch, second="P_V")
    res = pseudo_label_dataset(data, *runs, out, cfg, progress=False, check_run=check)
    assert [r.status for r in res.records] == ["disagreement"] * len(SHAPES), res.records
    for r in res.records:
        assert "not confirmed by the second model" in r.reason and "probability 0.00" in r.reason
        assert r.joints[0]["check_agrees"] is False and not (out / r.id).exists()
    with open(out / "summary.csv") as fh:
        assert int(list(csv.DictReader(fh))[-1]["disagreement"]) == len(SHAPES)
    # the bound is the caller's: at agree_prob 0 any motion passes (the axes still agree)
    loose = cfg.model_copy(update={"agree_prob": 0.0})
    res = pseudo_label_dataset(data, *runs, out, loose, progress=False, check_run=check)
    assert res.count("kept") == len(SHAPES) and res.n_skipped == 0
    # without a second model the same shapes are kept, and the record has no check fields
    res = pseudo_label_dataset(data, *runs, tmp_path / "alone", cfg, progress=False)
    assert res.count("kept") == len(SHAPES)
    assert all("check_agrees" not in r.joints[0] for r in res.records)


@pytest.mark.exactdata
def test_cli_takes_the_second_model_from_the_bundle(data, runs, tmp_path, monkeypatch):
    """``kinmo train all``'s bundle carries its coarse GNN as ``check/``; ``kinmo
    pseudo-label --model BUNDLE`` then requires it to agree, ``--no-check`` does not."""
    from typer.testing import CliRunner

    from kinmo.cli import app
    from kinmo.inference.bundle import read_bundle, write_bundle

    check, _ = write_untrained_models(tmp_path / "models", gnn="check")
    bundle = tmp_path / "bundle"
    write_bundle(bundle, runs[0], runs[1], check=check)
    assert read_bundle(bundle).check == bundle / "check"
    _hinge_on_largest_leaf(monkeypatch, second="P_V")
    # the bundle's check/ folder is named "check": the fake predicts a slider for it
    for extra, status in (([], "disagreement"), (["--no-check"], "kept")):
        out = tmp_path / f"out{len(extra)}"
        res = CliRunner().invoke(app, ["pseudo-label", str(data), "--model", str(bundle), "--out", str(out),
                                       "--threshold", "0", "--quiet", *extra])
        assert res.exit_code == 0, res.output
        with open(out / "shapes.csv") as fh:
            assert {r["status"] for r in csv.DictReader(fh)} == {status}
    # a second model given and turned off at once is a contradiction, said before any work
    out = tmp_path / "both"
    res = CliRunner().invoke(app, ["pseudo-label", str(data), "--model", str(bundle), "--out", str(out),
                                   "--no-check", "--check-model", str(check), "--quiet"])
    assert res.exit_code == 2 and "--no-check and --check-model" in res.output
    assert not out.exists()


@pytest.mark.exactdata
def test_threshold_rejects_and_failures_are_reported(data, runs, tmp_path, monkeypatch):
    _hinge_on_largest_leaf(monkeypatch)
    out = tmp_path / "out"
    # a broken shape: a mesh file is missing
    broken = tmp_path / "data" / "broken"
    shutil.copytree(data / SHAPES[0], broken, symlinks=False)
    victim = min((broken / "objs").glob("*.obj"))
    victim.unlink()
    (tmp_path / "data" / SHAPES[1]).symlink_to((data / SHAPES[1]).resolve())
    res = pseudo_label_dataset(tmp_path / "data", *runs, out, PseudoLabelConfig(threshold=1.0),
                               progress=False)
    by_id = {r.id: r for r in res.records}
    assert by_id["broken"].status == "failed" and victim.name in by_id["broken"].reason
    assert by_id[SHAPES[1]].status == "below_threshold"
    assert "below 1" in by_id[SHAPES[1]].reason and by_id[SHAPES[1]].min_score < 1.0
    assert not (out / SHAPES[1]).exists() and not (out / "broken").exists()
    with open(out / "shapes.csv") as fh:
        rows = {r["id"]: r for r in csv.DictReader(fh)}
    assert rows["broken"]["status"] == "failed" and rows[SHAPES[1]]["status"] == "below_threshold"


@pytest.mark.exactdata
def test_end_to_end_with_the_real_predictor(data, runs, tmp_path):
    """The untrained GNN and axis network through the real pipeline, two worker processes:
    every shape gets a status; kept ones are valid objects."""
    out = tmp_path / "out"
    res = pseudo_label_dataset(data, *runs, out, PseudoLabelConfig(threshold=0.0), workers=2,
                               progress=False)
    assert len(res.records) == len(SHAPES)
    for r in res.records:
        assert r.status in ("kept", "no_moving_joint"), (r.id, r.reason)
        if r.status == "kept":
            assert read_shape(out / r.id).links
        else:
            assert r.n_moving == 0 and not (out / r.id).exists()
    with open(out / "summary.csv") as fh:
        counts = list(csv.DictReader(fh))[-1]
    assert int(counts["shapes"]) == len(SHAPES)
    assert int(counts["kept"]) + int(counts["no_moving_joint"]) == len(SHAPES)


@pytest.mark.exactdata
def test_cli(data, runs, tmp_path, monkeypatch):
    from typer.testing import CliRunner

    from kinmo.cli import app

    _hinge_on_largest_leaf(monkeypatch)
    out = tmp_path / "out"
    res = CliRunner().invoke(app, [
        "pseudo-label", str(data), "--model", str(runs[0]), "--axis-model", str(runs[1]),
        "--out", str(out), "--threshold", "0", "--quiet", "--sign", "feasibility",
        "--format", "semantics", "--format", "mjcf",
    ])
    assert res.exit_code == 0, res.output
    assert "kept" in res.output and f"{len(SHAPES)} kept" in res.output
    assert len(list(out.glob("*/mobility_v2.json"))) == len(SHAPES)
    # --format: mobility_v2.json always, then the formats asked for (kinmo.export)
    assert len(list(out.glob("*/mobility.xml"))) == len(SHAPES)
    assert not list(out.glob("*/mobility.urdf"))
    bad = CliRunner().invoke(app, [
        "pseudo-label", str(data), "--model", str(tmp_path / "missing"), "--axis-model",
        str(runs[1]), "--out", str(out),
    ])
    assert bad.exit_code == 2 and "missing" in bad.output


@pytest.mark.exactdata
def test_cli_refinement_options_reach_the_scores(data, runs, tmp_path, monkeypatch):
    from typer.testing import CliRunner

    from kinmo.cli import app

    _hinge_on_largest_leaf(monkeypatch)
    out = tmp_path / "out"
    res = CliRunner().invoke(app, [
        "pseudo-label", str(data), "--model", str(runs[0]), "--axis-model", str(runs[1]),
        "--out", str(out), "--threshold", "0", "--quiet", "--keep-gnn", "--snap-angle", "10",
        "--score", "line",
    ])
    assert res.exit_code == 0, res.output
    scores = [json.loads(p.read_text()) for p in sorted(out.glob("*/scores.json"))]
    assert scores
    for s in scores:
        assert s["options"]["score"] == "line"
        assert all(j["score"] == j["line_confidence"] for j in s["joints"])
        assert s["options"]["refine"]["keep_gnn"] is True
        assert s["options"]["refine"]["snap_angle_deg"] == 10.0
        # the fake GNN's vertical hinge: the vertical OBB edges within 10 deg plus its own line
        for j in s["joints"]:
            assert j["n_candidates"] >= 2 and j["candidate"] in ("edge", "gnn")
            assert 0.0 <= j["score"] <= 1.0
    with open(out / "shapes.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == len(SHAPES)
    for r in rows:  # even at threshold 0: a joint whose only candidate is the GNN's own line
        # (no OBB axis within 10 deg of vertical) has no geometric confidence
        assert r["status"] == "kept" or (r["status"] == "below_threshold"
                                         and (out / ".records" / f"{r['id']}.json").is_file())
    rejected = [r for r in rows if r["status"] != "kept"]
    for r in rejected:
        rec = json.loads((out / ".records" / f"{r['id']}.json").read_text())
        assert any(j["candidate"] == "gnn" and j["n_candidates"] == 1 for j in rec["joints"])
    bad = CliRunner().invoke(app, [
        "pseudo-label", str(data), "--model", str(runs[0]), "--axis-model", str(runs[1]),
        "--out", str(out), "--snap-angle", "120",
    ])
    assert bad.exit_code == 2


@pytest.mark.exactdata
def test_one_run_per_output_folder(data, runs, tmp_path):
    """A second pseudo-label run on the same OUT fails at once and touches nothing."""
    import fcntl

    from kinmo.errors import KinmoError

    out = tmp_path / "out"
    out.mkdir()
    (out / ".staging").mkdir()  # the running one's work in progress
    with open(out / ".lock", "a+") as fh:
        fcntl.flock(fh, fcntl.LOCK_EX | fcntl.LOCK_NB)
        with pytest.raises(KinmoError, match="another kinmo pseudo-label is writing"):
            pseudo_label_dataset(data / SHAPES[0], *runs, out, progress=False)
    assert (out / ".staging").is_dir() and not (out / "shapes.csv").exists()


@pytest.mark.exactdata
def test_ray_executor_gives_the_same_records(data, runs, tmp_path):
    """``executor="ray"``: a local Ray of 2 CPUs is started for the call, each worker loads the
    models once (the initializer), and the records are those of the in-process run."""
    import ray

    cfg = PseudoLabelConfig(threshold=0.0)
    a = pseudo_label_dataset(data, *runs, tmp_path / "a", cfg, workers=1, progress=False)
    b = pseudo_label_dataset(data, *runs, tmp_path / "b", cfg, workers=2, progress=False,
                             executor="ray")
    assert not ray.is_initialized()  # started and shut down by the call
    key = [(r.id, r.status, r.n_moving, r.reason) for r in a.records]
    assert [(r.id, r.status, r.n_moving, r.reason) for r in b.records] == key
    assert sorted(p.name for p in (tmp_path / "b").iterdir()) == sorted(p.name for p in (tmp_path / "a").iterdir())


@pytest.mark.exactdata
def test_symlink_mode_links_to_the_source(data, runs, tmp_path, monkeypatch):
    _hinge_on_largest_leaf(monkeypatch)
    out = tmp_path / "out"
    res = pseudo_label_dataset(data / SHAPES[0], *runs, out,
                               PseudoLabelConfig(threshold=0.0, link="symlink"), progress=False)
    assert [r.status for r in res.records] == ["kept"]
    src = read_shape(data / SHAPES[0])
    for name in src.hierarchy.mesh_names(src.hierarchy.root):
        p = out / SHAPES[0] / "textured_objs" / f"{name}.obj"
        assert p.is_symlink() and p.resolve() == src.mesh_path(name).resolve()
    # kinmo's readers refuse meshes that leave the object folder unless told the links are its own
    from kinmo.errors import KinmoDataError

    with pytest.raises(KinmoDataError, match="symbolic link that leaves the shape folder"):
        read_shape(out / SHAPES[0])
    assert read_shape(out / SHAPES[0], external_links=True).links


@pytest.mark.exactdata
def test_hostile_mesh_name_writes_nothing_outside_out(data, runs, tmp_path, monkeypatch):
    """Finding 1 of the hostile-input issue: a mesh name in result.json was used as a path,
    and pseudo-label overwrote (or created a link at) a file outside its output folder."""
    _hinge_on_largest_leaf(monkeypatch)
    victim_dir = tmp_path / "probe"
    victim_dir.mkdir()
    victim = victim_dir / "victim.obj"
    victim.write_text("precious\n")
    ds = tmp_path / "data"
    shape = ds / "evil"
    shutil.copytree(data / SHAPES[0], shape, symlinks=False)
    doc = json.loads((shape / "result.json").read_text())
    leaf = doc[0]
    while leaf.get("children"):
        leaf = leaf["children"][0]
    depth = len((shape / "objs").resolve().relative_to(tmp_path).parts)
    hostile = "/".join([".."] * depth) + "/probe/victim"
    assert (shape / "objs" / f"{hostile}.obj").resolve() == victim.resolve()
    leaf["objs"] = [hostile]
    (shape / "result.json").write_text(json.dumps(doc))
    (ds / "absent").mkdir()  # a second hostile shape: the target does not exist yet
    shutil.copytree(shape, ds / "absent", dirs_exist_ok=True)
    leaf["objs"] = [hostile.replace("victim", "created")]
    (ds / "absent" / "result.json").write_text(json.dumps(doc))
    out = tmp_path / "out"
    res = pseudo_label_dataset(ds, *runs, out, PseudoLabelConfig(threshold=0.0), progress=False)
    by_id = {r.id: r for r in res.records}
    for sid in ("evil", "absent"):
        assert by_id[sid].status == "failed"
        assert "result.json" in by_id[sid].reason and "not a path" in by_id[sid].reason
        assert not (out / sid).exists()
    assert victim.read_text() == "precious\n"
    assert sorted(p.name for p in victim_dir.iterdir()) == ["victim.obj"]


@pytest.mark.exactdata
def test_each_shape_s_meshes_are_read_once(data, tmp_path, monkeypatch):
    """One path per data flow: the part graph, the learned selector's sweep and the URDF
    export of a kept shape share one read of its meshes (they read them three times before)."""
    from typer.testing import CliRunner

    import kinmo.data.build
    from kinmo.cli import app

    reads: list[int] = []
    real = kinmo.data.build.load_objs

    def counted(paths, *a, **kw):
        reads.append(len(paths))
        return real(paths, *a, **kw)

    monkeypatch.setattr(kinmo.data.build, "load_objs", counted)
    out = tmp_path / "out"
    r = CliRunner().invoke(app, ["pseudo-label", str(data), "-o", str(out), "-t", "0", "-j", "1", "-q"])
    assert r.exit_code == 0, r.output
    kept = [p for p in out.iterdir() if (p / "mobility.urdf").is_file()]
    assert kept and len(list((kept[0] / "collision").glob("*.obj")))  # exported with geometry
    assert len(reads) == len(SHAPES), reads


def test_one_worker_writes_the_bytes_two_workers_write(partnet_root, tmp_path):
    """``-j 1`` (in this process) and ``-j 2`` (worker processes) with the pretrained bundle:
    the same kept shapes, byte for byte (this process uses one torch thread, as each worker
    does; with torch's default threads, axis origins differed in the 8th digit)."""
    import subprocess
    import sys

    data = tmp_path / "data"
    data.mkdir()
    for s in sorted(p.name for p in partnet_root.iterdir() if p.is_dir())[:12]:
        (data / s).symlink_to(partnet_root / s)
    for j in ("1", "2"):  # fresh processes, as users run it (torch's default threads)
        r = subprocess.run([sys.executable, "-m", "kinmo", "pseudo-label", str(data), "-o", str(tmp_path / f"j{j}"),
                            "-j", j, "-q"], capture_output=True, text=True, timeout=600)
        assert r.returncode == 0, r.stdout + r.stderr
    kept = sorted(p.parent.name for p in (tmp_path / "j1").glob("*/mobility_v2.json"))
    assert kept and kept == sorted(p.parent.name for p in (tmp_path / "j2").glob("*/mobility_v2.json"))
    for s in kept:
        for name in ("mobility_v2.json", "scores.json", "mobility.urdf"):
            assert (tmp_path / "j1" / s / name).read_bytes() == (tmp_path / "j2" / s / name).read_bytes(), (s, name)


def test_the_process_that_hands_out_shapes_does_not_import_torch():
    """``kinmo pseudo-label -j N``: the coordinating process reads no model (each worker
    loads them), so it starts the workers without torch's import (issue 24); the in-process
    run (``-j 1``) and every worker load torch with the models."""
    code = ("import sys\n"
            "import kinmo.cli.pseudo_label, kinmo.pseudo_label\n"
            "from kinmo.parallel import torch_threads\n"
            "with torch_threads(0):\n"
            "    pass\n"
            "print('torch' in sys.modules)\n"
            "with torch_threads(1):\n"
            "    print('torch' in sys.modules)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.split() == ["False", "True"]
