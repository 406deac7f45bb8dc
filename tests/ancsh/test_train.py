"""ANCSH training on rendered scans: the loss falls, the checkpoint reloads to the same
predictions, presets, the semi-supervised pseudo-targets and the three settings' data."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import torch

from kinmo.ancsh.config import ANCSHConfig, preset
from kinmo.ancsh.dataset import ANCSHFrames, load_samples, scan_category
from kinmo.ancsh.evaluate import ground_truth_predictions
from kinmo.ancsh.postprocess import estimate
from kinmo.ancsh.semi import pseudo_sample, scan_confidence, unlabeled_object
from kinmo.ancsh.fit import fit
from kinmo.ancsh.inference import build_model, load_run, predict_scans, save_checkpoint
from kinmo.ancsh.scans import render_objects
from kinmo.ancsh.train import _labeled_subset, train_ancsh
from kinmo.errors import KinmoDataError, KinmoError
from kinmo.parallel import torch_threads

LAPTOPS = ["10306", "9968"]
TINY = dict(n_points=256, cache_points=1024, width=8, n_centers=(64, 16, 4), image_size=96,
            batch_size=4, lr=3e-3, render_workers=1, threads=1, schedule="constant", jitter=0.0)


@pytest.fixture(scope="module")
def laptops(mobility_root: Path):
    return scan_category(mobility_root, "Laptop")


@pytest.fixture(scope="module")
def samples(tmp_path_factory, laptops):
    tmp = tmp_path_factory.mktemp("ancsh_train")
    cfg = preset("quick", **TINY)
    files, failed = render_objects({i: laptops.folders[i] for i in LAPTOPS}, tmp / "objects", tmp / "scans", 2,
                                   cfg, progress=False)
    assert not failed
    out, _ = load_samples(files, laptops.parts, laptops.structure, cache_points=cfg.cache_points)
    return out


def test_presets_and_overrides():
    q, p = preset("quick"), preset("paper")
    assert (q.n_points, p.n_points) == (512, 1024)
    assert p.width == 64 and p.n_centers == (512, 128, 32) and p.steps_per_epoch is None
    assert preset("quick", epochs=3, seed=None).epochs == 3
    with pytest.raises(ValueError, match="unknown ANCSH training option"):
        preset("quick", wings=2)
    with pytest.raises(ValueError, match="unknown preset"):
        preset("huge")
    with pytest.raises(ValueError):
        ANCSHConfig(setting="unsupervised")


@pytest.mark.exactdata
def test_a_few_steps_lower_the_loss_and_the_checkpoint_reloads(samples, laptops, tmp_path):
    torch.manual_seed(0)
    cfg = preset("quick", epochs=4, steps_per_epoch=5, **TINY).model_copy(update={"category": "Laptop"})
    model = build_model(cfg, laptops.structure)
    rows = fit(model, ANCSHFrames(samples, cfg.n_points, seed=0), cfg, cfg.epochs, torch.device("cpu"),
               progress=False)
    losses = [r["loss"] for r in rows]
    assert len(rows) == 4 and all(np.isfinite(losses))
    assert losses[-1] < 0.8 * losses[0], losses
    assert rows[-1]["seg_acc"] > rows[0]["seg_acc"]
    save_checkpoint(tmp_path / "model.pt", model, cfg, laptops.structure, epoch=4)
    run = load_run(tmp_path, device="cpu")
    assert run.structure == laptops.structure and run.config == cfg and not run.model.training
    scans = [s.points for s in samples[:2]]
    with torch_threads(1):
        a = predict_scans(model, scans, cfg.n_points, seeds=[5, 6])
        b = predict_scans(run.model, scans, cfg.n_points, seeds=[5, 6])
    for (pa, qa), (pb, qb) in zip(a, b):
        np.testing.assert_array_equal(pa, pb)
        for k in qa:
            np.testing.assert_allclose(qa[k], qb[k], atol=1e-5)
    assert a[0][1]["npcs"].shape == (cfg.n_points, 2, 3) and a[0][1]["joint_logits"].shape == (cfg.n_points, 2)
    (tmp_path / "bad").mkdir()
    torch.save({"format": "something else"}, tmp_path / "bad" / "model.pt")
    with pytest.raises(KinmoDataError, match="not a kinmo ANCSH checkpoint"):
        load_run(tmp_path / "bad")


@pytest.mark.exactdata
def test_pseudo_targets_of_perfect_predictions_reproduce_the_labels(samples, laptops):
    s = samples[0]
    pred = ground_truth_predictions(s, laptops.structure)
    est = estimate(s.points, pred, laptops.structure)
    conf = scan_confidence(s.points, pred, est)
    assert conf["seg_confidence"] > 0.99 and conf["inlier_ratio"] > 0.95 and conf["parts_seen"] == 2
    assert conf["in_cube"] > 0.99
    p = pseudo_sample(s.key, s.frame, s.points, pred, est, laptops.structure)
    assert p.kind == "pseudo" and len(p) == len(s)
    np.testing.assert_array_equal(p.seg, s.seg)
    assert np.abs(p.npcs - s.npcs).max() < 0.01
    agree = (p.joint == s.joint).mean()
    assert agree > 0.97, agree
    # a garbage prediction is not confident
    rng = np.random.default_rng(0)
    junk = {k: rng.normal(size=v.shape) for k, v in pred.items()}
    junk["seg_logits"] = np.zeros_like(pred["seg_logits"])
    junk["npcs"] = rng.uniform(size=pred["npcs"].shape)
    with np.errstate(all="ignore"):
        cj = scan_confidence(s.points, junk, estimate(s.points, junk, laptops.structure, refine=False))
    assert cj["seg_confidence"] == pytest.approx(0.5) and cj["inlier_ratio"] < 0.5
    # a degenerate pose (tiny scale) maps the points far outside the NPCS cube
    est.parts[1].scale *= 1e-3
    assert scan_confidence(s.points, pred, est)["in_cube"] < 0.9
    assert pseudo_sample(s.key, s.frame, s.points, pred, est, laptops.structure).npcs.max() <= 1.0


@pytest.mark.exactdata
def test_unlabeled_partnet_shapes_are_wrapped_motionless(partnet_root, tmp_path):
    from kinmo.data.readers import read_shape

    src = partnet_root / "10101"  # a PartNet laptop
    w = unlabeled_object(src, tmp_path / "10101")
    shape = read_shape(w)
    assert shape.category == "Laptop" and len(shape.links) == 1 and not shape.links[0].joint.is_moving
    mtime = (w / "mobility_v2.json").stat().st_mtime_ns
    unlabeled_object(src, tmp_path / "10101")  # up to date: untouched (renders stay cached)
    assert (w / "mobility_v2.json").stat().st_mtime_ns == mtime
    with pytest.raises(KinmoDataError, match="not a PartNet shape"):
        unlabeled_object(tmp_path / "nothing", tmp_path / "x")


@pytest.mark.exactdata
def test_settings_use_only_training_objects(mobility_root, partnet_root, tmp_path):
    """semi and semi-weakly end to end on a tiny budget: test objects are never used, the data
    of each setting is counted, and a missing --pseudo is a clear error."""
    data = tmp_path / "mobility"
    data.mkdir()
    for oid in ["10040", "10306", "9968", "11405"]:
        (data / oid).symlink_to(mobility_root / oid, target_is_directory=True)
    partnet = tmp_path / "partnet"
    partnet.mkdir()
    (partnet / "10101").symlink_to(partnet_root / "10101", target_is_directory=True)
    # a "pseudo-labelled" folder: PartNet-Mobility format, one shape that is a test object
    pseudo = tmp_path / "pseudo"
    pseudo.mkdir()
    cfg = preset("quick", epochs=1, steps_per_epoch=1, semi_epochs=1, frames_per_object=1,
                 unlabeled_frames_per_object=2, **TINY)
    sup = train_ancsh("laptop", "supervised", tmp_path / "sup", cfg, data=data, scans=tmp_path / "scans",
                      progress=False)
    assert [r["stage"] for r in sup.history] == ["train"]
    res = train_ancsh("laptop", "semi", tmp_path / "semi", cfg, data=data, partnet=partnet,
                      scans=tmp_path / "scans", init=tmp_path / "sup", progress=False)
    assert [r["stage"] for r in res.history] == ["semi"]  # the supervised stage came from --init
    with pytest.raises(KinmoError, match="not a supervised run"):
        train_ancsh("laptop", "semi", tmp_path / "semi2", cfg, data=data, partnet=partnet,
                    init=tmp_path / "semi", progress=False)
    d = json.loads((tmp_path / "semi" / "data.json").read_text())
    split = json.loads((tmp_path / "semi" / "split.json").read_text())
    assert set(d["labeled_objects"]).isdisjoint(split["test"]) and d["labeled_objects"]
    assert d["unlabeled_objects"] == ["10101"] and d["unlabeled_scans"] == 2
    assert 0 <= d["pseudo_target_scans"] <= 2
    rows = (tmp_path / "semi" / "pseudo_targets.csv").read_text().splitlines()
    assert rows[0].startswith("id,frame") and len(rows) == 3
    with pytest.raises(KinmoError, match="--pseudo"):
        train_ancsh("laptop", "semi-weakly", tmp_path / "sw", cfg, data=data)
    test_id = split["test"][0]
    train_id = d["labeled_objects"][0]
    (pseudo / test_id).symlink_to(mobility_root / test_id, target_is_directory=True)
    (pseudo / "900001").symlink_to(mobility_root / train_id, target_is_directory=True)
    res = train_ancsh("laptop", "semi-weakly", tmp_path / "sw", cfg, data=data, pseudo=pseudo,
                      scans=tmp_path / "scans", progress=False)
    assert res.data["pseudo_labeled_objects"] == ["900001"]
    assert res.data["pseudo_labeled_ignored"] == {test_id: "is a test object"}
    assert res.data["pseudo_labeled_scans"] == 1 and res.data["labeled_scans"] == len(res.data["labeled_objects"])
    assert (tmp_path / "sw" / "model.pt").is_file() and (tmp_path / "sw" / "metrics.csv").is_file()


@pytest.mark.exactdata
def test_semi_weakly_without_pseudo_labels_is_the_supervised_training(mobility_root, tmp_path):
    """With no pseudo-labelled scan, semi-weakly trains exactly the supervised model; given that
    run (init, as `kinmo train all` does) it takes its weights and metrics instead of training
    again, and an init trained otherwise is a clear error."""
    data = tmp_path / "mobility"
    data.mkdir()
    for oid in ["10040", "10306", "9968", "11405"]:
        (data / oid).symlink_to(mobility_root / oid, target_is_directory=True)
    pseudo = tmp_path / "pseudo"  # no pseudo-labelled laptop
    pseudo.mkdir()
    cfg = preset("quick", epochs=2, steps_per_epoch=2, frames_per_object=1, **TINY)
    kw = dict(data=data, scans=tmp_path / "scans", progress=False)
    sup = train_ancsh("laptop", "supervised", tmp_path / "sup", cfg, **kw)
    trained = train_ancsh("laptop", "semi-weakly", tmp_path / "sw", cfg, pseudo=pseudo, **kw)
    reused = train_ancsh("laptop", "semi-weakly", tmp_path / "sw_init", cfg, pseudo=pseudo,
                         init=tmp_path / "sup", **kw)
    w_sup, w_trained, w_reused = (load_run(d, "cpu").model.state_dict() for d in
                                  (tmp_path / "sup", tmp_path / "sw", tmp_path / "sw_init"))
    assert all(torch.equal(w_sup[k], w_trained[k]) for k in w_sup)  # the same training
    assert all(torch.equal(w_sup[k], w_reused[k]) for k in w_sup)
    assert load_run(tmp_path / "sw_init", "cpu").setting == "semi-weakly"
    assert reused.data["weights_of"] == str((tmp_path / "sup").resolve()) and "weights_of" not in trained.data
    assert reused.history == sup.history
    no_time = lambda rows: [{k: v for k, v in r.items() if k != "seconds"} for r in rows]  # noqa: E731
    assert no_time(trained.history) == no_time(sup.history) and len(sup.history) == 2
    assert (tmp_path / "sw_init" / "metrics.csv").read_text() == (tmp_path / "sup" / "metrics.csv").read_text()
    with pytest.raises(KinmoError, match="epochs"):
        train_ancsh("laptop", "semi-weakly", tmp_path / "sw_other", cfg.model_copy(update={"epochs": 1}),
                    pseudo=pseudo, init=tmp_path / "sup", **kw)
    with pytest.raises(KinmoError, match="semi and semi-weakly"):
        train_ancsh("laptop", "supervised", tmp_path / "sup2", cfg, init=tmp_path / "sup", **kw)


def test_labeled_fraction_picks_nested_seeded_subsets():
    ids = ["10306", "10697", "11405", "9968"]
    subsets = {f: _labeled_subset(ids, f, seed=0) for f in (0.3, 0.5, 0.8, 1.0)}
    assert [len(subsets[f]) for f in (0.3, 0.5, 0.8, 1.0)] == [1, 2, 3, 4]  # rounded object counts
    assert set(subsets[0.3]) < set(subsets[0.5]) < set(subsets[0.8]) < set(ids)  # nested
    assert subsets[1.0] == ids and _labeled_subset(ids, 0.01, 0) and len(_labeled_subset(ids, 0.01, 0)) == 1
    assert _labeled_subset(ids, 0.5, seed=0) == subsets[0.5]  # deterministic
    many = [f"{i:03d}" for i in range(20)]
    picks = {tuple(_labeled_subset(many, 0.3, seed=s)) for s in range(5)}
    assert len(picks) > 1 and all(len(p) == 6 and set(p) <= set(many) for p in picks)  # the seed matters


@pytest.mark.exactdata
def test_cli_labeled_fraction_reduces_the_labeled_training_objects(mobility_root, tmp_path):
    """`kinmo train ancsh --labeled-fraction 0.5` renders and trains on half of the fitting
    training laptops (rounded), the same ones for the same seed."""
    from typer.testing import CliRunner

    from kinmo.cli import app

    data = tmp_path / "mobility"
    data.mkdir()
    for oid in ["10040", "10306", "9968", "11405", "10697"]:
        (data / oid).symlink_to(mobility_root / oid, target_is_directory=True)
    runner = CliRunner()
    common = ["train", "ancsh", "-c", "laptop", "--data", str(data), "--epochs", "1", "--steps-per-epoch", "1",
              "--frames-per-object", "1", "--batch-size", "2", "-j", "1", "-q", "--scans", str(tmp_path / "scans")]
    used = {}
    for name, extra in (("full", []), ("half", ["--labeled-fraction", "0.5"]),
                        ("half2", ["--labeled-fraction", "0.5"])):
        res = runner.invoke(app, common + ["-o", str(tmp_path / name)] + extra)
        assert res.exit_code == 0, res.output
        d = json.loads((tmp_path / name / "data.json").read_text())
        used[name] = d["labeled_objects"]
        assert d["labeled_scans"] == len(d["labeled_objects"])  # one frame per object
        assert sorted(p.name for p in (tmp_path / name / "objects" / "labeled").iterdir()) == sorted(used[name])
    split = json.loads((tmp_path / "full" / "split.json").read_text())
    assert set(used["full"]).isdisjoint(split["test"])
    assert len(used["half"]) == round(len(used["full"]) * 0.5) < len(used["full"])
    assert set(used["half"]) < set(used["full"]) and used["half2"] == used["half"]
    assert json.loads((tmp_path / "half" / "config.json").read_text())["labeled_fraction"] == 0.5
