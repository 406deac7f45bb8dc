"""Evaluation protocols.

- :mod:`kinmo.evaluate.pre_segmented`: motion prediction on pre-segmented shapes (Liu et al.
  2023, Table 1, GNN rows): the evaluation run (``kinmo eval pre-segmented``).
- :mod:`kinmo.evaluate.shape_metrics`: its metrics: type accuracy, mobile-part detection,
  axis errors, per shape and aggregated per category.
- :mod:`kinmo.evaluate.tables`: its tables: CSV, Markdown with the paper's means, terminal.
"""
