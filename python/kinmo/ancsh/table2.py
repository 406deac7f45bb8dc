"""Table 2 of Liu et al. CVPR 2023 from per-frame errors: rows, CSV, Markdown and rich tables.

:func:`summarize` turns the :class:`~kinmo.ancsh.frame_metrics.FrameErrors` of one run into a
:class:`Table2Row` (means over frames, NaNs ignored); :func:`table2_markdown`,
:func:`table2_csv`, :func:`rich_table` and :func:`paper_table` write the rows
(:mod:`kinmo.ancsh.evaluate` for the metrics and the files of an evaluation). Rows may carry
permutation-matched errors of interchangeable parts (:mod:`kinmo.ancsh.interchangeable`):
``table2.csv`` has their columns next to the raw ones, :func:`table2_markdown` and
:func:`matched_rich_table` a table of raw and matched errors side by side.
"""

from __future__ import annotations

import csv
import io
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from kinmo.ancsh.frame_metrics import FrameErrors
from kinmo.ancsh.interchangeable import describe_groups, interchangeable_groups
from kinmo.ancsh.structure import KinematicStructure
from kinmo.paper import PAPER_TABLE2

__all__ = ["MATCHED_METRICS", "METRICS", "SETTING_ORDER", "Table2Row", "matched_rich_table", "num", "paper_table",
           "rich_table", "structures_markdown", "summarize", "table2_csv", "table2_markdown"]

#: Row order of the settings.
SETTING_ORDER = {"supervised": 0, "semi": 1, "semi-weakly": 2}


@dataclass
class Table2Row:
    """One row of Table 2: mean errors of one run over the test frames.

    Attributes
    ----------
    setting, run : str
        The run's setting and folder.
    frames : int
    rotation_deg, translation, iou : (K,) float64
    state, angle_deg, distance : (J,) float64
    joint_types : tuple of str
    training : dict
        Scans the run trained on (``labeled``, ``pseudo_labeled``, ``pseudo_targets``) and the
        object counts.
    matched : dict of str to ndarray
        Permutation-matched errors (:mod:`kinmo.ancsh.interchangeable`): for each name of
        :data:`MATCHED_METRICS`, (K,) or (J,) float64 means over frames, same units as the raw
        array. Empty when not computed.
    swapped : int
        Frames whose matching assigned some predicted part to another true part.
    """

    setting: str
    run: str
    frames: int
    rotation_deg: np.ndarray
    translation: np.ndarray
    iou: np.ndarray
    state: np.ndarray
    angle_deg: np.ndarray
    distance: np.ndarray
    joint_types: tuple[str, ...]
    training: dict[str, Any] = field(default_factory=dict)
    matched: dict[str, np.ndarray] = field(default_factory=dict)
    swapped: int = 0

    def mean(self, name: str) -> float:
        """Mean over parts / joints of a metric (NaN entries ignored; NaN when none)."""
        return _nanmean(getattr(self, name))

    def matched_mean(self, name: str) -> float:
        """Mean over parts / joints of a permutation-matched metric (NaN when not computed)."""
        return _nanmean(self.matched.get(name, ()))


def _nanmean(values: Any) -> float:
    v = np.asarray(values, dtype=np.float64).ravel()
    v = v[np.isfinite(v)]
    return float(v.mean()) if len(v) else float("nan")


#: The per-part / per-joint error arrays of a row, in column order.
METRICS = ("rotation_deg", "translation", "iou", "state", "angle_deg", "distance")
#: The metrics also reported permutation-matched (:mod:`kinmo.ancsh.interchangeable`): part
#: rotation and translation, joint axis angle and distance.
MATCHED_METRICS = ("rotation_deg", "translation", "angle_deg", "distance")


def summarize(setting: str, run: str, errors: Sequence[FrameErrors], joint_types: Sequence[str],
              training: Mapping[str, Any] | None = None, matched: Sequence[FrameErrors] | None = None,
              swapped: int = 0) -> Table2Row:
    """Mean of per-frame errors (NaNs ignored per entry).

    ``matched``: the permutation-matched errors of the same frames
    (:func:`kinmo.ancsh.interchangeable.matched_frame_errors`), averaged alike into
    :attr:`Table2Row.matched`; ``swapped``: how many of them swapped parts.
    """
    def m(errs: Sequence[FrameErrors], name: str) -> np.ndarray:
        a = np.stack([getattr(e, name) for e in errs]) if errs else np.zeros((0, 0))
        with np.errstate(invalid="ignore"):
            return np.array([np.nanmean(c) if np.isfinite(c).any() else np.nan for c in a.T])
    if matched is not None and len(matched) != len(errors):
        raise ValueError(f"{len(matched)} matched errors for {len(errors)} frames")
    return Table2Row(setting, run, len(errors), *(m(errors, n) for n in METRICS), tuple(joint_types),
                     dict(training or {}), {n: m(matched, n) for n in MATCHED_METRICS} if matched is not None else {},
                     int(swapped))


def _fmt(x: float, digits: int = 3) -> str:
    return "—" if not np.isfinite(x) else f"{x:.{digits}f}"


def _cell(row: Table2Row, name: str, digits: int, matched: bool = False) -> str:
    v = np.asarray(row.matched.get(name, np.full(0, np.nan)) if matched else getattr(row, name), dtype=np.float64)
    if len(v) == 0:
        return "—"
    finite = v[np.isfinite(v)]
    if len(v) == 1:
        return _fmt(float(v[0]), digits)
    if name in ("state",) and len(set(row.joint_types)) > 1:  # no mean across units
        return " / ".join(_fmt(float(x), digits) for x in v)
    mean = float(finite.mean()) if len(finite) else float("nan")
    return f"{_fmt(mean, digits)} ({' / '.join(_fmt(float(x), digits) for x in v)})"


_HEADERS = (
    ("rotation_deg", "rotation error (°)", 2), ("translation", "translation error", 4),
    ("iou", "3D IoU", 3), ("state", "joint state error", 3), ("angle_deg", "axis angle error (°)", 2),
    ("distance", "axis distance", 4),
)
_SHORT = {"rotation_deg": "rot. (°)", "translation": "transl.", "iou": "IoU", "state": "state",
          "angle_deg": "axis (°)", "distance": "axis dist."}


def table2_markdown(rows: Sequence[Table2Row], category: str, structure: KinematicStructure,
                    notes: Sequence[str] = ()) -> str:
    """Table 2 of the paper for one category as Markdown (module docstring for the metrics)."""
    state_unit = "°" if set(structure.joint_types) == {"revolute"} else (
        "mesh units" if set(structure.joint_types) == {"prismatic"} else "° or mesh units")
    lines = [
        f"# Table 2 — {category} (structure {structure.signature()})", "",
        "ANCSH on single-view partial scans of the held-out test objects; means over frames. "
        "Cells with several parts (joints): mean (part 0 / part 1 / …); part 0 is the base. "
        f"Joint state error in {state_unit}; translation and axis distance in mesh units.", "",
        "| setting | frames | training scans (labelled / pseudo-labelled / pseudo-targets) | "
        + " | ".join(h for _, h, _ in _HEADERS) + " |",
        "|---|---:|---|" + "---:|" * len(_HEADERS),
    ]
    for r in rows:
        t = r.training
        tr = f"{t.get('labeled_scans', 0)} / {t.get('pseudo_labeled_scans', 0)} / {t.get('pseudo_target_scans', 0)}"
        lines.append(f"| {r.setting} | {r.frames} | {tr} | "
                     + " | ".join(_cell(r, n, d) for n, _, d in _HEADERS) + " |")
    groups = interchangeable_groups(structure)
    if groups and any(r.matched for r in rows):
        lines += _matched_markdown(rows, f"Permutation-matched errors (interchangeable "
                                   f"{describe_groups(groups, structure)}): per scan, predicted parts of a "
                                   "group are assigned to its true parts by the permutation of least summed "
                                   "rotation error (joints follow their parts); raw: part k against true part "
                                   "k, as in the table above.")
    if notes:
        lines += [""] + [f"- {n}" for n in notes]
    return "\n".join(lines) + "\n"


def _matched_markdown(rows: Sequence[Table2Row], lead: str) -> list[str]:
    """Markdown lines: ``lead``, then raw and permutation-matched cells of
    :data:`MATCHED_METRICS` side by side, one line per row."""
    lines = ["", lead, "", "| setting | frames | swapped scans | "
             + " | ".join(f"{h} raw | {h} matched" for n, h, _ in _HEADERS if n in MATCHED_METRICS) + " |",
             "|---|---:|---:|" + "---:|" * (2 * len(MATCHED_METRICS))]
    for r in rows:
        lines.append(f"| {r.setting} | {r.frames} | {r.swapped} | " + " | ".join(
            f"{_cell(r, n, d)} | {_cell(r, n, d, matched=True)}" for n, _, d in _HEADERS if n in MATCHED_METRICS)
            + " |")
    return lines


def structures_markdown(
    rows: Sequence[Table2Row], category: str,
    structures: Sequence[tuple[KinematicStructure, Sequence[Table2Row], Sequence[str], int]],
    missing: Sequence[str] = (),
) -> str:
    """``table2.md`` of a category with several kinematic structures: the category rows, then
    one :func:`table2_markdown` table per structure.

    Parameters
    ----------
    rows : sequence of Table2Row
        The category rows (one mean per metric).
    category : str
    structures : sequence of (structure, rows, notes, number of test objects)
    missing : sequence of str
        Why structures were not evaluated.
    """
    md = [f"# Table 2 — {category} ({len(structures)} kinematic structures)", "",
          "One ANCSH model per structure; each test object is evaluated with the model of its "
          "structure. Category row: mean over all test scans of the per-scan mean over parts "
          "(joints).", "",
          "| setting | frames | rotation error (°) | translation error | 3D IoU | joint state error | "
          "axis angle error (°) | axis distance |", "|---|---:|" + "---:|" * 6]
    for r in rows:
        md.append(f"| {r.setting} | {r.frames} | " + " | ".join(_cell(r, n, d) for n, _, d in _HEADERS) + " |")
    if any(interchangeable_groups(st) for st, _, _, _ in structures) and any(r.matched for r in rows):
        md += _matched_markdown(rows, "Permutation-matched errors of the interchangeable parts (per-structure "
                                "tables below); category row: mean over all test scans of the per-scan mean "
                                "over parts (joints).")
    md += ["", f"- structures: {'; '.join(f'{st.signature()} ({n} test objects)' for st, _, _, n in structures)}"]
    md += [f"- not evaluated: {m}" for m in missing]
    for st, st_rows, notes, _ in structures:
        md += ["", table2_markdown(st_rows, category, st, notes).replace("# Table 2", "## Table 2", 1)]
    return "\n".join(md) + "\n"


def table2_csv(rows: Sequence[Table2Row], k: int, jn: int) -> str:
    """``table2.csv`` text: one row per run, the mean and per-part (``k``) / per-joint (``jn``)
    columns of each metric, each of :data:`MATCHED_METRICS` followed by its permutation-matched
    columns (``<metric>_matched_mean``, ``<metric>_matched_part<i>`` / ``_joint<i>``; empty
    cells when not computed), and ``swapped_scans`` last."""
    cols = ["setting", "run", "frames", "labeled_scans", "pseudo_labeled_scans", "pseudo_target_scans"]
    for n in METRICS:
        per, width = ("part", k) if n in ("rotation_deg", "translation", "iou") else ("joint", jn)
        cols += [f"{n}_mean"] + [f"{n}_{per}{i}" for i in range(width)]
        if n in MATCHED_METRICS:
            cols += [f"{n}_matched_mean"] + [f"{n}_matched_{per}{i}" for i in range(width)]
    cols.append("swapped_scans")
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(cols)
    for r in rows:
        t = r.training
        vals: list[Any] = [r.setting, r.run, r.frames, t.get("labeled_scans", 0),
                           t.get("pseudo_labeled_scans", 0), t.get("pseudo_target_scans", 0)]
        for n in METRICS:
            vals.append(num(r.mean(n)))
            vals += [num(float(x)) for x in getattr(r, n)]
            if n in MATCHED_METRICS:
                m = r.matched.get(n)
                width = len(getattr(r, n))
                vals.append(num(r.matched_mean(n)))
                vals += [num(float(x)) for x in m] if m is not None else [""] * width
        vals.append(r.swapped)
        w.writerow(vals)
    return buf.getvalue()


def num(x: float) -> str:
    """A CSV cell: 6 significant digits, empty when not finite."""
    return "" if not np.isfinite(x) else f"{x:.6g}"


def rich_table(rows: Sequence[Table2Row], category: str, structure: KinematicStructure | None) -> Any:
    """The rows as a :class:`rich.table.Table` (``structure`` None: a category row over
    several structures)."""
    from rich.table import Table

    what = structure.signature() if structure is not None else "all structures"
    t = Table(title=f"Table 2 — {category} ({what}), means over test scans",
              caption="train scans: labelled + pseudo-labelled + pseudo-targets; cells: mean (per part / joint)")
    t.add_column("setting", no_wrap=True)
    t.add_column("frames", justify="right")
    t.add_column("train scans", justify="right")
    for n, _, _ in _HEADERS:
        t.add_column(_SHORT[n], justify="right")
    for r in rows:
        tr = r.training
        t.add_row(r.setting, str(r.frames),
                  f"{tr.get('labeled_scans', 0)}+{tr.get('pseudo_labeled_scans', 0)}+{tr.get('pseudo_target_scans', 0)}",
                  *(_cell(r, n, d) for n, _, d in _HEADERS))
    return t


def matched_rich_table(rows: Sequence[Table2Row], category: str, structure: KinematicStructure | None,
                       groups: str) -> Any:
    """Raw and permutation-matched means side by side, as a :class:`rich.table.Table`
    (:mod:`kinmo.ancsh.interchangeable`; per-part values in ``table2.md`` / ``table2.csv``).

    Parameters
    ----------
    rows : sequence of Table2Row
    category : str
    structure : KinematicStructure or None
        None: category rows over several structures.
    groups : str
        The matched parts, for the caption (:func:`kinmo.ancsh.interchangeable.describe_groups`).
    """
    from rich.table import Table

    what = structure.signature() if structure is not None else "all structures"
    t = Table(title=f"Table 2 — {category} ({what}), raw vs permutation-matched means over test scans",
              caption=f"matched: {groups}")
    t.add_column("setting", no_wrap=True)
    t.add_column("frames", justify="right")
    t.add_column("swapped", justify="right")
    for n, _, _ in _HEADERS:
        if n in MATCHED_METRICS:
            t.add_column(f"{_SHORT[n]} raw", justify="right")
            t.add_column(f"{_SHORT[n]} matched", justify="right")
    for r in rows:
        cells = []
        for n, _, d in _HEADERS:
            if n in MATCHED_METRICS:
                cells += [_fmt(r.mean(n), d), _fmt(r.matched_mean(n), d)]
        t.add_row(r.setting, str(r.frames), str(r.swapped), *cells)
    return t


def paper_table(rows: Sequence[Table2Row], category: str) -> Any:
    """The category's Table 2 row of each setting next to the paper's means
    (:data:`kinmo.paper.PAPER_TABLE2`), as a :class:`rich.table.Table` (rotation and
    axis angle error, degrees)."""
    from rich.table import Table


    t = Table(title=f"Table 2 — {category} vs the paper (Liu et al. 2023, mean over its categories)")
    for c in ("setting", "test scans", "rotation (°)", "paper rotation (°)", "axis angle (°)", "paper axis angle (°)"):
        t.add_column(c, justify="left" if c == "setting" else "right")
    for r in rows:
        ref = PAPER_TABLE2.get(r.setting)
        t.add_row(r.setting, str(r.frames), _fmt(r.mean("rotation_deg"), 2),
                  f"{ref['rotation']:.2f}" if ref else "–", _fmt(r.mean("angle_deg"), 2),
                  f"{ref['angle']:.2f}" if ref else "–")
    return t
