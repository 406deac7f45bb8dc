"""``kinmo train all --gnn-members N``: every motion GNN (fine, coarse, the ranker's fold GNNs)
is trained with N ensemble members, which the bundle carries and every prediction averages."""

import json

from kinmo.pipeline import PipelineConfig, run_pipeline
from kinmo.runs import member_folders
from kinmo.synth import generate_dataset
from kinmo.train.gnn import load_run

GNNS = ["gnn_fine", "gnn_coarse", *(f"ranker/folds/{t}_{f}" for t in ("fine", "coarse") for f in range(3))]


def test_every_gnn_gets_its_members_and_a_second_run_is_up_to_date(tmp_path):
    data = tmp_path / "partnet-mobility"
    generate_dataset(data, 10, 3, categories=["Laptop", "Refrigerator"], progress=False)
    cfg = PipelineConfig(labeled=data, out=tmp_path / "run", gnn_epochs=2, axis_epochs=1, skip_ancsh=True, train_synth=0,
                         render=False, workers=2, gnn_members=1)
    run_pipeline(cfg, progress=False)
    out = cfg.out
    seeds = {}
    for rel in GNNS:
        (member,) = member_folders(out / rel)
        seeds[rel] = json.loads((member / "config.json").read_text())["seed"]
        own = json.loads((out / rel / "config.json").read_text())["seed"]
        assert seeds[rel] == own + 1, rel
        assert json.loads((member / "split.json").read_text()) == json.loads((out / rel / "split.json").read_text())
    assert json.loads((out / "ranker" / "ranker.json").read_text())["meta"]["trained_on"]["members"] == 1
    # the bundle carries the members of its GNN and of its check model
    assert len(load_run(out / "model" / "gnn", device="cpu").members) == 1
    assert len(load_run(out / "model" / "check", device="cpu").members) == 1
    stamps = {rel: (m / "model.pt").stat().st_mtime_ns for rel in GNNS for m in member_folders(out / rel)}
    res = run_pipeline(cfg, progress=False)
    assert not any(t.ran for name, t in res.timings.items() if name.startswith("train"))
    assert stamps == {rel: (m / "model.pt").stat().st_mtime_ns for rel in GNNS for m in member_folders(out / rel)}
