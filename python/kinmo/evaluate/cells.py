"""Figures as Markdown table cells: the evaluation tables' one rule for missing values.

A mean over nothing (no matched joint of a type, no kept shape) is NaN in the summaries, or
null once read back from JSON. A table shows it as an en dash, never as ``nan``, so that a
table captured in a log or pasted into a document stays readable.
"""

from __future__ import annotations

__all__ = ["cell"]


def cell(v: float | int | None, places: int = 2, suffix: str = "") -> str:
    """``v`` with ``places`` decimals and ``suffix`` (a unit such as ``"°"``), or ``"–"``.

    Parameters
    ----------
    v : float, int or None
        The figure (numpy scalars too); None or NaN (a mean over nothing) gives ``"–"``,
        without the suffix.
    places : int
        Decimals (``>= 0``).
    suffix : str
        Text appended to a number.

    Returns
    -------
    str

    Raises
    ------
    ValueError
        ``places`` below 0.
    """
    if places < 0:
        raise ValueError(f"places must be >= 0, got {places}")
    if v is None or v != v:  # NaN of any float type (numpy's too) is not equal to itself
        return "–"
    return f"{v:.{places}f}{suffix}"
