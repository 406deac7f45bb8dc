"""Evaluation protocols.

- :mod:`kinmo.evaluate.pre_segmented`: motion prediction on pre-segmented shapes (Liu et al.
  2023, Table 1, GNN rows): type accuracy, mobile-part detection, axis errors.
"""
