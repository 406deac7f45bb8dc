"""Inference: a model bundle loaded once into a :class:`~kinmo.inference.predictor.Predictor`
shared by ``predict``, ``eval``, ``pseudo-label`` and the pipeline (issue 22).

- :mod:`kinmo.inference.bundle`: the model bundle folder (``bundle.json``), read, written and
  resolved from what ``--model`` / ``--axis-model`` / ``--ranker`` name.
- :mod:`kinmo.inference.gnn`: motion-GNN inference on part graphs (edge types, axes, priors).
- :mod:`kinmo.inference.predictor`: :class:`Predictor`, the GNN plus the selector's refinement.

The submodules import torch; import them directly (this package imports nothing).
"""
