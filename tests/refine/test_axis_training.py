"""Training data and the training run of the axis network (kinmo.refine.train)."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest
import torch

from kinmo.data.graph import PartGraph
from kinmo.refine.train import (
    build_triples,
    equivalent_lines,
    load_axis_model,
    moving_edges,
    preset_config,
    split_graphs,
    train_axis_model,
)

from .refine_boxes import box_cabinet

torch.set_num_threads(1)

TINY_NET = {"n_points": 64, "k": 8, "widths": [8, 8, 16], "emb_dim": 16, "head": [16],
            "dropout": 0.0}


def test_moving_edges_carry_labels_and_limits():
    g = box_cabinet(64)
    es = moving_edges([g])
    assert [e.fine_type for e in es] == ["R_V_S", "P_H", "R_H_C"]
    door, drawer, knob = es
    assert (door.moving, door.reference) == (2, 1) and door.limit == (-90.0, 0.0)
    assert drawer.limit[1] > 0 and knob.limit is None
    np.testing.assert_allclose(door.direction, [0, 1, 0])


def test_triples_move_the_part_about_the_true_axis_inside_its_limits():
    g = box_cabinet(256)
    es = moving_edges([g])
    cfg = preset_config("quick", net={**TINY_NET, "n_points": 200}, flip_prob=1.0,
                        mirror_prob=0.0)
    rest, pos, neg = build_triples([g], es, cfg, np.random.default_rng(0))
    assert rest.shape == pos.shape == neg.shape == (3, 200, 4)
    m = 100
    # reference points never move, the moving ones always do
    np.testing.assert_array_equal(pos[:, m:], rest[:, m:])
    np.testing.assert_array_equal(neg[:, m:], rest[:, m:])
    assert np.all(np.abs(pos[:, :m, :3] - rest[:, :m, :3]).max(axis=(1, 2)) > 1e-3)
    # door (limit -90..0 about +y, i.e. opening outwards): the free edge comes forwards (+z)
    assert pos[0, :m, 2].mean() > rest[0, :m, 2].mean()
    # flip_prob = 1: the negative is the forbidden direction (into the cabinet)
    assert neg[0, :m, 2].mean() < rest[0, :m, 2].mean()
    # drawer (0..0.3 depth along +z): slides out, not sideways, by 30-90 % of its range
    shift = (pos[1, :m, :3] - rest[1, :m, :3]).mean(axis=0)
    assert shift[2] > 0 and abs(shift[0]) < 1e-6 and abs(shift[1]) < 1e-6
    # knob: a rotation about its own (z) axis keeps z and all distances between its points
    np.testing.assert_allclose(pos[2, :m, 2], rest[2, :m, 2], atol=1e-6)
    d0 = np.linalg.norm(rest[2, :m, None, :3] - rest[2, None, :m, :3], axis=-1)
    d1 = np.linalg.norm(pos[2, :m, None, :3] - pos[2, None, :m, :3], axis=-1)
    np.testing.assert_allclose(d0, d1, atol=1e-5)
    assert np.abs(pos[2, :m, :2] - rest[2, :m, :2]).max() > 1e-3


def test_mirror_augmentation_flips_x_only():
    g = box_cabinet(128)
    es = moving_edges([g])
    plain = preset_config("quick", net=TINY_NET, mirror_prob=0.0)
    mirrored = preset_config("quick", net=TINY_NET, mirror_prob=1.0)
    a = build_triples([g], es, plain, np.random.default_rng(5))
    b = build_triples([g], es, mirrored, np.random.default_rng(5))
    for x, y in zip(a, b, strict=True):
        np.testing.assert_array_equal(y[..., 0], -x[..., 0])
        np.testing.assert_array_equal(y[..., 1:], x[..., 1:])


def test_equivalent_lines():
    o = np.array([[0, 0, 0], [0.05, 0, 0], [1, 0, 0], [0, 0, 0]], float)
    d = np.array([[0, 1, 0], [0, 1, 0], [0, 1, 0], [1, 0, 0]], float)
    m = equivalent_lines(o, d, [0, 5, 0], [0, -1, 0], True, 1.0)
    np.testing.assert_array_equal(m, [True, True, False, False])
    m = equivalent_lines(o, d, [0, 5, 0], [0, -1, 0], False, 1.0)
    np.testing.assert_array_equal(m, [True, True, True, False])


def test_split_excludes_the_gnn_test_shapes():
    gs = [box_cabinet(16, seed=s, shape_id=f"s{s}") for s in range(8)]
    cfg = preset_config("quick", test_fraction=0.25, val_fraction=0.34)
    tr, va, test = split_graphs(gs, cfg)
    ids = {gs[k].shape_id for k in tr + va}
    assert len(test) == 2 and not ids & set(test) and len(ids) == 6
    assert len(va) == 2 and not set(tr) & set(va)
    from kinmo.train.split import make_split

    assert test == make_split([g.shape_id for g in gs], [g.category for g in gs], 0.25, 0).test
    from kinmo.train.split import Split

    # an explicit split: only its test ids are excluded
    tr2, va2, test2 = split_graphs(gs, cfg, Split(train=[], test=["s0"]))
    assert test2 == ["s0"] and 0 not in tr2 + va2 and len(tr2) + len(va2) == 7


def test_training_run_writes_a_reproducible_loadable_model(tmp_path):
    gs = [box_cabinet(128, seed=s, jitter=0.2, shape_id=f"b{s}") for s in range(4)]
    # the graphs go through the cache format once
    for g in gs:
        g.save(tmp_path / "cache" / f"{g.shape_id}.npz")
    cfg = preset_config("quick", epochs=2, batch_size=4, test_fraction=0.0, val_fraction=0.25,
                        net=TINY_NET)
    res = train_axis_model(tmp_path / "cache", tmp_path / "run", cfg, progress=False)
    assert res.n_train_edges == 9 and res.n_val_edges == 3
    with open(tmp_path / "run" / "metrics.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert [int(r["epoch"]) for r in rows] == [1, 2]
    for r in rows:
        assert np.isfinite(float(r["train_loss"]))
    # quick validates every 3rd epoch and at the last one
    assert np.isnan(float(rows[0]["val_select_acc"]))
    assert 0 <= float(rows[1]["val_select_acc"]) <= float(rows[1]["val_select_coverage"]) <= 1
    conf = json.loads((tmp_path / "run" / "config.json").read_text())
    assert conf["config"]["net"] == {**TINY_NET, "norm": "batch", "dynamic": True,
                                     "context_fraction": 0.25, "crop": None, "input": "pair"}
    assert len(conf["split"]["val"]) == 1
    model = load_axis_model(tmp_path / "run")
    assert not model.training and model.config.n_points == 64
    res2 = train_axis_model(gs, tmp_path / "run2", cfg, progress=False)
    assert res2.metrics[-1]["train_loss"] == pytest.approx(res.metrics[-1]["train_loss"])
    # quick trains on one torch thread: the same seed gives bit-identical weights
    assert conf["config"]["threads"] == 1
    w1, w2 = load_axis_model(tmp_path / "run").state_dict(), load_axis_model(tmp_path / "run2").state_dict()
    assert w1.keys() == w2.keys() and all(torch.equal(w1[k], w2[k]) for k in w1)
    from kinmo.errors import KinmoDataError

    with pytest.raises(KinmoDataError, match="does not exist"):
        train_axis_model(tmp_path / "nothing", tmp_path / "run3", cfg, progress=False)
    unlabelled = box_cabinet(16, shape_id="u")
    unlabelled.edge_fine = unlabelled.edge_axis_origin = unlabelled.edge_axis_direction = None
    unlabelled.save(tmp_path / "partnet" / "u.npz")
    with pytest.raises(KinmoDataError, match="no labelled"):
        train_axis_model(tmp_path / "partnet", tmp_path / "run3", cfg, progress=False)


def test_load_axis_model_errors(tmp_path):
    from kinmo.errors import KinmoDataError

    with pytest.raises(KinmoDataError, match="model.pt"):
        load_axis_model(tmp_path)
    (tmp_path / "bad.pt").write_bytes(b"not a checkpoint")
    with pytest.raises(KinmoDataError, match="bad.pt"):
        load_axis_model(tmp_path / "bad.pt")
    assert isinstance(box_cabinet(8), PartGraph)
