"""The ranker's fold GNNs trained in parallel (issue 24: `train all`'s ranker stage): the same
models as one after the other, folds already trained are skipped, a failure names its fold."""

from __future__ import annotations

import pytest
import torch

from kinmo.errors import KinmoError
from kinmo.train import ranker
from motion_cabinet import cabinet_graph


def _graphs(n=6):
    return [cabinet_graph(n_points=32, seed=s, jitter=0.15, shape_id=f"cab{s}") for s in range(n)]


def _weights(run):
    state = torch.load(run / "model.pt", map_location="cpu", weights_only=False)
    return state["state_dict"]


def test_two_workers_train_the_models_one_worker_trains(tmp_path):
    graphs = _graphs()
    ids = [g.shape_id for g in graphs]
    kw = dict(k=3, preset="tiny", types=("fine", "coarse"), epochs=1, seed=0)
    assert ranker.train_folds(graphs, ids, tmp_path / "par", workers=2, **kw) == 6
    assert ranker.train_folds(graphs, ids, tmp_path / "seq", workers=1, **kw) == 6
    for t in ("fine", "coarse"):
        for f in range(3):
            a = _weights(tmp_path / "par" / "folds" / f"{t}_{f}")
            b = _weights(tmp_path / "seq" / "folds" / f"{t}_{f}")
            assert a.keys() == b.keys()
            assert all(torch.equal(a[n], b[n]) for n in a), f"{t}_{f} differs"
    # a rerun finds every fold trained
    assert ranker.train_folds(graphs, ids, tmp_path / "par", workers=2, **kw) == 0


def test_a_failed_fold_is_named(tmp_path):
    graphs = _graphs()
    for g in graphs:  # a fold whose graphs cannot be trained on: no points at all
        g.points = g.points[:, :0]
    with pytest.raises(KinmoError, match="fold GNN .*fine_"):
        ranker.train_folds(graphs, [g.shape_id for g in graphs], tmp_path, k=3, preset="tiny",
                           types=("fine",), epochs=1, workers=2)


def test_fold_gnns_train_like_the_motion_gnns_of_train_all():
    """Issue 34: the ranker learns how far to trust GNNs trained like the one it refines."""
    from kinmo.pipeline.config import PipelineConfig
    from kinmo.train.config import preset

    # train all's fine GNN is augmented by default, its coarse one never
    assert PipelineConfig.model_fields["augment_gnn"].default is True
    for name in ("quick", "paper"):
        fine, coarse = ranker.fold_config(name, "fine"), ranker.fold_config(name, "coarse")
        assert fine.epochs == coarse.epochs == preset(name).epochs
        assert (fine.flatten_prob, fine.drop_names_prob) == (preset(name).flatten_prob,
                                                             preset(name).drop_names_prob)
        assert fine.flatten_prob > 0 and fine.augment_turn == preset(name).augment_turn > 0
        assert (coarse.flatten_prob, coarse.drop_names_prob, coarse.augment_turn) == (0.0, 0.0, 0.0)
        plain = ranker.fold_config(name, "fine", augment=False)
        assert (plain.flatten_prob, plain.drop_names_prob, plain.augment_turn) == (0.0, 0.0, 0.0)
    assert ranker.fold_config("quick", "coarse", epochs=25).epochs == 25  # given: as given
    cfg = ranker.fold_config("quick", "coarse", seed=3)
    assert (cfg.model.types, cfg.seed, cfg.threads, cfg.device) == ("coarse", 3, 1, "auto")


def test_a_preset_change_refits_the_ranker_of_train_all(tmp_path, monkeypatch):
    """The ranker stage's key holds its fold GNNs' whole configuration: a resumed `train all`
    whose preset gained an augmentation (issue 36's quarter turns) fits the ranker again on
    fold GNNs trained like the new motion GNN, never keeping the stale one."""
    import kinmo.train.config as train_config
    from kinmo.pipeline import run as pipeline_run
    from kinmo.pipeline.config import PipelineConfig

    from types import SimpleNamespace

    cfg = PipelineConfig(labeled=tmp_path / "data", out=tmp_path / "run")
    before = pipeline_run._fold_stamp(cfg)
    _, key = pipeline_run._Context._ranker_stage(SimpleNamespace(cfg=cfg), SimpleNamespace(reuse={}, out=tmp_path, extra=None), {})
    assert key["ranker"]["fold_gnns"] == before
    assert before["fine"]["augment_turn"] == train_config.AUGMENT_TURN
    monkeypatch.setattr(train_config, "AUGMENT_TURN", 0.0)
    after = pipeline_run._fold_stamp(cfg)
    assert after != before and after["coarse"] == before["coarse"]
    pipeline_run._ranker_fold_stamp(cfg, tmp_path / "ranker")
    (tmp_path / "ranker" / "folds" / "fine_0").mkdir(parents=True)
    monkeypatch.setattr(train_config, "AUGMENT_TURN", 0.15)
    pipeline_run._ranker_fold_stamp(cfg, tmp_path / "ranker")  # folds of another configuration go
    assert not (tmp_path / "ranker" / "folds").exists()


def test_train_ranker_command_passes_members(monkeypatch, tmp_path):
    """``kinmo train ranker --members N`` fits on fold GNNs with N members each (issue 34)."""
    from typer.testing import CliRunner

    import kinmo.train.ranker as train_ranker_module
    from kinmo.cli import app

    seen = {}

    def fake(*a, **k):
        seen.update(k)
        return None, {}

    monkeypatch.setattr(train_ranker_module, "train_ranker", fake)
    args = ["train", "ranker", "--data", str(tmp_path), "--out", str(tmp_path / "o"),
            "--split", str(tmp_path / "s.json")]
    r = CliRunner().invoke(app, args + ["--members", "2"])
    assert r.exit_code == 0, r.output
    assert seen["members"] == 2
    assert CliRunner().invoke(app, args).exit_code == 0 and seen["members"] == 0
    assert CliRunner().invoke(app, args + ["--members", "-1"]).exit_code != 0


def test_a_ranker_that_cannot_be_fit_is_one_clear_error(tmp_path, monkeypatch):
    """``kinmo train all`` on too few objects or with too short a preset: the fit finds no
    group with a right candidate, and the stage says so in one line instead of a traceback."""
    from types import SimpleNamespace

    from kinmo.errors import KinmoDataError

    graphs = _graphs()
    monkeypatch.setattr(ranker, "ranker_graphs", lambda data, sp: graphs)
    monkeypatch.setattr(ranker.Split, "load", classmethod(
        lambda cls, path: SimpleNamespace(train=[g.shape_id for g in graphs])))

    def no_positive(*a, **k):
        raise ValueError("fit_ranker: no group with a positive candidate")

    monkeypatch.setattr(ranker, "fit_type_rankers", no_positive)
    with pytest.raises(KinmoDataError, match="cannot fit the selector .* no group with a positive"):
        ranker.train_ranker(tmp_path / "cache", tmp_path / "out", tmp_path / "split.json", folds=3,
                            preset="tiny", epochs=1, progress=False)
    assert not (tmp_path / "out" / "ranker.json").exists()


def test_extra_objects_are_in_every_folds_training_and_never_held_out(tmp_path):
    ids = [f"cab{s}" for s in range(6)]
    cats = ["A", "B"] * 3
    plain = ranker.fold_plan(ids, cats, tmp_path, k=3, preset="tiny")
    plan = ranker.fold_plan(ids, cats, tmp_path, k=3, preset="tiny", extra={"gen0": "A", "gen1": "C"})
    assert [s.test for _, _, s in plan] == [s.test for _, _, s in plain]  # the folds are the same
    for (_, _, s), (_, _, s0) in zip(plan, plain):
        assert s.train == sorted(s0.train + ["gen0", "gen1"])
        assert s.categories["gen1"] == "C"
    with pytest.raises(ValueError, match="also fold objects"):
        ranker.fold_plan(ids, cats, tmp_path, k=3, preset="tiny", extra={"cab2": "A"})
    with pytest.raises(KinmoError, match="also fold objects"):
        ranker.train_folds(_graphs(), ids, tmp_path, k=3, preset="tiny", epochs=1,
                           extra=[cabinet_graph(n_points=32, seed=9, shape_id="cab2")])
