"""The Siamese DGCNN axis-selection network (kinmo.refine.axis_net)."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from kinmo.refine.axis_net import (
    AxisNetConfig,
    AxisSelectionNet,
    DGCNNEncoder,
    EdgeConv,
    knn,
)

torch.set_num_threads(1)

TINY = AxisNetConfig(n_points=64, k=8, widths=[8, 8, 16], emb_dim=16, head=[16], dropout=0.0)


def test_knn_matches_brute_force():
    torch.manual_seed(0)
    x = torch.randn(2, 30, 3)
    idx = knn(x, 5)
    assert idx.shape == (2, 30, 5)
    d = torch.cdist(x, x)
    ref = d.topk(5, dim=-1, largest=False).indices
    for b in range(2):
        for i in range(30):
            assert set(idx[b, i].tolist()) == set(ref[b, i].tolist())
            assert i in idx[b, i].tolist()  # a point is its own nearest neighbour


def test_edgeconv_equals_dgcnn_formula():
    """max_j LeakyReLU(W [x_j - x_i, x_i]) computed naively (norm off)."""
    torch.manual_seed(1)
    conv = EdgeConv(4, 6, k=5, norm="none")
    x = torch.randn(2, 12, 4)
    idx = knn(x[..., :3].contiguous(), 5)
    out = conv(x, idx)
    wa, wb = conv.proj.weight[:6], conv.proj.weight[6:]  # A and B of W = [A, A + B]
    ba, bb = conv.proj.bias[:6], conv.proj.bias[6:]
    w1, w2 = wa, wa + wb  # W [x_j - x_i, x_i] = W1 (x_j - x_i) + W2 x_i
    ref = torch.empty(2, 12, 6)
    for b in range(2):
        for i in range(12):
            xi = x[b, i]
            vals = [torch.nn.functional.leaky_relu(w1 @ (x[b, j] - xi) + w2 @ xi + ba + bb, 0.2)
                    for j in idx[b, i]]
            ref[b, i] = torch.stack(vals).max(dim=0).values
    torch.testing.assert_close(out, ref, atol=1e-5, rtol=1e-5)


@pytest.mark.parametrize("norm", ["batch", "group", "none"])
def test_shapes_gradients_and_broadcast(norm):
    torch.manual_seed(2)
    net = AxisSelectionNet(TINY.model_copy(update={"norm": norm}))
    before = torch.randn(5, 64, 4)
    after = torch.randn(5, 64, 4)
    logits = net(before, after)
    assert logits.shape == (5,)
    torch.nn.functional.binary_cross_entropy_with_logits(logits, torch.ones(5)).backward()
    for name, p in net.named_parameters():
        assert p.grad is not None and torch.isfinite(p.grad).all(), name
    assert any(float(p.grad.abs().sum()) > 0 for p in net.encoder.parameters())
    net.eval()
    with torch.no_grad():
        one = net(before[0], after)  # one rest state for all motions
        rep = net(before[0:1].expand(5, -1, -1), after)
    torch.testing.assert_close(one, rep)
    f = net.feasibility(before[0], after, chunk=2)
    assert f.shape == (5,) and torch.all((f >= 0) & (f <= 1))
    torch.testing.assert_close(f, torch.sigmoid(rep))


def test_encoder_is_invariant_to_point_order():
    torch.manual_seed(3)
    enc = DGCNNEncoder([8, 16], 16, k=6).eval()
    x = torch.randn(2, 50, 4)
    perm = torch.randperm(50)
    with torch.no_grad():
        torch.testing.assert_close(enc(x), enc(x[:, perm]), atol=1e-5, rtol=1e-5)


def test_static_graph_option_and_errors():
    torch.manual_seed(4)
    net = AxisSelectionNet(TINY.model_copy(update={"dynamic": False})).eval()
    with torch.no_grad():
        assert net(torch.randn(64, 4), torch.randn(3, 64, 4)).shape == (3,)
    with pytest.raises(ValueError, match="points must be"):
        net.encode(torch.randn(2, 64, 3))
    with pytest.raises(ValueError, match="batch"):
        net(torch.randn(2, 64, 4), torch.randn(3, 64, 4))
    with pytest.raises(ValueError):
        AxisNetConfig(norm="layer")


def test_overfits_a_few_positive_and_negative_motions():
    """On fixed (rest, positive, negative) triples of box cabinets the network separates the
    true motions from the wrong ones (the pipeline carries the information)."""
    from kinmo.refine.train import build_triples, moving_edges, preset_config

    from .refine_boxes import box_cabinet

    graphs = [box_cabinet(256, seed=s, jitter=0.2, shape_id=f"b{s}") for s in range(2)]
    edges = moving_edges(graphs)
    cfg = preset_config("quick", net=TINY.model_dump())
    rest, pos, neg = (torch.from_numpy(a) for a in
                      build_triples(graphs, edges, cfg, np.random.default_rng(0)))
    torch.manual_seed(0)
    net = AxisSelectionNet(TINY)
    opt = torch.optim.Adam(net.parameters(), lr=1e-2)
    b = rest.shape[0]
    target = torch.cat([torch.ones(b), torch.zeros(b)])
    for _ in range(60):
        f = net.encode(torch.cat([rest, pos, neg]))
        logits = net.head(torch.cat([f[:b], f[:b]]), f[b:])
        loss = torch.nn.functional.binary_cross_entropy_with_logits(logits, target)
        opt.zero_grad()
        loss.backward()
        opt.step()
    net.eval()
    with torch.no_grad():
        p = torch.cat([net.feasibility(rest[i], pos[i:i + 1]) for i in range(b)])
        n = torch.cat([net.feasibility(rest[i], neg[i:i + 1]) for i in range(b)])
    assert float(loss.detach()) < 0.2
    assert bool(torch.all(p > n)), (p, n)
