"""Evaluation metrics.

- :mod:`kinmo.metrics.axis`: joint-axis angle error and line distances (Table 1).
- :mod:`kinmo.metrics.pose`: per-part pose metrics of partial-scan models (Table 2).
"""

from kinmo.metrics.axis import axis_angle_deg, line_distance, point_line_distance

__all__ = ["axis_angle_deg", "line_distance", "point_line_distance"]
