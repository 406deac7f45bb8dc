"""The learned side of a joint's range: a prior of ranges per category and part name.

Fitted on labelled objects (PartNet-Mobility): every true hinge and slider gives its range in
kinmo's sign convention (the axis oriented by :func:`kinmo.mobility_tree.opening_direction`,
as predicted joints are, so a positive value opens the part), in **prior units**:

- hinges: degrees from the rest pose, ``[min, max]`` shifted by whole turns towards 0
  (:func:`kinmo.metrics.motion_range.hinge_interval`); ``noLimit`` and ranges of a full turn
  or more count as *continuous*;
- sliders (and the translation of cylindrical joints): fractions of the moving part's
  extent along the axis (:func:`axial_extent`: a drawer slides about its own depth, a
  button a fraction of its height), the extent floored at :attr:`RangePrior.min_extent`
  of the shape's diagonal. The floor is part of the unit, so it is stored with the prior
  (``ranges.json`` ``min_extent``; a file without it was written with the former floor,
  :data:`LEGACY_MIN_EXTENT_FRACTION`). Since session 16 the floor is 0.2 % of the diagonal
  (:data:`MIN_EXTENT_FRACTION`) where it was 2 %: buttons are thinner than 2 % of their
  object's diagonal, so the old floor made every button's unit the diagonal. Their travel
  follows their own height (a remote's taller buttons travel further): out of fold on the
  235 shared objects (``kinmo eval oof``, OBB_fine, pooled), slider range IoU 0.527 -> 0.714
  (fold seed 0) and 0.485 -> 0.680 (seed 1) (docs/results/ranges.md).

Entries are grouped by ``(kind, category, name)``, ``(kind, category)``, ``(kind, name)`` and
``(kind,)``; a query takes the most specific group that exists (:meth:`RangePrior.lookup`).
Hinges are also grouped by their fine motion type (``(kind, fine)``: ``R_H_C``, ``R_V_S`` ...,
:data:`kinmo.data.model.FINE_TYPES`; since file version 2). A hinge that only the kind alone
covers (a part of unknown category and name: a user's ``part_<k>``) takes its range from the
kind's group and whether it turns freely from its predicted fine type's group: rotations about
a central axis (knobs, wheels, caps) mostly turn without limit, about a side axis (doors, lids)
never. Cross-validated on the 235 shared objects (5 folds, true types and axes), continuous-or-
not accuracy of such hinges rises from 0.635 to 0.927, while their range IoU goes from 0.485 to
0.476 (the range itself from the fine group instead: 0.516, but fewer at IoU >= 0.5, 0.55
against 0.63; docs/results/ranges.md).
Each group keeps the number of joints, the share of continuous ones and its **medoid
range**: the training range with the largest summed IoU to the group's others, a range that
actually occurs, which on 5-fold cross-validation of the shared data's 235 objects (true
axes) gave hinge range IoU 0.70 against 0.68 for the median of each end
(docs/results/ranges.md). A training range that leaves out the rest state (7 of the shared
data's 719 limited ranges: a washing machine door annotated 70° to 178°, dishwasher shelves,
bottle lids) is widened to reach 0 first, so that every group's range holds the rest pose.

File: ``ranges.json`` (:meth:`RangePrior.save`), written by ``kinmo train all`` into the
model bundle. It is read as untrusted input: size bounded, every number finite and bounded,
names plain text.
"""

from __future__ import annotations

import math
from collections import defaultdict
from collections.abc import Iterable
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from kinmo import limits
from kinmo.data.graph import PartGraph
from kinmo.data.labels import link_subtree
from kinmo.data.model import FINE_TYPES
from kinmo.errors import KinmoDataError
from kinmo.io import read_json_document, write_json
from kinmo.metrics.motion_range import hinge_interval, range_iou
from kinmo.mobility_tree import opening_direction

__all__ = ["LEGACY_MIN_EXTENT_FRACTION", "MIN_EXTENT_FRACTION", "PRIOR_FORMAT", "PRIOR_VERSION", "RangeEntry",
           "RangePrior", "TrueRange", "axial_extent", "fit_range_prior", "true_ranges"]

PRIOR_FORMAT = "kinmo-range-prior"
#: Version 2 adds the hinge groups by fine type (``"fine"``); version 1 files still load.
PRIOR_VERSION = 2
#: Floor of a slider's axial extent, as a fraction of the shape's diagonal (a flat part
#: moving along its normal still gets a usable unit), for priors fitted now ...
MIN_EXTENT_FRACTION = 0.002
#: ... and for prior files that do not record theirs (written before session 16).
LEGACY_MIN_EXTENT_FRACTION = 0.02
#: Largest magnitude accepted for a range end in a prior file (degrees or extents).
_MAX_END = 1.0e4
_KINDS = ("hinge", "slider")


def axial_extent(points: np.ndarray, direction: np.ndarray, scale: float,
                 floor: float = MIN_EXTENT_FRACTION) -> float:
    """The moving part's extent along its axis: the prior's unit of slider travel.

    Parameters
    ----------
    points : (N, 3) float
        Surface points of the moving part (mesh frame).
    direction : (3,) float64
        Unit axis direction.
    scale : float
        The shape's diagonal (mesh units).
    floor : float
        Smallest extent, as a fraction of ``scale`` (the prior's :attr:`RangePrior.min_extent`).

    Returns
    -------
    float
        ``max(ptp(points . d), floor * scale)``, mesh units, > 0 for positive ``floor`` and
        ``scale``.
    """
    p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    e = float(np.ptp(p @ np.asarray(direction, float))) if len(p) else 0.0
    return max(e, float(floor) * float(scale))


@dataclass(frozen=True)
class TrueRange:
    """One true joint's range in prior units (module docstring).

    Attributes
    ----------
    kind : {"hinge", "slider"}
    category, name : str
    continuous : bool
        A hinge turning without limit (``lo``/``hi`` are then 0).
    lo, hi : float
        Degrees (hinges) or axial extents (sliders), ``lo <= hi``.
    fine : str
        The joint's fine motion type (:data:`kinmo.data.model.FINE_TYPES`, that of a sibling
        edge of its link); empty when the graph has none.
    """

    kind: str
    category: str
    name: str
    continuous: bool
    lo: float
    hi: float
    fine: str = ""


def _centres(g: PartGraph, lk: dict, moving: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Moving and reference centres of a true link, as the mobility tree would take them: the
    OBB centres of a sibling edge of the link's joint (its reference in the parent link when
    there is one), else the point means of the link and of its parent link."""
    if g.edge_link is not None and len(g.sibling_edges):
        ks = np.flatnonzero(np.asarray(g.edge_link) == lk["id"])
        if len(ks):
            nl = np.asarray(g.node_link)
            pick = [k for k in ks if nl[g.sibling_edges[k][1]] == lk["parent"]]
            i, j = g.sibling_edges[int((pick or list(ks))[0])]
            return np.asarray(g.obb_center[i], float), np.asarray(g.obb_center[j], float)
    leaves = np.flatnonzero(g.is_leaf)
    nl = np.asarray(g.node_link)
    rest = [n for n in leaves if nl[n] == lk["parent"]] or list(np.setdiff1d(leaves, moving))
    cm = np.asarray(g.points[moving], float).reshape(-1, 3).mean(0)
    cr = np.asarray(g.points[rest], float).reshape(-1, 3).mean(0) if rest else cm
    return cm, cr


def _fine_type(g: PartGraph, link: int) -> str:
    """The fine motion type of a sibling edge of true link ``link`` (empty: none)."""
    if g.edge_link is None or g.edge_fine is None or not len(g.sibling_edges):
        return ""
    ks = np.flatnonzero(np.asarray(g.edge_link) == link)
    return FINE_TYPES[int(g.edge_fine[ks[0]])] if len(ks) else ""


def true_ranges(g: PartGraph, min_extent: float = MIN_EXTENT_FRACTION) -> list[TrueRange]:
    """The true hinge and slider ranges of a labelled part graph, in prior units.

    Parameters
    ----------
    g : PartGraph
        PartNet-Mobility graph (``meta["links"]``, ``node_link``).
    min_extent : float
        Floor of the slider unit, a fraction of the diagonal (:func:`axial_extent`).

    Returns
    -------
    list of TrueRange
        One per moving link with an axis; empty for an unlabelled graph.
    """
    links = g.meta.get("links") or []
    if g.node_link is None or not links:
        return []
    leaves = np.flatnonzero(g.is_leaf)
    nl = np.asarray(g.node_link)[leaves]
    parent_of = {lk["id"]: lk["parent"] for lk in links}
    out = []
    for lk in links:
        if lk.get("joint") not in _KINDS or lk.get("direction") is None:
            continue
        moving = leaves[np.isin(nl, list(link_subtree(parent_of, lk["id"])))]
        if not len(moving):
            continue
        hinge = lk["joint"] == "hinge"
        o = np.asarray(lk.get("origin") or (0.0, 0.0, 0.0), float)
        d0 = np.asarray(lk["direction"], float)
        cm, cr = _centres(g, lk, moving)
        d = opening_direction(hinge, o, d0, cm, cr)
        flip = float(np.dot(d, d0)) < 0
        lim = lk.get("limit")
        name, cat = str(lk.get("name", "")), str(g.category)
        if hinge:
            if lim is not None and flip:
                lim = (-float(lim[1]), -float(lim[0]))
            iv = None if lim is None else hinge_interval(*lim)
            fine = _fine_type(g, lk["id"])
            if iv is None:
                out.append(TrueRange("hinge", cat, name, True, 0.0, 0.0, fine))
            else:
                out.append(TrueRange("hinge", cat, name, False, *iv, fine))
            continue
        if lim is None:  # a slider without limits: nothing to learn from
            continue
        lo, hi = sorted(float(x) for x in lim)
        if flip:
            lo, hi = -hi, -lo
        ext = axial_extent(g.points[moving], d, g.scale, min_extent)
        out.append(TrueRange("slider", cat, name, False, lo / ext, hi / ext))
    return out


@dataclass(frozen=True)
class RangeEntry:
    """A group of the prior (module docstring).

    Attributes
    ----------
    kind : {"hinge", "slider"}
    category, name : str or None
        None: any.
    n : int
        Training joints in the group.
    continuous : float
        Share of them that turn without limit (hinges), in ``[0, 1]``.
    lo, hi : float or None
        The medoid range in prior units (None when every joint of the group is continuous).
    fine : str or None
        A fine motion type: the hinge group of that type (``category`` and ``name`` None);
        None for the other groups.
    """

    kind: str
    category: str | None
    name: str | None
    n: int
    continuous: float
    lo: float | None
    hi: float | None
    fine: str | None = None

    @property
    def is_continuous(self) -> bool:
        """Most of the group's joints turn freely."""
        return self.continuous >= 0.5 or self.lo is None


def _key(kind: str, category: str | None, name: str | None, fine: str | None = None) -> tuple:
    return (kind, category.lower() if category else None, name.lower() if name else None, fine or None)


@dataclass
class RangePrior:
    """Range prior: groups of :class:`RangeEntry` (module docstring).

    Attributes
    ----------
    entries : list of RangeEntry
    min_extent : float
        Floor of the slider unit its entries were fitted with, a fraction of the shape's
        diagonal (:func:`axial_extent`); predictions must use the same.
    """

    entries: list[RangeEntry] = field(default_factory=list)
    min_extent: float = MIN_EXTENT_FRACTION

    def __post_init__(self) -> None:
        self._by = {_key(e.kind, e.category, e.name, e.fine): e for e in self.entries}

    def lookup(self, kind: str, category: str | None, name: str | None,
               fine: str | None = None) -> RangeEntry | None:
        """The most specific group of ``kind`` for a joint: ``(category, name)``, then
        ``category``, then ``name``, then the kind alone; None when the prior has none.
        Matching is case-insensitive; an empty category or name counts as unknown.

        When only the kind alone covers a hinge and ``fine`` (its predicted fine type) has a
        group, the kind's entry is returned with that group's share of continuous joints
        (module docstring)."""
        cat, nm = category or None, name or None
        for c, n in ((cat, nm), (cat, None), (None, nm), (None, None)):
            e = self._by.get(_key(kind, c, n))
            if e is not None:
                f = self._by.get(_key(kind, None, None, fine)) if fine and c is None and n is None else None
                return e if f is None else replace(e, continuous=f.continuous)
        return None

    def save(self, path: str | Path) -> None:
        """Write ``ranges.json`` atomically."""
        write_json(Path(path), {
            "format": PRIOR_FORMAT, "version": PRIOR_VERSION,
            "units": {"hinge": "degrees from the rest pose",
                      "slider": "fractions of the moving part's extent along the axis"},
            "min_extent": self.min_extent,
            "entries": [{"kind": e.kind, "category": e.category, "name": e.name, "n": e.n,
                         "continuous": e.continuous, "lo": e.lo, "hi": e.hi,
                         **({"fine": e.fine} if e.fine else {})}
                        for e in self.entries]})

    @classmethod
    def load(cls, path: str | Path) -> RangePrior:
        """Read ``ranges.json``.

        Raises
        ------
        KinmoDataError
            Missing, too large, malformed, of another format or a newer version, or an entry
            out of bounds (one line naming the file).
        """
        p = Path(path)
        doc = read_json_document(p, PRIOR_FORMAT, PRIOR_VERSION, "range prior",
                                 "range prior missing (run `kinmo train all`)")
        raw = doc.get("entries")
        if not isinstance(raw, list):
            raise KinmoDataError(p, "malformed range prior: 'entries' must be a list")
        limits.check("range_entries", len(raw), p)
        floor = doc.get("min_extent", LEGACY_MIN_EXTENT_FRACTION)
        if not isinstance(floor, (int, float)) or isinstance(floor, bool) or not 0.0 < float(floor) <= 1.0:
            raise KinmoDataError(p, "malformed range prior: 'min_extent' must be a number in (0, 1]")
        return cls([_entry(e, p) for e in raw], float(floor))


def _entry(e: object, p: Path) -> RangeEntry:
    def bad(why: str) -> KinmoDataError:
        return KinmoDataError(p, f"malformed range prior entry: {why}")

    if not isinstance(e, dict) or e.get("kind") not in _KINDS:
        raise bad("each entry needs a kind 'hinge' or 'slider'")
    for k in ("category", "name"):
        if e.get(k) is not None and (not isinstance(e[k], str) or len(e[k]) > 256):
            raise bad(f"{k} must be a string of at most 256 characters or null")
    n, c = e.get("n"), e.get("continuous")
    if not isinstance(n, int) or n < 1 or not isinstance(c, (int, float)) or not 0.0 <= c <= 1.0:
        raise bad("n must be a positive integer and continuous a share in [0, 1]")
    lo, hi = e.get("lo"), e.get("hi")
    if (lo is None) != (hi is None):
        raise bad("lo and hi must both be numbers or both null")
    if lo is not None:
        if not all(isinstance(x, (int, float)) and math.isfinite(x) and abs(x) <= _MAX_END for x in (lo, hi)) \
                or lo > hi:
            raise bad(f"lo <= hi must be finite numbers within ±{_MAX_END:g}")
        lo, hi = float(lo), float(hi)
    fine = e.get("fine")
    if fine is not None and (fine not in FINE_TYPES or e.get("category") is not None or e.get("name") is not None):
        raise bad("fine must be a fine motion type, on an entry without category and name")
    return RangeEntry(e["kind"], e.get("category"), e.get("name"), n, float(c), lo, hi, fine)


def _medoid(ranges: list[tuple[float, float]]) -> tuple[float, float]:
    """The range with the largest summed IoU to the others (ties: the first in sorted order)."""
    ranges = sorted(ranges)
    scores = [sum(range_iou(a, b) for b in ranges) for a in ranges]
    return ranges[int(np.argmax(scores))]


def fit_range_prior(graphs: Iterable[PartGraph], min_extent: float = MIN_EXTENT_FRACTION) -> RangePrior:
    """Fit the prior on labelled part graphs (module docstring).

    Parameters
    ----------
    graphs : iterable of PartGraph
        Labelled graphs (others give nothing); typically the training split.
    min_extent : float
        Floor of the slider unit, a fraction of the diagonal, recorded in the prior.

    Returns
    -------
    RangePrior
        Empty when no graph has a moving joint.
    """
    groups: dict[tuple, list[TrueRange]] = defaultdict(list)
    for g in graphs:
        for t in true_ranges(g, min_extent):
            cat, nm = t.category or None, t.name or None
            keys = {(t.kind, cat, nm, None), (t.kind, cat, None, None), (t.kind, None, nm, None),
                    (t.kind, None, None, None)}
            if t.kind == "hinge" and t.fine:
                keys.add((t.kind, None, None, t.fine))
            for key in keys:
                groups[key].append(t)
    entries = []
    for (kind, cat, name, fine), ts in sorted(groups.items(), key=lambda kv: tuple(str(x) for x in kv[0])):
        # a range always holds the rest state (a few annotations leave it out)
        limited = [(min(t.lo, 0.0), max(t.hi, 0.0)) for t in ts if not t.continuous]
        lo, hi = _medoid(limited) if limited else (None, None)
        entries.append(RangeEntry(kind, cat, name, len(ts), float(np.mean([t.continuous for t in ts])),
                                  lo, hi, fine))
    return RangePrior(entries, min_extent)
