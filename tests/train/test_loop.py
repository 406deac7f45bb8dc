"""The training plumbing shared by the three trainers (kinmo.train.loop), and the module
boundaries it allows (ANCSH evaluation without the trainer)."""

from __future__ import annotations

import csv
import io
import subprocess
import sys

import pytest
import torch

from kinmo.errors import KinmoDataError
from kinmo.parallel import torch_threads
from kinmo.train.loop import (
    build_or_refuse,
    load_checkpoint,
    optimizer_step,
    override,
    preset_values,
    rows_csv,
    save_checkpoint,
    training_session,
)


def test_preset_values_are_fresh_copies_and_overrides_are_checked():
    presets = {"a": {"x": 1, "nested": {"y": [1, 2]}}, "b": lambda: {"x": 2, "nested": {}}}
    v = preset_values(presets, "a")
    v["nested"]["y"].append(3)
    assert presets["a"]["nested"]["y"] == [1, 2]  # deep copy
    assert preset_values(presets, "b") == {"x": 2, "nested": {}}
    with pytest.raises(ValueError, match=r"unknown preset 'c' \(choose from a, b\)"):
        preset_values(presets, "c")
    assert override(v, {"x": 5, "nested": None}) == {"x": 5, "nested": {"y": [1, 2, 3]}}
    with pytest.raises(ValueError, match="unknown ANCSH training option 'wings'"):
        override(v, {"wings": 2}, "ANCSH training")


def test_the_three_trainers_share_the_preset_errors():
    from kinmo.ancsh.config import preset as ancsh_preset
    from kinmo.refine.axis_config import preset_config
    from kinmo.train.config import preset as gnn_preset

    for make in (gnn_preset, ancsh_preset, preset_config):
        with pytest.raises(ValueError, match=r"unknown preset 'huge' \(choose from quick, paper"):
            make("huge")


def test_rows_csv_formats_floats_nan_and_missing_cells():
    rows = [{"epoch": 1, "loss": 0.123456789, "acc": float("nan"), "extra": "ignored"},
            {"epoch": 2, "loss": 2.0, "kept": True}]
    text = rows_csv(rows, ("epoch", "loss", "acc", "kept"))
    assert text == "epoch,loss,acc,kept\n1,0.123457,,\n2,2,,True\n"
    raw = rows_csv(rows, ("epoch", "loss", "acc"), digits=None, nan="nan")
    got = list(csv.DictReader(io.StringIO(raw)))
    assert got[0] == {"epoch": "1", "loss": "0.123456789", "acc": "nan"}


def test_training_session_seeds_and_restores_torch_settings():
    before_threads = torch.get_num_threads()
    before_det = torch.are_deterministic_algorithms_enabled()
    want = 1 if before_threads != 1 else 2
    with training_session("cpu", seed=11, threads=want, deterministic=not before_det) as (info, dev):
        assert torch.get_num_threads() == want
        assert torch.are_deterministic_algorithms_enabled() is (not before_det)
        assert dev == torch.device("cpu") and info.world_size == 1 and info.is_main
        a = torch.rand(3)
    assert torch.get_num_threads() == before_threads
    assert torch.are_deterministic_algorithms_enabled() is before_det
    with training_session("cpu", seed=11):
        assert torch.equal(torch.rand(3), a)
    with torch_threads(0):
        assert torch.get_num_threads() == before_threads
    if not torch.cuda.is_available():
        with pytest.raises(ValueError, match="CUDA is not available"), training_session("cuda"):
            pass


def test_optimizer_step_weights_and_clips():
    torch.manual_seed(0)
    model = torch.nn.Linear(3, 1)
    x = torch.randn(8, 3)
    w0 = model.weight.detach().clone()
    opt = torch.optim.SGD(model.parameters(), lr=1.0)
    optimizer_step(opt, (model(x) ** 2).mean() * 1e6, model, weight=1.0, grad_clip=0.5)
    assert torch.linalg.vector_norm(model.weight.detach() - w0) <= 0.5 + 1e-6  # clipped step
    w1 = model.weight.detach().clone()
    optimizer_step(opt, (model(x) ** 2).mean(), model, weight=0.0)
    assert torch.equal(model.weight.detach(), w1)  # a zero-weight rank changes nothing


def test_checkpoints_round_trip_and_refuse_foreign_or_missing_files(tmp_path):
    model = torch.nn.Linear(2, 2)
    path = save_checkpoint(tmp_path / "run" / "model.pt", "kinmo-test", model, epoch=3, config={"a": 1})
    payload, ckpt = load_checkpoint(tmp_path / "run", "kinmo-test", "test-net", "kinmo train test")
    assert ckpt == path and payload["epoch"] == 3 and payload["config"] == {"a": 1}
    assert list(payload)[:3] == ["format", "version", "state_dict"]
    assert all(torch.equal(payload["state_dict"][k], v) for k, v in model.state_dict().items())
    assert not list((tmp_path / "run").glob("*.tmp*"))  # written atomically, nothing left over
    with pytest.raises(KinmoDataError, match=r"test-net checkpoint is missing \(train with `kinmo train test`\)"):
        load_checkpoint(tmp_path / "none", "kinmo-test", "test-net", "kinmo train test")
    torch.save({"format": "other", "state_dict": {}}, tmp_path / "other.pt")
    with pytest.raises(KinmoDataError, match="not a kinmo test-net checkpoint"):
        load_checkpoint(tmp_path / "other.pt", "kinmo-test", "test-net", "kinmo train test")

    def build():
        m = torch.nn.Linear(3, 3)
        m.load_state_dict(payload["state_dict"])
        return m

    with pytest.raises(KinmoDataError, match="model.pt: checkpoint does not match the model"):
        build_or_refuse(ckpt, build)


def test_ancsh_evaluation_does_not_import_the_trainer():
    code = ("import sys, kinmo.ancsh.evaluate, kinmo.ancsh.inference, kinmo.ancsh.table2; "
            "print(sorted(m for m in sys.modules if m in ('kinmo.ancsh.train', 'kinmo.ancsh.fit', "
            "'kinmo.ancsh.semi')))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]", out.stdout + out.stderr


def test_tiny_presets_shorten_quick_and_the_trainer_clis_read_kinmo_preset(tmp_path, monkeypatch):
    from typer.testing import CliRunner

    from kinmo.ancsh.config import preset as ancsh_preset
    from kinmo.cli import app
    from kinmo.refine.axis_config import preset_config
    from kinmo.train.config import preset as gnn_preset

    g, a, s = gnn_preset("tiny"), preset_config("tiny"), ancsh_preset("tiny")
    assert (g.preset, g.epochs, g.model) == ("tiny", 25, gnn_preset("quick").model)
    assert (a.preset, a.epochs, a.net) == ("tiny", 2, preset_config("quick").net)
    assert (s.preset, s.epochs, s.semi_epochs, s.steps_per_epoch, s.frames_per_object) == ("tiny", 1, 1, 2, 1)
    assert s.width == ancsh_preset("quick").width
    # KINMO_PRESET is read by every trainer's --preset (a bad one is refused before any work)
    monkeypatch.setenv("KINMO_PRESET", "huge")
    for argv in (["train", "gnn", "--data", str(tmp_path), "--out", str(tmp_path / "g")],
                 ["train", "axis", "--data", str(tmp_path), "--out", str(tmp_path / "a")],
                 ["train", "ancsh", "--category", "Laptop", "--data", str(tmp_path), "--out", str(tmp_path / "s")]):
        r = CliRunner().invoke(app, argv)
        assert r.exit_code == 2 and "unknown preset 'huge'" in r.output, (argv, r.output)
