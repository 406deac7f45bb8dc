"""``kinmo train all -j N`` (issue 24): the motion GNNs, the axis network and the ranker's fold
GNNs train N at a time, giving the models the one-after-the-other run gives, timed once."""

import json

import pytest
import torch

from kinmo.pipeline import PipelineConfig, run_pipeline
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
        cfg = PipelineConfig(labeled=data, out=root / f"j{j}", gnn_epochs=2, axis_epochs=1, skip_ancsh=True,
                             render=False, workers=j)
        out[j] = run_pipeline(cfg, progress=False)
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
    _, out = runs
    t2, t1 = out[2].timings, out[1].timings
    pool = [k for k in t2 if k.startswith("train 9 models, 2 at a time")]
    assert pool == ["train 9 models, 2 at a time"]
    assert not any(k.startswith("train ") and "at a time" in k for k in t1)
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
