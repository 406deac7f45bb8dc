import torch

from kinmo.ancsh.model import ANCSH, ancsh_loss
from kinmo.ancsh.pointnet2 import ball_query, farthest_point_sample


def _tiny(n_parts=3, n_joints=2):
    torch.manual_seed(0)
    return ANCSH(n_parts, n_joints, width=8, n_centers=(16, 8, 4), radii=(0.2, 0.4, 0.8))


def _target(b, n, k, j, g):
    seg = torch.randint(0, k, (b, n), generator=g)
    joint = torch.randint(0, j + 1, (b, n), generator=g)
    return {
        "seg": seg,
        "npcs": torch.rand(b, n, 3, generator=g),
        "naocs": torch.rand(b, n, 3, generator=g),
        "heatmap": torch.rand(b, n, generator=g),
        "unitvec": torch.nn.functional.normalize(torch.randn(b, n, 3, generator=g), dim=-1),
        "axis": torch.nn.functional.normalize(torch.randn(b, n, 3, generator=g), dim=-1),
        "joint": joint,
    }


def test_fps_returns_spread_out_distinct_points():
    g = torch.Generator().manual_seed(0)
    xyz = torch.rand(2, 200, 3, generator=g)
    idx = farthest_point_sample(xyz, 20)
    assert idx.shape == (2, 20)
    for b in range(2):
        assert len(set(idx[b].tolist())) == 20
    # FPS covers space better than the first 20 points
    sel = xyz[0, idx[0]]
    d_fps = torch.cdist(sel, sel).add(torch.eye(20) * 10).min().item()
    d_first = torch.cdist(xyz[0, :20], xyz[0, :20]).add(torch.eye(20) * 10).min().item()
    assert d_fps > d_first


def test_ball_query_neighbours_within_radius():
    g = torch.Generator().manual_seed(1)
    xyz = torch.rand(1, 300, 3, generator=g)
    centers = xyz[:, :10]
    idx = ball_query(0.2, 16, xyz, centers)
    assert idx.shape == (1, 10, 16)
    d = (xyz[0, idx[0]] - centers[0, :, None]).norm(dim=-1)
    assert (d <= 0.2 + 1e-6).all()


def test_ancsh_shapes_and_ranges():
    m = _tiny().eval()
    out = m(torch.rand(2, 128, 3) - 0.5)
    assert out["seg_logits"].shape == (2, 128, 3)
    assert out["npcs"].shape == (2, 128, 3, 3)
    assert out["naocs"].shape == (2, 128, 3)
    assert out["heatmap"].shape == (2, 128)
    assert out["joint_logits"].shape == (2, 128, 3)
    assert torch.allclose(out["axis"].norm(dim=-1), torch.ones(2, 128), atol=1e-5)
    assert ((out["npcs"] >= 0) & (out["npcs"] <= 1)).all()


def test_ancsh_loss_backprop_reaches_every_parameter_and_overfits():
    m = _tiny().train()
    g = torch.Generator().manual_seed(0)
    xyz = torch.rand(2, 32, 3, generator=g) - 0.5
    tgt = _target(2, 32, 3, 2, g)
    opt = torch.optim.Adam(m.parameters(), lr=1e-2)
    losses = []
    for step in range(40):
        opt.zero_grad()
        terms = ancsh_loss(m(xyz), tgt)
        terms["total"].backward()
        if step == 0:
            for name, p in m.named_parameters():
                assert p.grad is not None and torch.isfinite(p.grad).all(), name
        opt.step()
        losses.append(terms["total"].item())
    assert min(losses[-5:]) < 0.7 * losses[0]


def test_perfect_prediction_has_zero_regression_loss():
    g = torch.Generator().manual_seed(2)
    b, n, k, j = 1, 50, 3, 2
    tgt = _target(b, n, k, j, g)
    npcs = torch.rand(b, n, k, 3, generator=g)
    npcs.scatter_(2, tgt["seg"][..., None, None].expand(-1, -1, 1, 3), tgt["npcs"][:, :, None])
    pred = {
        "seg_logits": torch.nn.functional.one_hot(tgt["seg"], k).float() * 100,
        "npcs": npcs,
        "naocs": tgt["naocs"],
        "heatmap": tgt["heatmap"],
        "unitvec": tgt["unitvec"],
        "axis": -tgt["axis"],  # the sign of an axis does not matter
        "joint_logits": torch.nn.functional.one_hot(tgt["joint"], j + 1).float() * 100,
    }
    terms = ancsh_loss(pred, tgt)
    for name in ("seg", "npcs", "naocs", "heatmap", "unitvec", "axis", "joint_cls"):
        assert terms[name].item() < 1e-5, name
