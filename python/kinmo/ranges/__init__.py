"""Range of motion of predicted joints (issue 35): a learned prior of ranges per category and
part name (:mod:`kinmo.ranges.prior`), clipped by a swept-collision test of the moving part
against the rest of the object (:mod:`kinmo.ranges.predict`).

Scores against true ranges: :mod:`kinmo.metrics.motion_range`.
"""

from kinmo.ranges.predict import free_extents, predict_ranges
from kinmo.ranges.prior import RangeEntry, RangePrior, TrueRange, axial_extent, fit_range_prior, true_ranges

__all__ = ["RangeEntry", "RangePrior", "TrueRange", "axial_extent", "fit_range_prior", "free_extents",
           "predict_ranges", "true_ranges"]
