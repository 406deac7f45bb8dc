"""The refinement options reach the Table 1 evaluation (kinmo.evaluate.pre_segmented)."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from kinmo.refine.refine import RefineConfig
from kinmo.refine.scoring import ScoringConfig

from .refine_boxes import box_cabinet

torch.set_num_threads(1)


@pytest.fixture(scope="module")
def setup(tmp_path_factory):
    from kinmo.features import SemanticVocab
    from kinmo.models.motion_gnn import MotionGNN
    from kinmo.refine.axis_net import AxisNetConfig, AxisSelectionNet
    from kinmo.refine.train import save_axis_model
    from kinmo.train.config import preset
    from kinmo.train.gnn import save_checkpoint

    root = tmp_path_factory.mktemp("evalcfg")
    for s in range(2):
        box_cabinet(128, seed=s, jitter=0.1, shape_id=f"t{s}").save(root / "cache" / f"t{s}.npz")
    torch.manual_seed(0)
    c = preset("quick", types="fine")
    save_checkpoint(root / "fine" / "model.pt", MotionGNN(c.model), c, SemanticVocab(), None, 0)
    net = AxisSelectionNet(AxisNetConfig(n_points=64, k=8, widths=[8, 8, 16], emb_dim=16,
                                         head=[16], dropout=0.0))
    save_axis_model(root / "axis" / "model.pt", net)
    return root


@pytest.fixture
def seen(monkeypatch):
    """The RefineConfig of every refine_shape_prediction call (the real function still runs)."""
    import kinmo.inference.predictor as ip

    configs = []
    real = ip.refine_shape_prediction

    def spy(prediction, axis_model, config=None, options=None, meshes=None):
        configs.append(config)
        return real(prediction, axis_model, config, options, meshes=meshes)

    monkeypatch.setattr(ip, "refine_shape_prediction", spy)
    return configs


def test_refine_config_is_used_for_the_obb_columns(setup, seen):
    from kinmo.evaluate.pre_segmented import run_evaluation

    # the GNN's own line always wins without the network's vote: OBB axes = GNN axes
    cfg = RefineConfig(keep_gnn=True, scoring=ScoringConfig(w_feasibility=0.0))
    rep, paths = run_evaluation([setup / "fine"], setup / "cache", out=setup / "eval",
                                all_shapes=True, device="cpu", progress=False,
                                axis_model=setup / "axis", refine_config=cfg)
    assert rep.models == ["GNN_fine", "OBB_fine"]
    assert len(seen) == 2 and all(c is cfg for c in seen)
    for key in ("angle_edge", "angle_joint"):
        g, o = rep.table[("GNN_fine", "all")][key], rep.table[("OBB_fine", "all")][key]
        assert (np.isnan(g) and np.isnan(o)) or g == pytest.approx(o, abs=1e-6)
    assert "OBB_fine" in paths["markdown"].read_text()
    seen.clear()
    run_evaluation([setup / "fine"], setup / "cache", out=setup / "eval2", all_shapes=True,
                   device="cpu", progress=False, axis_model=setup / "axis")
    assert seen == [RefineConfig()] * 2  # default: the paper's scoring


def test_cli_flags_reach_the_refinement(setup, seen):
    """``kinmo eval pre-segmented --feasibility-only --keep-gnn --snap-angle`` build the config."""
    from typer.testing import CliRunner

    from kinmo.cli import app

    args = ["eval", "pre-segmented", "--model", str(setup / "fine"), "--data", str(setup / "cache"),
            "--all", "--device", "cpu", "-q", "--axis-model", str(setup / "axis")]
    r = CliRunner().invoke(app, [*args, "--out", str(setup / "eval_cli"), "--feasibility-only",
                                 "--keep-gnn", "--snap-angle", "10",
                                 "--box-frames", "moving, reference"])
    assert r.exit_code == 0, r.output
    assert seen and all(c.scoring.feasibility_only and c.keep_gnn and c.snap_angle_deg == 10.0
                        and c.box_frames == ("moving", "reference") for c in seen)
    assert (setup / "eval_cli" / "table1.csv").is_file()
    bad = CliRunner().invoke(app, [*args, "--out", str(setup / "eval_bad"), "--snap-angle", "120"])
    assert bad.exit_code == 2
    bad = CliRunner().invoke(app, [*args, "--out", str(setup / "eval_bad"), "--box-frames", "world"])
    assert bad.exit_code == 2 and "invalid refinement option" in bad.output
    assert not (setup / "eval_bad").exists()
