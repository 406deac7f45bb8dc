"""Range-of-motion metrics: how well a predicted joint range matches the true one (issue 35).

For a matched joint of the right kind whose axis is within :data:`MAX_AXIS_ANGLE_DEG` of the
truth (the evaluation decides which joints qualify; these functions score one pair):

- **Direction.** The predicted range is brought onto the true axis direction: when the two
  directions point opposite ways (``d_p . d_t < 0``) the range is negated and its ends
  swapped (``[lo, hi] -> [-hi, -lo]``): a positive joint value then moves the part the same
  way under both.
- **Hinge.** A range is ``[min(a, b), max(a, b)]`` degrees shifted by whole turns towards 0
  (:func:`kinmo.urdf.hinge_limits_rad`'s rule); PartNet-Mobility's ``limit`` is the interval
  between ``a`` and ``b`` in either order.
- **Range IoU** = overlap / union of the two intervals (0 when the union is empty).
- **Worst end-point error** = ``max(|lo_p - lo_t|, |hi_p - hi_t|)``: degrees for hinges; for
  sliders a fraction of the true travel ``hi_t - lo_t``.
- Continuous (``noLimit``) joints have no interval: they are scored only by whether the
  prediction is continuous too (:func:`continuity_correct`).

Units: degrees for hinges, mesh units for sliders (both inputs in the same units).
"""

from __future__ import annotations

import math

import numpy as np

from kinmo.urdf import hinge_limits_rad

__all__ = ["MAX_AXIS_ANGLE_DEG", "continuity_correct", "hinge_interval", "onto_true_direction",
           "range_iou", "worst_endpoint_error"]

#: Joints whose predicted axis is farther than this from the truth (degrees) are not scored.
MAX_AXIS_ANGLE_DEG = 20.0


def hinge_interval(a_deg: float, b_deg: float) -> tuple[float, float] | None:
    """A hinge's interval in degrees: ``[min, max]`` shifted by whole turns towards 0.

    Returns None (continuous) when it spans a full turn or more (the rule of
    :func:`kinmo.urdf.hinge_limits_rad`, in degrees).
    """
    r = hinge_limits_rad(a_deg, b_deg)
    return None if r is None else (math.degrees(r[0]), math.degrees(r[1]))


def onto_true_direction(limit: tuple[float, float], pred_direction: np.ndarray,
                        true_direction: np.ndarray) -> tuple[float, float]:
    """The predicted ``(lo, hi)`` expressed about the true axis direction.

    Parameters
    ----------
    limit : (float, float)
        Predicted range about ``pred_direction``.
    pred_direction, true_direction : (3,) float64
        Axis directions (any length > 0).

    Returns
    -------
    (float, float)
        ``(lo, hi)`` sorted; negated and swapped when the directions point opposite ways.
    """
    lo, hi = sorted((float(limit[0]), float(limit[1])))
    if float(np.dot(np.asarray(pred_direction, float), np.asarray(true_direction, float))) < 0:
        lo, hi = -hi, -lo
    return lo, hi


def range_iou(pred: tuple[float, float], true: tuple[float, float]) -> float:
    """Overlap / union of two intervals ``(lo, hi)`` (each sorted here); 0 for an empty union."""
    p0, p1 = sorted(pred)
    t0, t1 = sorted(true)
    union = max(p1, t1) - min(p0, t0)
    if not union > 0:
        return 0.0
    return max(0.0, min(p1, t1) - max(p0, t0)) / union


def worst_endpoint_error(pred: tuple[float, float], true: tuple[float, float],
                         relative: bool = False) -> float:
    """``max(|lo_p - lo_t|, |hi_p - hi_t|)``; with ``relative`` divided by the true travel
    ``hi_t - lo_t`` (sliders; NaN for a zero travel)."""
    p0, p1 = sorted(pred)
    t0, t1 = sorted(true)
    e = max(abs(p0 - t0), abs(p1 - t1))
    if relative:
        travel = t1 - t0
        return e / travel if travel > 0 else float("nan")
    return e


def continuity_correct(pred_continuous: bool, true_continuous: bool) -> bool:
    """True when both joints turn freely or neither does."""
    return bool(pred_continuous) == bool(true_continuous)
