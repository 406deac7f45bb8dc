"""The ranker's fold GNNs train on the device of every other kinmo training (issue 23).

They were pinned to the CPU, so `kinmo train all --preset paper` on a CUDA machine trained
its first fold GNN at 13 s per epoch (400 epochs per fold) while the motion GNNs before it
took 0.4 s per epoch on the GPU."""

from __future__ import annotations

from types import SimpleNamespace

import pytest

from kinmo.train import ranker


class _Stop(Exception):
    pass


def test_fold_gnn_config_uses_auto_device(monkeypatch, tmp_path):
    seen = []

    def fake_train(graphs, run_dir, cfg, split, progress=False):
        seen.append(cfg)
        raise _Stop

    monkeypatch.setattr(ranker, "train_gnn", fake_train)
    graphs = [SimpleNamespace(shape_id=f"s{i}", category="Laptop") for i in range(6)]
    with pytest.raises(_Stop):
        ranker.oof_predictions(graphs, [g.shape_id for g in graphs], tmp_path, k=3, preset="paper")
    assert len(seen) == 1
    assert seen[0].device == "auto"
    assert seen[0].preset == "paper"
