"""Ensemble members of a motion-GNN run (kinmo.train.gnn.Run.members, kinmo.inference.gnn):
``<run>/members/<k>/`` are loaded with the run, and inference averages their answers."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from kinmo.errors import KinmoDataError
from kinmo.features import SemanticVocab, graph_tensors
from kinmo.inference.gnn import average_members, forward, infer_edges_with_priors
from kinmo.models.motion_gnn import MotionGNN
from kinmo.train.config import preset
from kinmo.runs import member_folders
from kinmo.train.gnn import load_run, save_checkpoint


def _save(path, seed: int, vocab: SemanticVocab = SemanticVocab()) -> None:
    """An untrained quick-preset GNN with spread-out head weights (``seed``)."""
    torch.manual_seed(seed)
    cfg = preset("quick")
    model = MotionGNN(cfg.model)
    with torch.no_grad():
        for name, p in model.named_parameters():
            if "head" in name and p.dim() > 1:
                p.add_(0.5 * torch.randn(p.shape))
    save_checkpoint(path / "model.pt", model, cfg, vocab, None, 0)


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """Three single models (seeds 0, 1, 2) and the ensemble of the three (run 0 with members
    1 and 2)."""
    root = tmp_path_factory.mktemp("members")
    for s in range(3):
        _save(root / f"single_{s}", s)
        _save(root / "ensemble" / ("members/" + str(s) if s else ""), s)
    return root


def _tensors(graph, vocab):
    t = graph_tensors(graph, vocab)
    t.edge_fine = t.axis_origin = t.axis_direction = t.has_axis = None
    return t


def test_members_are_loaded_in_order_with_their_run(runs):
    assert [p.name for p in member_folders(runs / "ensemble")] == ["1", "2"]
    assert member_folders(runs / "single_0") == []
    run = load_run(runs / "ensemble", device="cpu")
    assert [m.path.name for m in run.members] == ["1", "2"]
    assert load_run(runs / "single_0", device="cpu").members == ()


def test_the_ensemble_answers_with_its_models_mean(runs, graph):
    ens = load_run(runs / "ensemble", device="cpu")
    singles = [load_run(runs / f"single_{s}", device="cpu") for s in range(3)]
    t = _tensors(graph, ens.vocab)
    (pred,), (prior,) = forward(ens, [t])
    each = [forward(r, [t]) for r in singles]
    probs = [e[0][0].probs for e in each]
    assert not np.allclose(probs[0], probs[1], atol=1e-3)  # the models differ ...
    np.testing.assert_allclose(pred.probs, np.mean(probs, axis=0), atol=1e-12)  # ... and are averaged
    np.testing.assert_allclose(pred.origin, np.mean([e[0][0].origin for e in each], axis=0), atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(pred.direction, axis=1), 1.0, atol=1e-9)
    assert np.all(np.sum(pred.direction * each[0][0][0].direction, axis=1) >= 0)  # signed as the first
    np.testing.assert_allclose(prior.axis_prob.sum(axis=1), 1.0, atol=1e-9)
    np.testing.assert_array_equal(prior.axis_dirs, each[0][1][0].axis_dirs)
    # an ensemble of one model's answer three times is that answer
    (p0,), (q0,) = each[0]
    same, same_prior = average_members([p0] * 3, [q0] * 3)
    np.testing.assert_allclose(same.probs, p0.probs, atol=1e-12)
    np.testing.assert_allclose(np.abs(np.sum(same.direction * p0.direction, axis=1)), 1.0, atol=1e-9)
    np.testing.assert_allclose(same_prior.axis_prob, q0.axis_prob, atol=1e-12)
    # the whole inference path (quarter turns included) takes the members
    a, _ = infer_edges_with_priors(ens, [graph], turns="always")
    b, _ = infer_edges_with_priors(singles[0], [graph], turns="always")
    assert not np.allclose(a[0].probs, b[0].probs, atol=1e-3)


def test_a_member_of_another_vocabulary_is_refused(tmp_path):
    _save(tmp_path / "run", 0)
    _save(tmp_path / "run" / "members" / "1", 1, SemanticVocab(["door", "drawer"]))
    with pytest.raises(KinmoDataError, match="members/1.*vocabulary"):
        load_run(tmp_path / "run", device="cpu")


def test_members_are_trained_on_the_run_split_and_travel_in_the_bundle(tiny_gnn, tmp_path):
    import shutil

    from kinmo.inference.bundle import write_bundle
    from kinmo.train.gnn import train_members

    run_dir = tmp_path / "run"
    shutil.copytree(tiny_gnn["run"], run_dir)
    base = load_run(run_dir, device="cpu")
    trained = train_members(tiny_gnn["cache"], run_dir, base.config, 2, progress=False)
    assert [r.run_dir.name for r in trained] == ["1", "2"]
    assert [r.config.seed for r in trained] == [base.config.seed + 1, base.config.seed + 2]
    assert all(r.split.train == trained[0].split.train for r in trained)
    assert train_members(tiny_gnn["cache"], run_dir, base.config, 2, progress=False) == []  # resumes
    run = load_run(run_dir, device="cpu")
    assert len(run.members) == 2
    w0 = next(iter(run.model.state_dict().values()))
    assert not torch.equal(w0, next(iter(run.members[0].model.state_dict().values())))
    bundle = write_bundle(tmp_path / "bundle", run_dir, check=run_dir)
    assert len(load_run(bundle.gnn, device="cpu").members) == 2
    assert len(load_run(bundle.check, device="cpu").members) == 2
    # a run without a split of its own has none to give its members
    with pytest.raises(KinmoDataError, match="split"):
        train_members(tiny_gnn["cache"], tmp_path / "empty", base.config, 1, progress=False)
