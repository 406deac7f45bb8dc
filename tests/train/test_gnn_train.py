"""Training loop, presets and checkpoints of the motion GNN (on synthetic cabinets)."""

from __future__ import annotations

import csv

import pytest
import torch

from kinmo.errors import KinmoDataError
from kinmo.train.config import preset, resolve_device
from kinmo.train.gnn import METRIC_COLUMNS, load_run, train_gnn
from kinmo.train.split import Split
from motion_cabinet import cabinet_graph

torch.set_num_threads(1)


def tiny(**over):
    over = {"flatten_prob": 0.0, "drop_names_prob": 0.0, "augment_turn": 0.0, **over}
    cfg = preset("quick", batch_size=3, n_points=32, threads=1, lr=5e-3, **over)
    small = cfg.model.model_copy(update=dict(point_widths=[16], geo_dim=16, node_dim=24, edge_dim=24,
                                             semantic_dim=4, gnn_layers=2))
    return cfg.model_copy(update={"model": small})


def _graphs(n=6):
    return [cabinet_graph(n_points=32, seed=s, jitter=0.15, shape_id=f"cab{s}") for s in range(n)]


def _rows(path):
    with open(path) as f:
        return list(csv.DictReader(f))


def test_presets():
    q = preset("quick")
    p = preset("paper")
    assert q.model.point_encoder == "pointnet" and q.n_points == 256 and q.model.types == "fine"
    assert p.model.point_encoder == "dgcnn" and p.model.node_dim == 256 and p.model.gnn_layers == 5
    assert (p.lr, p.weight_decay, p.epochs, p.batch_size) == (1e-4, 1e-4, 400, 2)
    c = preset("quick", types="coarse", epochs=3, seed=7, device=None)
    assert (c.model.types, c.epochs, c.seed, c.device) == ("coarse", 3, 7, "auto")
    with pytest.raises(ValueError, match="preset"):
        preset("huge")
    with pytest.raises(ValueError, match="option"):
        preset("quick", wings=2)
    with pytest.raises(ValueError):
        preset("quick", types="medium")
    assert resolve_device("cpu").type == "cpu"
    assert resolve_device("auto").type == ("cuda" if torch.cuda.is_available() else "cpu")


def test_training_lowers_the_loss_and_writes_a_reproducible_run(tmp_path):
    graphs = _graphs()
    split = Split(train=[f"cab{s}" for s in range(5)], test=["cab5"])
    cfg = tiny(epochs=25, seed=3)
    res = train_gnn(graphs, tmp_path / "run", cfg, split=split, progress=False)
    run = tmp_path / "run"
    for name in ("model.pt", "config.json", "split.json", "metrics.csv", "recall.json"):
        assert (run / name).is_file(), name
    rows = _rows(run / "metrics.csv")
    assert len(rows) == 25 and tuple(rows[0]) == METRIC_COLUMNS
    first, last = float(rows[0]["loss"]), float(rows[-1]["loss"])
    assert last < 0.5 * first
    assert float(rows[-1]["train_acc"]) > 0.8  # majority class (None) is 0.5
    assert rows[-1]["test_acc"] != ""  # the held-out cabinet is evaluated every epoch
    assert set(res.recall["train"]) >= {"R_V_S", "P_H", "Fixed", "None"}
    # the same seed gives the same run
    res2 = train_gnn(graphs, tmp_path / "run2", cfg, split=split, progress=False)
    assert [r["loss"] for r in res2.history] == [r["loss"] for r in res.history]
    # the checkpoint reloads with its config and vocabulary
    loaded = load_run(run, device="cpu")
    assert loaded.types == "fine" and loaded.config.epochs == 25
    assert loaded.config.model.vocab_size == len(loaded.vocab) == 7  # 6 names + unknown
    assert not loaded.model.training


def test_coarse_training_and_default_split(tmp_path):
    res = train_gnn(_graphs(4), tmp_path / "run", tiny(epochs=2, types="coarse"), progress=False)
    assert res.config.model.types == "coarse"
    # all four cabinets share a category: one of them is held out
    assert len(res.split.test) == 1 and len(res.split.train) == 3
    assert Split.load(tmp_path / "run" / "split.json").test == res.split.test


def test_errors(tmp_path):
    g = cabinet_graph()
    g.edge_fine = None
    with pytest.raises(KinmoDataError, match="labelled"):
        train_gnn([g], tmp_path / "r", tiny(epochs=1), progress=False)
    with pytest.raises(KinmoDataError, match="no labelled graph for training"):
        train_gnn(_graphs(2), tmp_path / "r", tiny(epochs=1), split=Split([], ["cab0", "cab1"]),
                  progress=False)
    with pytest.raises(KinmoDataError, match="checkpoint is missing"):
        load_run(tmp_path / "nothing")
    (tmp_path / "bad").mkdir()
    (tmp_path / "bad" / "model.pt").write_bytes(b"not a checkpoint")
    with pytest.raises(KinmoDataError, match="not a motion-GNN checkpoint"):
        load_run(tmp_path / "bad")
    with pytest.raises(KinmoDataError, match="cache folder does not exist"):
        train_gnn(tmp_path / "no-cache", tmp_path / "r", tiny(epochs=1), progress=False)


def test_checkpoints_without_axis_mode_load_as_regression(tmp_path):
    from kinmo.features import SemanticVocab
    from kinmo.models import MotionGNN
    from kinmo.train.gnn import save_checkpoint

    cfg = tiny(epochs=1)
    cfg = cfg.model_copy(update={"model": cfg.model.model_copy(update={"axis_mode": "regress"})})
    save_checkpoint(tmp_path / "model.pt", MotionGNN(cfg.model), cfg, SemanticVocab(), None, 1)
    payload = torch.load(tmp_path / "model.pt", weights_only=True)
    del payload["config"]["model"]["axis_mode"]  # as written before the field existed
    torch.save(payload, tmp_path / "model.pt")
    assert load_run(tmp_path, device="cpu").config.model.axis_mode == "regress"


def test_dropped_names_train_and_keep_the_vocabulary(tmp_path):
    graphs = _graphs(4)
    res = train_gnn(graphs, tmp_path / "r", tiny(epochs=2, drop_names_prob=1.0), progress=False)
    run = load_run(res.run_dir, "cpu")
    # the vocabulary comes from the names before they are dropped; unnamed nodes are index 0
    assert len(run.vocab) > 1
    assert all(run.vocab.index(n) > 0 for n in graphs[0].node_names if n.lower() not in ("unknown",))
    assert run.vocab.index("part_3") == 0


def test_quarter_turn_augmentation_turns_the_share_it_says_reproducibly(tmp_path, monkeypatch):
    """Issue 36: ``augment_turn`` shows that share of the training shapes a quarter turn (1-3)
    off PartNet's facing, drawn from the run's seed; 0 draws nothing."""
    from kinmo.features import GraphTensors

    seen: list[int] = []
    real = GraphTensors.turned

    def spy(self, k):
        seen.append(int(k))
        return real(self, k)

    monkeypatch.setattr(GraphTensors, "turned", spy)
    graphs = _graphs(4)
    split = Split(train=[f"cab{s}" for s in range(4)], test=[])
    train_gnn(graphs, tmp_path / "none", tiny(epochs=3, augment_turn=0.0), split=split, progress=False)
    assert seen == []
    a = train_gnn(graphs, tmp_path / "all", tiny(epochs=3, augment_turn=1.0), split=split, progress=False)
    assert len(seen) == 12 and set(seen) <= {1, 2, 3} and len(set(seen)) > 1
    first = list(seen)
    b = train_gnn(graphs, tmp_path / "again", tiny(epochs=3, augment_turn=1.0), split=split, progress=False)
    assert seen[12:] == first and [r["loss"] for r in a.history] == [r["loss"] for r in b.history]
    seen.clear()
    train_gnn(graphs, tmp_path / "some", tiny(epochs=10, augment_turn=0.25), split=split, progress=False)
    assert 0 < len(seen) < 40
    assert preset("quick").augment_turn == preset("paper").augment_turn > 0.0 == preset("tiny").augment_turn
