"""Geometry plans of the PointNet++ backbone (:mod:`kinmo.ancsh.pointnet2`): the Rust plan
equals the PyTorch reference's indices, and the network, its losses and a training step are
the same with either, within float tolerance."""

from __future__ import annotations

import copy

import numpy as np
import pytest
import torch

from kinmo.ancsh.fit import train_step
from kinmo.ancsh.model import ANCSH, ancsh_loss
from kinmo.ancsh.pointnet2 import FPLevel, GeometryPlan, PointNet2Backbone, build_plan
from kinmo.parallel import torch_threads



@pytest.fixture(autouse=True)
def _one_thread():
    """Float rounding of the comparisons below does not depend on the suite's thread count."""
    with torch_threads(1):
        yield


SIZES = [  # (width, centres, points, batch): tiny, the quick preset, the paper preset
    (8, (16, 8, 4), 64, 2),
    (16, (128, 32, 8), 512, 8),
    (64, (512, 128, 32), 1024, 4),
]
RADII = (0.2, 0.4, 0.8)


def _scans(seed: int, b: int, n: int) -> torch.Tensor:
    """Normalised clouds (unit ball) like the training inputs, half of one padded by repeats."""
    g = torch.Generator().manual_seed(seed)
    x = torch.randn(b, n, 3, generator=g) * torch.tensor([1.0, 0.5, 0.2])
    x[0, n // 2:] = x[0, : n - n // 2]
    x = x - x.mean(1, keepdim=True)
    return x / x.norm(dim=-1).amax(1)[:, None, None]


def _items(seed: int, b: int, n: int, k: int, j: int) -> list[dict[str, torch.Tensor]]:
    g = torch.Generator().manual_seed(seed + 1)
    xyz = _scans(seed, b, n)
    return [{
        "xyz": xyz[i],
        "seg": torch.randint(0, k, (n,), generator=g),
        "npcs": torch.rand(n, 3, generator=g),
        "naocs": torch.rand(n, 3, generator=g),
        "heatmap": torch.rand(n, generator=g),
        "unitvec": torch.nn.functional.normalize(torch.randn(n, 3, generator=g), dim=-1),
        "axis": torch.nn.functional.normalize(torch.randn(n, 3, generator=g), dim=-1),
        "joint": torch.randint(0, j + 1, (n,), generator=g),
    } for i in range(b)]


@pytest.mark.parametrize(("width", "centers", "n", "b"), SIZES)
def test_rust_plan_has_the_reference_indices(width, centers, n, b):
    xyz = _scans(n, b, n)
    rust = build_plan(xyz, centers, RADII, 32, "rust")
    torch_ref = build_plan(xyz, centers, RADII, 32, "torch")
    for a, r in zip(rust.sa, torch_ref.sa):
        assert a.centers.dtype == torch.int64 and a.groups.dtype == torch.int64
        assert torch.equal(a.centers, r.centers)
        assert torch.equal(a.groups, r.groups)  # no float tie at a radius on these clouds
    for a, r in zip(rust.fp, torch_ref.fp):
        assert torch.equal(a.index, r.index)
        assert a.weight.dtype == torch.float32
        torch.testing.assert_close(a.weight.sum(-1), torch.ones(a.weight.shape[:2]))
        # cdist's matrix product leaves ~1e-4 for a point on a coarse point: weights ~0.99 vs 1
        assert float((a.weight - r.weight).abs().max()) < 0.02


def test_plan_levels_chain_and_point_on_coarse_points_weigh_one():
    xyz = _scans(3, 2, 256)
    plan = build_plan(xyz, (64, 16, 4), RADII, 16)
    assert [tuple(s.centers.shape) for s in plan.sa] == [(2, 64), (2, 16), (2, 4)]
    assert [tuple(s.groups.shape) for s in plan.sa] == [(2, 64, 16), (2, 16, 16), (2, 4, 16)]
    assert [tuple(f.index.shape) for f in plan.fp] == [(2, 16, 3), (2, 64, 3), (2, 256, 3)]
    c1 = plan.sa[0].centers
    w = torch.gather(plan.fp[2].weight[..., 0], 1, c1)  # input points that are level-1 centres
    assert torch.all(torch.gather(plan.fp[2].index[..., 0], 1, c1) == torch.arange(64))
    assert torch.all(w > 0.999999)


@pytest.mark.parametrize(("width", "centers", "n", "b"), SIZES[:2])
@pytest.mark.parametrize("train", [True, False])
def test_forward_and_losses_equal_the_reference_path(width, centers, n, b, train):
    torch.manual_seed(0)
    model = ANCSH(3, 2, width, centers, RADII).train(train)  # train: batch-norm batch statistics
    items = _items(5, b, n, 3, 2)
    xyz = torch.stack([it["xyz"] for it in items])
    target = {k: torch.stack([it[k] for it in items]) for k in items[0]}
    ref_model = copy.deepcopy(model)
    ref = ref_model.forward_reference(xyz)  # the computation before plans
    plan = model.backbone.plan(xyz)
    # the same network: with the reference's interpolation weights, equal up to float rounding
    # (~1e-5; sums in another order: matrix products instead of convolutions)
    same_weights = GeometryPlan(plan.sa, tuple(FPLevel(a.index, r.weight) for a, r in
                                               zip(plan.fp, model.backbone.plan(xyz, "torch").fp)))
    out = model(xyz, same_weights)
    for k in out:
        torch.testing.assert_close(out[k], ref[k], rtol=1e-3, atol=1e-3)
    # batch-norm running statistics and their counters move alike
    for (name, a), r in zip(model.named_buffers(), ref_model.buffers()):
        torch.testing.assert_close(a, r, rtol=1e-5, atol=1e-6, msg=name)
    # exact distances (module docstring): outputs within 1e-2, losses within 1e-4 relative
    out = model(xyz, plan)
    for k in out:
        torch.testing.assert_close(out[k], ref[k], rtol=0, atol=1e-2)
    lo, lr = ancsh_loss(out, target), ancsh_loss(ref, target)
    for k in lo:
        torch.testing.assert_close(lo[k], lr[k], rtol=1e-4, atol=1e-6)


def _grads(model: torch.nn.Module) -> torch.Tensor:
    return torch.cat([p.grad.flatten() for p in model.parameters()])


def test_gradients_equal_the_reference_gradients():
    torch.manual_seed(1)
    model = ANCSH(3, 2, 16, (128, 32, 8), RADII).train()
    items = _items(9, 8, 512, 3, 2)
    xyz = torch.stack([it["xyz"] for it in items])
    target = {k: torch.stack([it[k] for it in items]) for k in items[0]}
    ref = copy.deepcopy(model)
    ancsh_loss(ref.forward_reference(xyz), target)["total"].backward()
    plan = model.backbone.plan(xyz)
    same_weights = GeometryPlan(plan.sa, tuple(FPLevel(a.index, r.weight) for a, r in
                                               zip(plan.fp, model.backbone.plan(xyz, "torch").fp)))
    for p, tol in ((same_weights, 2e-3), (plan, 5e-2)):
        m = copy.deepcopy(model)
        ancsh_loss(m(xyz, p), target)["total"].backward()
        rel = float((_grads(m) - _grads(ref)).norm() / _grads(ref).norm())
        # the same network: 2e-5 to 5e-4 (float rounding); exact interpolation distances
        # (kinmo.ancsh.plan docstring): ~2e-2
        assert rel < tol, rel


def test_training_steps_equal_the_reference_steps():
    torch.manual_seed(1)
    model = ANCSH(3, 2, 16, (128, 32, 8), RADII)
    ref = copy.deepcopy(model)
    items = _items(9, 8, 512, 3, 2)
    for m in (model, ref):
        m.train()
    opt = torch.optim.Adam(model.parameters(), lr=2e-3)
    opt_ref = torch.optim.Adam(ref.parameters(), lr=2e-3)
    cpu = torch.device("cpu")
    for step in range(4):
        terms, _, _ = train_step(model, opt, items, cpu, grad_clip=5.0)
        terms_ref, _, _ = train_step(ref, opt_ref, items, cpu, grad_clip=5.0, reference=True)
        if step == 0:
            for k in terms:
                torch.testing.assert_close(terms[k], terms_ref[k], rtol=1e-4, atol=1e-6)
        # Adam's first updates are about lr in size whatever the gradient (and the biases
        # before batch norms have none): float-level differences become ~1e-3 of the loss
        torch.testing.assert_close(terms["total"], terms_ref["total"], rtol=5e-3, atol=0)


def test_backbone_without_plan_builds_the_rust_plan():
    torch.manual_seed(2)
    bb = PointNet2Backbone(8, (32, 8, 4), RADII).eval()
    xyz = _scans(4, 3, 128)
    with torch.no_grad():
        torch.testing.assert_close(bb(xyz), bb(xyz, bb.plan(xyz)), rtol=0, atol=0)
    plan = bb.plan(xyz)
    assert isinstance(plan, GeometryPlan)
    with pytest.raises(ValueError, match="plan is of a batch"):
        bb(xyz[:2], plan)
    with pytest.raises(ValueError, match="unknown plan backend"):
        build_plan(xyz, (32, 8, 4), RADII, 32, "cuda")  # type: ignore[arg-type]


def test_plans_are_deterministic_and_per_cloud():
    xyz = _scans(6, 4, 300)
    whole = build_plan(xyz, (64, 16, 4), RADII, 16)
    again = build_plan(xyz.clone(), (64, 16, 4), RADII, 16)
    one = build_plan(xyz[2:3], (64, 16, 4), RADII, 16)
    for a, b, c in zip(whole.sa, again.sa, one.sa):
        assert torch.equal(a.groups, b.groups) and torch.equal(a.groups[2:3], c.groups)
    for a, b, c in zip(whole.fp, again.fp, one.fp):
        assert torch.equal(a.weight, b.weight) and torch.equal(a.weight[2:3], c.weight)


def test_float64_inputs_are_planned_in_float32():
    xyz = _scans(8, 2, 100)
    p32 = build_plan(xyz, (16, 8, 4), RADII, 8)
    p64 = build_plan(xyz.double(), (16, 8, 4), RADII, 8)
    assert all(torch.equal(a.groups, b.groups) for a, b in zip(p32.sa, p64.sa))
    assert np.array_equal(p32.fp[2].index.numpy(), p64.fp[2].index.numpy())
