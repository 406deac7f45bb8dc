"""Loss of the motion GNN (paper Eq. 1-4) on hand-made cases."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from kinmo.data.model import FINE_INDEX
from kinmo.features import SemanticVocab, collate, graph_tensors
from kinmo.models.losses import MotionLoss, class_weights, direction_loss, position_loss
from kinmo.models.motion_gnn import MotionGNNOutput
from motion_cabinet import cabinet_graph


def test_direction_loss_hand_cases():
    true = torch.tensor([[0.0, 1.0, 0.0]] * 4)
    pred = torch.tensor([[0.0, 2.0, 0.0], [0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0]])
    out = direction_loss(pred, true)
    torch.testing.assert_close(out, torch.tensor([0.0, 0.0, 1.0, 1 - math.cos(math.pi / 4)]))


def test_position_loss_hand_cases():
    origin = torch.tensor([[0.0, 0.0, 0.0]] * 3)
    d = torch.tensor([[0.0, 1.0, 0.0]] * 3)
    p = torch.tensor([[0.0, 5.0, 0.0], [3.0, -2.0, 4.0], [0.0, 0.0, -0.5]])
    torch.testing.assert_close(position_loss(p, origin, d), torch.tensor([0.0, 5.0, 0.5]))


def test_class_weights_inverse_sqrt():
    w = class_weights(np.array([100, 25, 0, 4]))
    # proportional to 1/sqrt(n) for present classes
    assert w[0] / w[1] == pytest.approx(0.5)
    assert w[1] / w[3] == pytest.approx(2 / 5)
    # the average weight over the training edges is 1
    n = np.array([100, 25, 0, 4])
    assert float((w.numpy() * n).sum() / n.sum()) == pytest.approx(1.0, rel=1e-6)
    # an absent class gets the largest present weight
    assert w[2] == pytest.approx(float(w.max()))
    with pytest.raises(ValueError):
        class_weights(np.zeros(3))


def _perfect_output(batch, types="fine", wrong_dir=False):
    k = 10 if types == "fine" else 5
    target = batch.edge_labels(types)
    logits = torch.full((batch.n_edges, k), -20.0)
    logits[torch.arange(batch.n_edges), target] = 20.0
    d = batch.axis_direction.clone()
    d[~batch.has_axis] = torch.tensor([0.0, 1.0, 0.0])
    if wrong_dir:
        # perpendicular to every true axis: cross with a helper vector
        helper = torch.tensor([0.3, 0.5, 0.8])
        d = torch.linalg.cross(d, helper.expand_as(d), dim=1)
        d = torch.nn.functional.normalize(d, dim=1)
    # a point on the true axis, shifted along it (still on the line)
    o = batch.axis_origin + 0.37 * batch.axis_direction
    return MotionGNNOutput(logits.requires_grad_(), d, o)


@pytest.mark.parametrize("types", ["fine", "coarse"])
def test_perfect_prediction_has_zero_axis_losses(types):
    b = collate([graph_tensors(cabinet_graph(seed=s, jitter=0.2), SemanticVocab()) for s in range(2)])
    terms = MotionLoss(types)(_perfect_output(b, types), b)
    assert float(terms.direction.detach()) == pytest.approx(0.0, abs=1e-6)
    assert float(terms.position.detach()) == pytest.approx(0.0, abs=1e-6)
    assert float(terms.type.detach()) < 1e-6
    assert float(terms.total.detach()) < 1e-5


def test_perpendicular_direction_costs_one():
    b = collate([graph_tensors(cabinet_graph(), SemanticVocab())])
    terms = MotionLoss("fine")(_perfect_output(b, wrong_dir=True), b)
    assert float(terms.direction.detach()) == pytest.approx(1.0, abs=1e-6)


def test_position_term_only_on_rotating_edges():
    """Moving the predicted point of the prismatic drawer edge changes nothing; of the door, it does."""
    g = cabinet_graph()
    b = collate([graph_tensors(g, SemanticVocab())])
    out = _perfect_output(b)
    fine = b.edge_fine
    drawer = int(torch.nonzero(fine == FINE_INDEX["P_H"])[0])
    door = int(torch.nonzero(fine == FINE_INDEX["R_V_S"])[0])
    loss = MotionLoss("fine")
    out.origin[drawer] += torch.tensor([0.0, 5.0, 0.0])
    assert float(loss(out, b).position) == pytest.approx(0.0, abs=1e-6)
    out.origin[door] += torch.tensor([0.3, 0.0, 0.4])  # 0.5 off a vertical axis
    assert float(loss(out, b).position) == pytest.approx(0.5, abs=1e-5)


def test_class_weights_and_focal_change_type_loss():
    b = collate([graph_tensors(cabinet_graph(), SemanticVocab())])
    torch.manual_seed(0)
    out = MotionGNNOutput(torch.randn(b.n_edges, 10), torch.randn(b.n_edges, 3), torch.randn(b.n_edges, 3))
    plain = float(MotionLoss("fine")(out, b).type)
    focal = float(MotionLoss("fine", focal_gamma=2.0)(out, b).type)
    w = torch.ones(10)
    w[FINE_INDEX["None"]] = 0.0
    weighted = float(MotionLoss("fine", weights=w)(out, b).type)
    assert focal < plain
    target = b.edge_labels("fine")
    logp = torch.log_softmax(out.logits, 1)[torch.arange(b.n_edges), target]
    keep = target != FINE_INDEX["None"]
    assert weighted == pytest.approx(float(-logp[keep].mean()), rel=1e-5)


def test_candidate_choice_loss():
    """Choosing a correct candidate costs ~0; a wrong one costs its cross-entropy."""
    from kinmo.models.edge_gnn import axis_candidates
    from kinmo.models.losses import candidate_targets

    b = collate([graph_tensors(cabinet_graph(), SemanticVocab())])
    i, j = b.edges[:, 0], b.edges[:, 1]
    free = torch.nn.functional.normalize(torch.tensor([[0.3, 0.2, 0.9]]).expand(b.n_edges, 3), dim=1)
    cand = axis_candidates(b.obb_axes[i], b.obb_axes[j], free)
    true = b.axis_direction.clone()
    ok = candidate_targets(cand, true)
    door = int(torch.nonzero(b.edge_fine == FINE_INDEX["R_V_S"])[0])
    # the vertical hinge: the y axes of both boxes and the world y are correct, nothing else
    assert ok[door].tolist() == [False, True, False, False, True, False, False, True, False, False]
    # an axis 30 degrees off every fixed candidate: only the free one is correct
    odd = torch.nn.functional.normalize(torch.tensor([[0.5, 0.866, 0.0]]), dim=1)
    assert candidate_targets(cand[:1], odd)[0].tolist() == [False] * 9 + [True]

    def output(pick):
        logits = torch.full((b.n_edges, 10), -30.0)
        logits[:, pick] = 30.0
        type_logits = torch.full((b.n_edges, 10), -20.0)
        type_logits[torch.arange(b.n_edges), b.edge_fine] = 20.0
        d = cand[torch.arange(b.n_edges), torch.full((b.n_edges,), pick)]
        return MotionGNNOutput(type_logits, d, b.axis_origin.clone(), true.clone(), logits, cand)

    loss = MotionLoss("fine")
    right = loss(output(7), b)  # world y: right for the door, wrong for the drawer (z)
    all_right = MotionLoss("fine")(output(8), b)  # world z: right for the drawer only
    # one edge right (cross-entropy ~0), the other wrong: logsumexp(all) - logsumexp(its 3
    # correct candidates) = 30 - (-30 + ln 3); the free directions are exact (no 1-|cos| term)
    expect = (60.0 - math.log(3.0)) / 2
    assert float(right.direction) == pytest.approx(expect, rel=1e-4)
    assert float(all_right.direction) == pytest.approx(expect, rel=1e-4)
    both = output(7)
    drawer = int(torch.nonzero(b.edge_fine == FINE_INDEX["P_H"])[0])
    both.axis_logits[drawer] = torch.full((10,), -30.0)
    both.axis_logits[drawer, 8] = 30.0
    assert float(loss(both, b).direction) == pytest.approx(0.0, abs=1e-5)
