"""Shapes, invariances and gradients of the motion GNN's layers."""

from __future__ import annotations

import pytest
import torch

from kinmo.features import EDGE_DIM, SemanticVocab, collate, graph_tensors
from kinmo.models import ModelConfig, MotionGNN
from kinmo.models.edge_gnn import N_CANDIDATES, OFFSET_FLOOR, EdgeGNN
from kinmo.models.hierarchy import HierarchyEncoder
from kinmo.models.losses import MotionLoss
from kinmo.models.point_encoder import DGCNN, PointNet, make_point_encoder
from kinmo.models.scatter import scatter_max, scatter_mean, scatter_sum
from motion_cabinet import cabinet_graph

torch.set_num_threads(1)


def _grads_ok(module: torch.nn.Module) -> list[str]:
    """Names of parameters whose gradient is missing, non-finite or all zero."""
    bad = []
    for name, p in module.named_parameters():
        if p.grad is None or not torch.isfinite(p.grad).all() or float(p.grad.abs().sum()) == 0.0:
            bad.append(name)
    return bad


def test_scatter_reductions_match_hand_computation():
    src = torch.tensor([[1.0, -2.0], [3.0, 5.0], [-1.0, 0.5], [4.0, 4.0]])
    idx = torch.tensor([0, 2, 0, 2])
    torch.testing.assert_close(scatter_sum(src, idx, 3), torch.tensor([[0.0, -1.5], [0, 0], [7.0, 9.0]]))
    torch.testing.assert_close(scatter_mean(src, idx, 3), torch.tensor([[0.0, -0.75], [0, 0], [3.5, 4.5]]))
    torch.testing.assert_close(scatter_max(src, idx, 3), torch.tensor([[1.0, 0.5], [0, 0], [4.0, 5.0]]))
    with pytest.raises(ValueError):
        scatter_sum(src, idx[:3], 3)


@pytest.mark.parametrize("enc", [PointNet([16, 32], 24), DGCNN([16, 16], 24, k=5, chunk=2)])
def test_point_encoders_shape_permutation_invariance_and_grads(enc):
    torch.manual_seed(0)
    pts = torch.randn(5, 40, 3)
    out = enc(pts)
    assert out.shape == (5, 24)
    perm = torch.randperm(40)
    torch.testing.assert_close(enc(pts[:, perm]), out, atol=1e-5, rtol=1e-5)
    out.pow(2).sum().backward()
    assert _grads_ok(enc) == []
    with pytest.raises(ValueError, match="points"):
        enc(torch.randn(5, 40))


def test_make_point_encoder_rejects_unknown():
    with pytest.raises(ValueError, match="unknown point encoder"):
        make_point_encoder("pointnet++", [8], 8)


def _cabinet_inputs():
    b = collate([graph_tensors(cabinet_graph(), SemanticVocab())])
    torch.manual_seed(0)
    x = torch.randn(b.n_nodes, 16)
    ef = torch.randn(b.n_edges, 8)
    return b, x, ef


def test_hierarchy_bottom_up_reaches_the_root_and_top_down_the_leaves():
    b, x, ef = _cabinet_inputs()
    torch.manual_seed(1)
    enc = HierarchyEncoder(16, 8, iterations=2, top_down=False)
    h = enc(x, b.parent, b.depth, b.edges, ef)
    assert h.shape == (6, 16)
    # changing the handle (leaf 5) changes the drawer (3) and the root (0), not the door (2)
    x2 = x.clone()
    x2[5] += 1.0
    h2 = enc(x2, b.parent, b.depth, b.edges, ef)
    changed = (h2 - h).abs().sum(1) > 1e-6
    assert changed.tolist() == [True, False, False, True, False, True]
    # with the top-down pass the root's context reaches every node
    enc_td = HierarchyEncoder(16, 8, iterations=2, top_down=True)
    t1 = enc_td(x, b.parent, b.depth, b.edges, ef)
    t2 = enc_td(x2, b.parent, b.depth, b.edges, ef)
    assert bool(((t2 - t1).abs().sum(1) > 1e-6).all())
    t1.pow(2).sum().backward()
    assert _grads_ok(enc_td) == []


def test_edge_gnn_outputs_and_obb_frame_parameterisation():
    b, x, _ = _cabinet_inputs()
    gnn = EdgeGNN(16, EDGE_DIM, 12, layers=2, n_types=5, axis_frame="obb", axis_mode="regress")
    out = gnn(x, b.edges, b.edge_feat, b.obb_center, b.obb_axes, b.obb_size)
    logits, d, o = out.logits, out.direction, out.origin
    assert logits.shape == (b.n_edges, 5) and d.shape == (b.n_edges, 3) and o.shape == (b.n_edges, 3)
    assert out.axis_logits is None and torch.equal(out.direction_free, d)
    torch.testing.assert_close(d.norm(dim=1), torch.ones(b.n_edges))
    i = b.edges[:, 0]
    (logits.sum() + d.sum() + o.sum()).backward()
    assert _grads_ok(gnn) == []
    # zero raw offsets put the point at the moving node's OBB centre
    with torch.no_grad():
        gnn.axis_head[-1].weight.zero_()
        gnn.axis_head[-1].bias.zero_()
    o0 = gnn(x, b.edges, b.edge_feat, b.obb_center, b.obb_axes, b.obb_size).origin
    torch.testing.assert_close(o0, b.obb_center[i])
    # a unit raw offset along the first OBB axis is (half extent + floor) along that axis
    with torch.no_grad():
        gnn.axis_head[-1].bias.copy_(torch.tensor([0, 0, 0, 1.0, 0, 0]))
    o1 = gnn(x, b.edges, b.edge_feat, b.obb_center, b.obb_axes, b.obb_size).origin
    expect = b.obb_center[i] + (b.obb_size[i, :1] / 2 + OFFSET_FLOOR) * b.obb_axes[i, 0]
    torch.testing.assert_close(o1, expect)
    with pytest.raises(ValueError):
        EdgeGNN(16, EDGE_DIM, 12, 1, 5, axis_frame="world")
    with pytest.raises(ValueError):
        EdgeGNN(16, EDGE_DIM, 12, 1, 5, axis_mode="vote")


def test_candidate_head_selects_one_of_the_candidates():
    b, x, _ = _cabinet_inputs()
    gnn = EdgeGNN(16, EDGE_DIM, 12, layers=1, n_types=10, axis_mode="candidates")
    out = gnn(x, b.edges, b.edge_feat, b.obb_center, b.obb_axes, b.obb_size)
    assert out.axis_logits.shape == (b.n_edges, N_CANDIDATES)
    cand = out.axis_candidates
    assert cand.shape == (b.n_edges, N_CANDIDATES, 3)
    i, j = b.edges[:, 0], b.edges[:, 1]
    torch.testing.assert_close(cand[:, :3], b.obb_axes[i])
    torch.testing.assert_close(cand[:, 3:6], b.obb_axes[j])
    torch.testing.assert_close(cand[:, 6:9], torch.eye(3).expand(b.n_edges, 3, 3))
    torch.testing.assert_close(cand[:, 9], out.direction_free)
    best = out.axis_logits.argmax(1)
    torch.testing.assert_close(out.direction, cand[torch.arange(b.n_edges), best])
    out.axis_logits.sum().backward()
    assert gnn.cand_head[0].weight.grad is not None


@pytest.mark.parametrize("mode", ["candidates", "regress"])
def test_edge_heads_in_chunks_at_inference_equal_the_whole_graph(monkeypatch, mode):
    """Issue 21 finding 4: without autograd the heads run on chunks of edges (bounded memory
    on a flat 500-part asset), with the same outputs."""
    import kinmo.models.edge_gnn as edge_gnn

    b, x, _ = _cabinet_inputs()
    gnn = EdgeGNN(16, EDGE_DIM, 12, layers=2, n_types=10, axis_mode=mode).eval()
    args = (x, b.edges, b.edge_feat, b.obb_center, b.obb_axes, b.obb_size)
    whole = gnn(*args)  # autograd on: one pass over every edge
    assert b.n_edges > 3
    monkeypatch.setattr(edge_gnn, "EDGE_CHUNK", 3)
    seen = []
    heads = gnn._heads
    monkeypatch.setattr(gnn, "_heads", lambda *a: seen.append(a[2].shape[0]) or heads(*a))
    with torch.no_grad():
        chunked = gnn(*args)
    assert max(seen) == 3 and sum(seen) == b.n_edges  # it did run in chunks
    for name in ("logits", "direction", "origin", "direction_free", "axis_logits", "axis_candidates"):
        w, c = getattr(whole, name), getattr(chunked, name)
        assert (w is None) == (c is None), name
        if w is not None:
            torch.testing.assert_close(c, w.detach(), rtol=1e-5, atol=1e-6)


@pytest.mark.parametrize(
    "types,encoder,frame,mode",
    [("fine", "pointnet", "obb", "candidates"), ("coarse", "dgcnn", "shape", "regress")],
)
def test_motion_gnn_every_parameter_gets_a_gradient(types, encoder, frame, mode):
    vocab = SemanticVocab.from_graphs([cabinet_graph()])
    b = collate([graph_tensors(cabinet_graph(seed=s, jitter=0.2), vocab) for s in range(3)], n_points=32)
    cfg = ModelConfig(types=types, point_encoder=encoder, point_widths=[16], geo_dim=16, node_dim=16,
                      edge_dim=16, semantic_dim=4, vocab_size=len(vocab), gnn_layers=2,
                      axis_frame=frame, axis_mode=mode, dgcnn_k=4)
    torch.manual_seed(0)
    model = MotionGNN(cfg)
    out = model(b)
    k = 10 if types == "fine" else 5
    assert out.logits.shape == (b.n_edges, k)
    assert out.direction.shape == out.origin.shape == (b.n_edges, 3)
    terms = MotionLoss(types)(out, b)
    assert all(torch.isfinite(t) for t in (terms.total, terms.type, terms.direction, terms.position))
    terms.total.backward()
    assert _grads_ok(model) == []
