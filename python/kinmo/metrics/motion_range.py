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
from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np

from kinmo.data.model import Joint, JointType
from kinmo.metrics.axis import axis_angle_deg
from kinmo.urdf import hinge_limits_rad

__all__ = ["MAX_AXIS_ANGLE_DEG", "RANGE_KEYS", "RangeScore", "continuity_correct", "hinge_interval",
           "joint_kind", "onto_true_direction", "range_iou", "score_range", "summarise_ranges",
           "worst_endpoint_error"]

#: The summary keys of :func:`summarise_ranges`, in table order.
RANGE_KEYS = ("range_iou_hinge", "range_ok_hinge", "range_end_hinge", "range_iou_slider",
              "range_ok_slider", "range_end_slider", "range_cont_acc")
#: A continuous prediction of a limited hinge is scored as this interval (degrees).
FULL_TURN = (-180.0, 180.0)

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


@dataclass(frozen=True)
class RangeScore:
    """The range scores of one matched joint (module docstring).

    Attributes
    ----------
    kind : {"hinge", "slider"}
    iou, end : float or None
        Range IoU and worst end-point error; None for a true continuous hinge (or a slider
        without limits on either side).
    continuous_ok : bool or None
        Hinges: continuous or not, as the truth; None for sliders.
    """

    kind: str
    iou: float | None
    end: float | None
    continuous_ok: bool | None


def joint_kind(j: Joint) -> str:
    """``"R"`` (hinge), ``"P"`` (slider) or ``"PR"`` (cylindrical: a slider that rotates)."""
    return "R" if j.type is JointType.HINGE else ("PR" if j.rotates else "P")


def score_range(pred: Joint, true: Joint) -> RangeScore | None:
    """Score a predicted joint's range against its matched true joint.

    Only joints of the same kind (revolute, prismatic, cylindrical) whose axes are within
    :data:`MAX_AXIS_ANGLE_DEG` are scored (None otherwise). A continuous prediction of a
    limited hinge counts as :data:`FULL_TURN`; cylindrical joints are scored on their
    translation range.
    """
    if joint_kind(pred) != joint_kind(true) or pred.direction is None or true.direction is None:
        return None
    if float(axis_angle_deg(pred.direction, true.direction)) > MAX_AXIS_ANGLE_DEG:
        return None
    if true.type is JointType.HINGE:
        t = None if true.limit is None else hinge_interval(*true.limit)
        p = None if pred.limit is None else hinge_interval(*onto_true_direction(
            pred.limit, pred.direction, true.direction))
        ok = continuity_correct(p is None, t is None)
        if t is None:
            return RangeScore("hinge", None, None, ok)
        p = p or FULL_TURN
        return RangeScore("hinge", range_iou(p, t), worst_endpoint_error(p, t), ok)
    if true.limit is None or pred.limit is None:
        return RangeScore("slider", None, None, None)
    p = onto_true_direction(pred.limit, pred.direction, true.direction)
    return RangeScore("slider", range_iou(p, true.limit), worst_endpoint_error(p, true.limit, relative=True),
                      None)


def summarise_ranges(scores: Iterable[RangeScore | None]) -> dict[str, float]:
    """Pool range scores into :data:`RANGE_KEYS`: mean IoU, share with IoU >= 0.5 and median
    worst end-point error per kind, and the continuity accuracy of hinges (NaN where there is
    nothing to pool)."""
    scores = [s for s in scores if s is not None]
    out: dict[str, float] = {}
    for kind in ("hinge", "slider"):
        ious = [s.iou for s in scores if s.kind == kind and s.iou is not None]
        ends = [s.end for s in scores if s.kind == kind and s.end is not None and not math.isnan(s.end)]
        out[f"range_iou_{kind}"] = float(np.mean(ious)) if ious else float("nan")
        out[f"range_ok_{kind}"] = float(np.mean(np.asarray(ious) >= 0.5)) if ious else float("nan")
        out[f"range_end_{kind}"] = float(np.median(ends)) if ends else float("nan")
    cont = [s.continuous_ok for s in scores if s.continuous_ok is not None]
    out["range_cont_acc"] = float(np.mean(cont)) if cont else float("nan")
    return out
