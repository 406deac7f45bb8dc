"""Articulated training triples, whole-shape inputs, batched multi-angle scoring and
per-category axis networks (kinmo.refine.axis_data / feasibility / axis_io / train)."""

from __future__ import annotations

import csv
import dataclasses
import json

import numpy as np
import torch

from kinmo.refine.axis_data import _negative_line, build_triples, moving_edges
from kinmo.refine.axis_io import AxisModelSet, load_axis_model, load_axis_models
from kinmo.refine.axis_net import AxisNetConfig, AxisSelectionNet
from kinmo.refine.candidates import candidate_axes
from kinmo.refine.feasibility import PAPER_ANGLES, LineRequest, score_lines
from kinmo.refine.motions import MotionAmounts, edge_cloud
from kinmo.refine.train import preset_config, train_axis_model

from .refine_boxes import box_cabinet

torch.set_num_threads(1)

TINY_NET = {"n_points": 64, "k": 8, "widths": [8, 8, 16], "emb_dim": 16, "head": [16],
            "dropout": 0.0}


def _to_plain(art: np.ndarray, plain: np.ndarray, m: int) -> np.ndarray:
    """Map clouds of one frame to another through their common static rows (scale + shift)."""
    ra, rp = art[0, m:, :3], plain[0, m:, :3]
    ca, cp = ra - ra.mean(axis=0), rp - rp.mean(axis=0)
    k = float((ca * cp).sum() / (ca * ca).sum())
    off = (rp - k * ra).mean(axis=0)
    np.testing.assert_allclose(k * ra + off, rp, atol=1e-5)  # truly a similarity
    return k * art[..., :3] + off


def test_articulated_rest_states_move_along_the_true_axis():
    g = box_cabinet(256)
    door = moving_edges([g])[:1]  # R_V_S, limit -90..0 about +y: opens towards +z
    kw = {"net": {**TINY_NET, "n_points": 200}, "flip_prob": 1.0, "mirror_prob": 0.0}
    plain = build_triples([g], door, preset_config("quick", articulated_prob=0.0, **kw),
                          np.random.default_rng(3))
    art = build_triples([g], door, preset_config("quick", articulated_prob=1.0, **kw),
                        np.random.default_rng(3))
    m = 100
    rest_p, pos_p, neg_p = plain
    rest_a, pos_a, neg_a = (_to_plain(x, rest_p, m) for x in art)
    z = lambda c: float(c[0, :m, 2].mean())  # noqa: E731
    # the articulated rest lies between the closed door and the positive end state ...
    assert z(rest_p[..., :3]) + 1e-3 < z(rest_a) < z(pos_p[..., :3]) - 1e-3
    # ... which is the same absolute state: the positive does the rest of the way
    np.testing.assert_allclose(pos_a[0], pos_p[0, :, :3], atol=1e-5)
    # the flip negative turns back past the closed pose, into the cabinet
    assert z(neg_a) < z(rest_p[..., :3]) - 1e-3
    # static rows of one triple share the frame; the mask channel is unchanged
    np.testing.assert_array_equal(art[1][:, m:], art[0][:, m:])
    np.testing.assert_array_equal(art[0][..., 3], plain[0][..., 3])


def test_negative_lines_span_every_orientation_or_only_the_fine_type():
    g = box_cabinet(128)
    door = moving_edges([g])[0]
    obb = (g.obb_center[door.moving], g.obb_axes[door.moving], g.obb_half_extents[door.moving])
    diag = 2 * float(np.linalg.norm(obb[2]))
    cos = {}
    for hard in (0.0, 1.0):
        cfg = preset_config("quick", hard_negative_prob=hard)
        lines = [_negative_line(g, door, cfg, obb, diag, np.random.default_rng(s))
                 for s in range(40)]
        cos[hard] = np.array([abs(d @ door.direction) / np.linalg.norm(d) for _, d in lines])
        # never the true axis itself
        for o, d in lines:
            off = np.linalg.norm(np.cross(door.origin - o, d / np.linalg.norm(d)))
            assert abs(d @ door.direction) / np.linalg.norm(d) < 0.98 or off > 0.1 * diag
    assert np.all(cos[1.0] > 0.98)  # R_V_S candidates: vertical lines only
    assert np.any(cos[0.0] < 0.1)  # coarse R candidates: horizontal ones too


def test_whole_shape_input_masks_the_moving_part():
    g = box_cabinet(256)
    net = AxisNetConfig(**TINY_NET, input="shape")
    pc = edge_cloud(g, 2, 1, net, 0)
    assert pc.points.shape == (64, 3) and pc.n_moving == 32
    # static points: anywhere on the shape but the door (the knob, the drawer, the body)
    door_pts = g.points[2]
    d = np.linalg.norm(pc.points[32:, None] - door_pts[None], axis=-1).min(axis=1)
    assert np.all(d > 1e-9)
    body = g.points[1]
    on_body = np.linalg.norm(pc.points[32:, None] - body[None], axis=-1).min(axis=1) < 1e-9
    assert 0 < on_body.sum() < 32  # not only the reference part
    np.testing.assert_array_equal(pc.flags, [1.0] * 32 + [0.0] * 32)


def _requests(g):
    reqs = []
    for k, me in enumerate(moving_edges([g])):
        obb = (g.obb_center[me.moving], g.obb_axes[me.moving], g.obb_half_extents[me.moving])
        c = candidate_axes(obb, me.fine_type, g.points[me.moving], g.points[me.reference])
        reqs.append(LineRequest(g, me.moving, me.reference, c, seed=(7, k)))
    return reqs


def test_score_lines_shapes_determinism_and_batching():
    torch.manual_seed(0)
    net = AxisSelectionNet(AxisNetConfig(**TINY_NET)).eval()
    g1, g2 = box_cabinet(128, seed=1, shape_id="a"), box_cabinet(128, seed=2, shape_id="b")
    reqs = _requests(g1) + _requests(g2)
    res = score_lines(net, reqs, chunk=5)
    assert len(res) == len(reqs) == 6
    for r, lf in zip(reqs, res, strict=True):
        c = len(r.candidates)
        a = len(PAPER_ANGLES) if r.candidates.motion != "P" else 1
        assert lf.per_motion.shape == (c, 2, a)
        np.testing.assert_allclose(lf.feasibility, lf.per_motion.mean(axis=(1, 2)))
        np.testing.assert_allclose(lf.positive, lf.per_motion[:, 0].mean(axis=1))
        np.testing.assert_allclose(lf.negative, lf.per_motion[:, 1].mean(axis=1))
        assert np.all((lf.per_motion >= 0) & (lf.per_motion <= 1))
        np.testing.assert_array_equal(lf.sign, np.where(lf.negative > lf.positive, -1, 1))
    # deterministic for a seed, independent of batching and chunking
    again = score_lines(net, reqs, chunk=64)
    one_by_one = [score_lines(net, [r])[0] for r in reqs]
    for x, y, z in zip(res, again, one_by_one, strict=True):
        np.testing.assert_allclose(x.per_motion, y.per_motion, atol=1e-5)
        np.testing.assert_allclose(x.per_motion, z.per_motion, atol=1e-5)
    # the unbatched network call on the same clouds gives the same values
    r = reqs[0]
    from kinmo.refine.motions import candidate_motions, network_inputs

    obb = (g1.obb_center[r.moving], g1.obb_axes[r.moving], g1.obb_half_extents[r.moving])
    mot = candidate_motions(r.candidates, obb, MotionAmounts(PAPER_ANGLES))
    pair = edge_cloud(g1, r.moving, r.reference, net.config, np.random.default_rng(r.seed))
    rest, moved = network_inputs(pair, mot.origins, mot.directions, mot.angles, mot.translations)
    ref = net.feasibility(torch.from_numpy(rest), torch.from_numpy(moved)).numpy()
    np.testing.assert_allclose(res[0].per_motion.reshape(-1), ref, atol=1e-5)
    # an angle subset is the mean over those amounts only
    sub = res[0].subset([0, 3])
    np.testing.assert_allclose(sub.feasibility, res[0].per_motion[:, :, [0, 3]].mean(axis=(1, 2)))
    # a different seed samples other points
    other = score_lines(net, [dataclasses.replace(reqs[0], seed=(8, 0))])[0]
    assert not np.allclose(other.per_motion, res[0].per_motion)


def test_model_set_picks_the_category_network_and_falls_back():
    torch.manual_seed(0)
    glob = AxisSelectionNet(AxisNetConfig(**TINY_NET)).eval()
    torch.manual_seed(1)
    cab = AxisSelectionNet(AxisNetConfig(**TINY_NET)).eval()
    models = AxisModelSet(glob, {"StorageFurniture": cab})
    g = box_cabinet(128)
    other = box_cabinet(128)
    other.category = "Oven"
    r1, r2 = _requests(g)[0], _requests(other)[0]
    got = score_lines(models, [r1, r2])
    np.testing.assert_allclose(got[0].per_motion, score_lines(cab, [r1])[0].per_motion,
                               atol=1e-6)
    np.testing.assert_allclose(got[1].per_motion, score_lines(glob, [r2])[0].per_motion,
                               atol=1e-6)
    assert not np.allclose(got[0].per_motion, score_lines(glob, [r1])[0].per_motion)


def test_per_category_networks_are_kept_only_when_better(tmp_path):
    gs = [box_cabinet(128, seed=s, jitter=0.2, shape_id=f"b{s}") for s in range(6)]
    for g in gs[3:]:
        g.category = "Oven"
    cfg = preset_config("quick", epochs=1, batch_size=4, test_fraction=0.0, val_fraction=0.34,
                        net=TINY_NET, category_min_objects=2, category_epochs=2,
                        angles_deg=(45.0, 80.0), sign_mode="mean", articulated_prob=0.5)
    train_axis_model(gs, tmp_path / "run", cfg, progress=False)
    with open(tmp_path / "run" / "categories.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert sorted(r["category"] for r in rows) == ["Oven", "StorageFurniture"]
    index = json.loads((tmp_path / "run" / "categories.json").read_text())
    assert index["rule"]["min_train_objects"] == 2
    models = load_axis_models(tmp_path / "run")
    glob = load_axis_model(tmp_path / "run")
    for r in rows:
        kept = r["kept"] == "True"
        assert kept == (float(r["category_select_acc"]) > float(r["global_select_acc"]))
        assert (r["category"] in index["categories"]) == kept
        net = load_axis_model(tmp_path / "run", category=r["category"])
        same = all(torch.equal(a, b) for a, b in zip(net.state_dict().values(),
                                                     glob.state_dict().values(), strict=True))
        assert same != kept
        assert (models.for_category(r["category"]) is not models.global_model) == kept
    assert models.for_category("Nothing") is models.global_model
    # a category below the rule gets no network of its own
    cfg2 = cfg.model_copy(update={"category_min_objects": 3})
    train_axis_model(gs, tmp_path / "run2", cfg2, progress=False)
    assert json.loads((tmp_path / "run2" / "categories.json").read_text())["categories"] == {}


def test_paper_preset_starts():
    cfg = preset_config("paper")
    assert cfg.net.n_points == 4096 and cfg.net.input == "shape"
    assert cfg.articulated_prob == 0.5 and tuple(cfg.angles_deg) == PAPER_ANGLES
    net = AxisSelectionNet(cfg.net)
    g = box_cabinet(64)
    rest, pos, neg = build_triples([g], moving_edges([g])[:1], cfg, np.random.default_rng(0))
    assert rest.shape == (1, 4096, 4)
    net.train()
    logits = net(torch.from_numpy(np.concatenate([rest, rest])),
                 torch.from_numpy(np.concatenate([pos, neg])))
    assert logits.shape == (2,) and torch.isfinite(logits).all()


def test_progress_bar_tasks_end_at_their_totals(tmp_path, monkeypatch):
    """The axis network's bar and the per-category networks' have their own totals, and each
    ends exactly at it (the category fine-tuning once ran the base task to 612/528)."""
    import kinmo.refine.train as axis_train

    tasks: dict[str, list[int]] = {}

    class Recording:
        def __enter__(self):
            return self

        def __exit__(self, *exc):
            return False

        def task(self, description, total):
            tasks[description] = [total, 0]
            return description

        def advance(self, task, n=1, info=None):
            tasks[task][1] += n

        def describe(self, task, description):
            pass

        def log(self, text):
            pass

    monkeypatch.setattr(axis_train, "training_bar", lambda progress, title: Recording())
    gs = [box_cabinet(128, seed=s, jitter=0.2, shape_id=f"b{s}") for s in range(6)]
    for g in gs[3:]:
        g.category = "Oven"
    cfg = preset_config("quick", epochs=2, batch_size=4, test_fraction=0.0, val_fraction=0.34,
                        net=TINY_NET, category_min_objects=2, category_epochs=2, samples_per_shape=3)
    train_axis_model(gs, tmp_path / "run", cfg, progress=True)
    assert set(tasks) == {"axis net", "category nets"}
    for name, (total, done) in tasks.items():
        assert total > 0 and done == total, (name, total, done)
