"""Formatting and chart helpers shared by the report's sections (:mod:`kinmo.report.build`).

How a metric is printed in a table (:func:`fmt_value`), the difference to a paper value and
its mark (:func:`paper_delta`), a PNG as a :class:`~kinmo.report.document.Figure`, and a chart
that never sinks the report (:func:`chart_block`).
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable

from kinmo.report.collect import png_size
from kinmo.report.document import Block, Figure, Note

__all__ = ["chart_block", "file_slug", "fmt_value", "paper_delta", "png_figure"]


def fmt_value(column: str, v: float) -> str:
    """Format a metric for a table: angles and rotations 2 decimals, distances, accuracies
    and other scores 3, counts as integers, NaN as an en dash."""
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return "–"
    c = column.lower()
    if re.search(r"(^|_)(n|count|shapes|joints|frames|epoch)s?($|_)", c) and float(v).is_integer():
        return str(int(v))
    if any(w in c for w in ("angle", "rot", "deg")):
        return f"{v:.2f}"
    if any(w in c for w in ("dist", "trans", "acc", "recall", "precision", "iou", "loss",
                            "coverage", "chance")):
        return f"{v:.3f}"
    return f"{v:.3f}" if v == 0 or 1e-3 <= abs(v) < 1e4 else f"{v:.4g}"


def file_slug(text: str) -> str:
    """``text`` as a lower-case file-name stem (``"run"`` when nothing is left)."""
    s = re.sub(r"[^A-Za-z0-9]+", "_", text).strip("_").lower()
    return s or "run"


def png_figure(name: str, png: bytes, alt: str, caption: str = "") -> Figure:
    """A :class:`~kinmo.report.document.Figure` of ``png`` with its pixel size."""
    w, h = png_size(png) or (0, 0)
    return Figure(name, png, alt, caption, w, h)


def paper_delta(value: float, ref: float | None, decimals: int = 2) -> tuple[str, str | None]:
    """``value - ref`` formatted, and its mark (lower is better)."""
    if ref is None or math.isnan(value):
        return "–", None
    d = value - ref
    return f"{d:+.{decimals}f}", ("better" if d <= 0 else "worse")


def chart_block(make: Callable[[], bytes], name: str, alt: str, caption: str,
                blocks: list[Block]) -> None:
    """Append the chart ``make()`` draws to ``blocks``, or a problem note when it fails."""
    try:
        png = make()
    except Exception as e:  # noqa: BLE001 - a chart must never sink the report
        blocks.append(Note(f"chart {name} could not be drawn: {type(e).__name__}: {e}", "problem"))
        return
    blocks.append(png_figure(name, png, alt, caption))
