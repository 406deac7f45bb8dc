"""Quarter turns for unnamed objects (kinmo.inference.gnn, issue 36): an object without a known
part name is predicted as the average over the four quarter turns about the vertical, so its
answer no longer depends on which quarter it faces; a named object gets one pass."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from conftest import write_untrained_models

from kinmo.features import SemanticVocab, graph_tensors, quarter_turn
from kinmo.inference.gnn import average_turns, forward, infer_edges_with_priors
from kinmo.train.gnn import load_run


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    gnn, _ = write_untrained_models(tmp_path_factory.mktemp("runs"), "gnn_fine")
    r = load_run(gnn, device="cpu")
    r.model.eval()
    with torch.no_grad():  # an untrained head is near uniform: give its weights more spread
        gen = torch.Generator().manual_seed(1)
        for name, p in r.model.named_parameters():
            if "head" in name and p.dim() > 1:
                p.add_(0.5 * torch.randn(p.shape, generator=gen))
    return r


def _tensors(graph, vocab):
    t = graph_tensors(graph, vocab)
    t.edge_fine = t.axis_origin = t.axis_direction = t.has_axis = None
    return t


def test_the_averaged_answer_does_not_depend_on_the_quarter_the_object_faces(run, graph):
    t = _tensors(graph, SemanticVocab())
    t1 = t.turned(1)
    assert torch.equal(t1.turned(3).obb_axes, t.obb_axes)  # the four turns are the same set

    def averaged(x):
        (pred,), (prior,) = forward(run, [x])
        return average_turns(x, pred, prior, *forward(run, [x.turned(q) for q in (1, 2, 3)]))

    a_pred, a_prior = averaged(t)
    b_pred, b_prior = averaged(t1)
    single = forward(run, [t1])[0][0]
    # one pass is not invariant (else the test would prove nothing) ...
    assert not np.allclose(single.probs, forward(run, [t])[0][0].probs, atol=1e-3)
    # ... the average is: types equal, axes turned with the object
    np.testing.assert_allclose(b_pred.probs, a_pred.probs, atol=1e-5)
    np.testing.assert_allclose(b_pred.probs.sum(axis=1), 1.0, atol=1e-9)
    r = quarter_turn(1)
    np.testing.assert_allclose(np.abs(np.sum(b_pred.direction * (a_pred.direction @ r.T), axis=1)), 1.0,
                               atol=1e-4)
    centre = np.asarray(t.center)
    np.testing.assert_allclose(b_pred.origin - centre, (a_pred.origin - centre) @ r.T, atol=1e-4 * t.scale)
    np.testing.assert_allclose(np.linalg.norm(b_pred.direction, axis=1), 1.0, atol=1e-9)
    assert b_prior.turned and not forward(run, [t])[1][0].turned  # the selector is told
    # the axis-candidate prior is a distribution over turn 0's candidates
    np.testing.assert_allclose(b_prior.axis_prob.sum(axis=1), 1.0, atol=1e-9)
    assert b_prior.axis_dirs is not None and b_prior.axis_prob.shape == b_prior.axis_dirs.shape[:2]


def test_only_unnamed_objects_are_turned(run, graph):
    unnamed = run.vocab.names == [] or not any(run.vocab.index(n) for n in graph.node_names)
    assert unnamed  # the untrained run knows no names
    never, _ = infer_edges_with_priors(run, [graph], turns="never")
    always, _ = infer_edges_with_priors(run, [graph], turns="always")
    default, _ = infer_edges_with_priors(run, [graph])
    assert not np.allclose(never[0].probs, always[0].probs, atol=1e-4)
    np.testing.assert_allclose(default[0].probs, always[0].probs)
    # a model that knows the cabinet's part names gives it one pass
    named = run.vocab
    try:
        run.vocab = SemanticVocab(graph.node_names)
        assert any(run.vocab.index(n) for n in graph.node_names)
        one, _ = infer_edges_with_priors(run, [graph], turns="never")
        dflt, _ = infer_edges_with_priors(run, [graph])
        np.testing.assert_array_equal(dflt[0].probs, one[0].probs)
    finally:
        run.vocab = named
    with pytest.raises(ValueError, match="turns"):
        infer_edges_with_priors(run, [graph], turns="sometimes")
