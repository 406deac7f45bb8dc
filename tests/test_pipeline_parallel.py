"""``kinmo train all -j N`` (issues 24, 23): the motion GNNs, the axis network and the ranker's
fold GNNs train N at a time, then the ANCSH models one category per worker, giving the models
the one-after-the-other run gives, timed once."""

import io
import json

import pytest
import torch
from rich.console import Console

from kinmo.pipeline import PipelineConfig, category_runs, run_pipeline
from kinmo.synth import generate_dataset

MODELS = ["gnn_fine", "gnn_coarse", "axis", *(f"ranker/folds/{t}_{f}" for t in ("fine", "coarse") for f in range(3))]


def _weights(run):
    return torch.load(run / "model.pt", map_location="cpu", weights_only=False)["state_dict"]


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    root = tmp_path_factory.mktemp("parallel")
    data = root / "partnet-mobility"
    generate_dataset(data, 10, 3, categories=["Laptop", "Refrigerator"], progress=False)
    out = {}
    for j in (2, 1):
        cfg = PipelineConfig(labeled=data, out=root / f"j{j}", gnn_epochs=2, axis_epochs=1, skip_ancsh=True, train_synth=0,
                             render=False, workers=j)
        log = io.StringIO()
        out[j] = run_pipeline(cfg, console=Console(file=log, width=1000, no_color=True), progress=False)
        (root / f"j{j}.log").write_text(log.getvalue())
    return root, out


def test_the_pool_trains_the_models_of_the_sequential_run(runs):
    root, _ = runs
    for rel in MODELS:
        a, b = _weights(root / "j2" / rel), _weights(root / "j1" / rel)
        assert a.keys() == b.keys(), rel
        assert all(torch.equal(a[n], b[n]) for n in a), f"{rel} differs"
    ra = json.loads((root / "j2/ranker/ranker.json").read_text())
    rb = json.loads((root / "j1/ranker/ranker.json").read_text())
    assert {k: v for k, v in ra.items() if k != "meta"} == {k: v for k, v in rb.items() if k != "meta"}


def test_pooled_stages_are_timed_once(runs):
    root, out = runs
    t2, t1 = out[2].timings, out[1].timings
    pool = [k for k in t2 if k.startswith("train 9 models, 2 at a time")]
    assert pool == ["train 9 models, 2 at a time"]
    assert not any(k.startswith("train ") and "at a time" in k for k in t1)
    # the pool's opening line names a few of its trainings and counts the rest
    line = next(ln for ln in (root / "j2.log").read_text().splitlines() if ln.startswith("train 9 models"))
    assert line.endswith(" and 3 more") and line.count(", ") == 1 + 5, line
    for name in ("train gnn (fine)", "train gnn (coarse)", "train axis", "train ranker: fold GNN fine_0"):
        assert t2[name].ran and t2[name].parallel and t2[name].cpu_s > 0, name
    assert not t1["train gnn (fine)"].parallel
    # the ranker stage still ran (its fit), on folds trained by the pool
    assert t2["train ranker"].ran and not t2["train ranker"].parallel
    own = [t for t in t2.values() if not t.parallel]
    assert out[2].total().wall_s == pytest.approx(sum(t.wall_s for t in own))
    assert out[2].total().wall_s < sum(t.wall_s for t in t2.values())


def test_a_second_run_is_up_to_date(runs):
    root, out = runs
    cfg = PipelineConfig.model_validate_json((root / "j2" / "pipeline.json").read_text())
    res = run_pipeline(cfg, progress=False)
    assert {k for k, t in res.timings.items() if t.ran} == {"report"}


@pytest.fixture(scope="module")
def ancsh_runs(tmp_path_factory):
    """Two categories with an ANCSH model each (supervised only: no unlabelled data), tiny
    settings, trained with -j 2 and -j 1."""
    root = tmp_path_factory.mktemp("parallel-ancsh")
    data = root / "partnet-mobility"
    generate_dataset(data, 12, 5, categories=["Laptop", "Microwave"], progress=False)
    out = {}
    for j in (2, 1):
        cfg = PipelineConfig(labeled=data, out=root / f"j{j}", gnn_epochs=1, refine=False, render=False, train_synth=0,
                             categories=["Laptop", "Microwave"], ancsh_epochs=1, ancsh_steps_per_epoch=2,
                             frames_per_object=2, workers=j)
        out[j] = run_pipeline(cfg, progress=False)
    return root, out


def test_ancsh_categories_train_in_parallel_as_one_after_the_other(ancsh_runs):
    root, out = ancsh_runs
    assert out[2].categories == out[1].categories == ["Laptop", "Microwave"]
    models = sorted(p.relative_to(root / "j1") for p in (root / "j1" / "ancsh").rglob("model.pt"))
    assert len(models) == 3  # Laptop, and Microwave's two structures (generated layouts)
    for rel in models:
        a, b = _weights((root / "j2" / rel).parent), _weights((root / "j1" / rel).parent)
        assert a.keys() == b.keys()
        assert all(torch.equal(a[n], b[n]) for n in a), f"{rel} differs"
    for cat in ("Laptop", "Microwave"):
        # each category renders into its own scans/<Category>/ (one lock and manifest each)
        assert (root / "j2" / "scans" / cat / "labeled" / "manifest.csv").is_file()
        # the same Table 2
        t2csv = (root / "j2" / "eval" / cat / "table2.csv").read_text().replace(str(root / "j2"), str(root / "j1"))
        assert t2csv == (root / "j1" / "eval" / cat / "table2.csv").read_text()
    ancsh2 = {k: t for k, t in out[2].timings.items() if k.startswith("train ancsh ")}
    ancsh1 = {k: t for k, t in out[1].timings.items() if k.startswith("train ancsh ")}
    assert ancsh2.keys() == ancsh1.keys() and len(ancsh2) == 3
    assert all(t.ran and t.parallel for t in ancsh2.values()) and not any(t.parallel for t in ancsh1.values())
    assert [k for k in out[2].timings if "chains" in k] == ["train ancsh: 3 models in 2 chains, 2 at a time"]
    # `kinmo eval --category laptop` in the folder of that run finds its runs and the
    # category's render cache
    cwd = root / "cwd"
    (cwd / "runs").mkdir(parents=True)
    (cwd / "runs" / "all").symlink_to(root / "j2", target_is_directory=True)
    found = category_runs("laptop", cwd=cwd)
    assert found.runs == cwd / "runs" / "all" / "ancsh" / "Laptop"
    assert found.scans == cwd / "runs" / "all" / "scans" / "Laptop"
