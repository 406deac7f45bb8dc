"""Candidate joint axes of a moving part (Liu et al. 2023, Sec. 3.3, "motion refinement").

The regressed axis of the motion GNN is refined by choosing among a few geometrically
meaningful candidates built from the moving part's oriented bounding box (OBB) and the
predicted motion type (:data:`~kinmo.data.model.FINE_TYPES`):

- **side pivot** (``R_H_S``, ``R_V_S``): the OBB edges whose direction has the predicted
  orientation; each edge is a line through the edge midpoint along the edge direction (a door
  hinge is one of the 4 vertical edges of the door's box);
- **centre pivot** (``R_H_C``, ``R_V_C``): the lines through the OBB centre along the OBB axes
  of the predicted orientation, and the same directions through the centroid of the
  *interaction region* between the moving and the reference part
  (:func:`kinmo.geometry.interaction_region`; a knob turns about the line through the middle
  of its contact with the drawer front);
- **prismatic** (``P_H``, ``P_V``) and **both** (``PR_H``, ``PR_V``): the OBB axes of the
  predicted orientation, through the OBB centre (a prismatic axis has no position; the origin
  only matters for the rotation of ``PR``).

Coarse types (:data:`~kinmo.data.model.COARSE_TYPES`, the paper's ``OBB_coarse`` setting)
know neither the orientation nor the pivot kind: ``R`` gets every OBB edge, the centre lines
and the interaction lines of all three axes; ``P`` and ``PR`` all three OBB axes.

Orientation follows the labels (:mod:`kinmo.data.labels`): a direction is vertical when its
angle to the +y axis line is below 45° (``|d_y| > cos 45°``), horizontal otherwise. Of the
three orthonormal OBB axes at most one is vertical, so horizontal candidates always exist;
when no OBB axis is vertical (a box tilted by more than 45°), vertical types fall back to the
axis nearest to ±y.

Candidates are *lines*: a direction and its reverse are the same candidate (the sign of the
motion is decided by the feasibility test, :mod:`kinmo.refine.motions`). Directions are
returned with a canonical sign (largest-magnitude component positive) and coincident lines
(edges of flat, degenerate boxes) are merged.

Frames and units: those of the inputs (kinmo: mesh frame, y-up, mesh units).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from kinmo.data.labels import VERTICAL_COS, obb_edges
from kinmo.data.model import COARSE_TYPES, FINE_TYPES

__all__ = [
    "CANDIDATE_KINDS",
    "MOVING_TYPES",
    "Candidates",
    "candidate_axes",
    "canonical_direction",
    "frame_box",
    "merge_candidates",
    "motion_of",
    "obb_of",
]

#: Kinds of candidates: an OBB edge, a line through the OBB centre, a line through the
#: interaction-region centroid, an OBB axis of a prismatic motion.
CANDIDATE_KINDS: tuple[str, ...] = ("edge", "center", "interaction", "axis")

#: Type names with an axis (fine and coarse), accepted by :func:`candidate_axes`.
MOVING_TYPES: tuple[str, ...] = tuple(
    t for t in FINE_TYPES + COARSE_TYPES if t not in ("Fixed", "None")
)


class _Box(NamedTuple):
    center: np.ndarray
    axes: np.ndarray
    half_extents: np.ndarray


@dataclass(frozen=True)
class Candidates:
    """Candidate axis lines of one moving part.

    Attributes
    ----------
    origins : (C, 3) float64
        A point of each line (edge midpoint, OBB centre or interaction centroid).
    directions : (C, 3) float64
        Unit directions, canonical sign (:func:`canonical_direction`).
    kinds : tuple of str
        One of :data:`CANDIDATE_KINDS` per candidate.
    motion_type : str
        The type the candidates were built for (a name of :data:`MOVING_TYPES`).
    """

    origins: np.ndarray
    directions: np.ndarray
    kinds: tuple[str, ...]
    motion_type: str

    def __len__(self) -> int:
        return int(self.origins.shape[0])

    @property
    def motion(self) -> str:
        """``"R"`` (revolute), ``"P"`` (prismatic) or ``"PR"`` (both)."""
        return motion_of(self.motion_type)

    def subset(self, index: np.ndarray | list[int]) -> Candidates:
        """The candidates at ``index`` (integer indices or a boolean mask)."""
        idx = np.arange(len(self))[np.asarray(index)]
        return Candidates(
            self.origins[idx], self.directions[idx], tuple(self.kinds[i] for i in idx),
            self.motion_type,
        )


def motion_of(motion_type: str) -> str:
    """Coarse motion of a fine or coarse type name: ``"R"``, ``"P"`` or ``"PR"``.

    Raises
    ------
    ValueError
        ``motion_type`` is not in :data:`MOVING_TYPES` (``Fixed`` and ``None`` have no axis).
    """
    if motion_type not in MOVING_TYPES:
        raise ValueError(
            f"motion_type: expected one of {', '.join(MOVING_TYPES)}, got {motion_type!r}"
        )
    return motion_type.split("_")[0]


def canonical_direction(d: np.ndarray) -> np.ndarray:
    """Unit directions with the largest-magnitude component made positive.

    Parameters
    ----------
    d : (..., 3) float
        Non-zero directions.

    Returns
    -------
    (..., 3) float64
        ``±d / |d|``: a line's two directions map to the same vector (ties between equal
        components go to the first of them).
    """
    d = np.asarray(d, dtype=np.float64)
    u = d / np.linalg.norm(d, axis=-1, keepdims=True)
    k = np.argmax(np.abs(u) - 1e-9 * np.arange(3), axis=-1)
    s = np.sign(np.take_along_axis(u, k[..., None], axis=-1))
    return u * np.where(s == 0, 1.0, s)


def obb_of(obb) -> _Box:
    """Validate an OBB given as :class:`kinmo.geometry.OBB` or ``(center, axes, half_extents)``.

    Raises
    ------
    ValueError
        Wrong shapes, non-finite values, negative half extents, or axes that are not
        orthonormal (tolerance 1e-6).
    """
    try:
        center, axes, half = obb
    except (TypeError, ValueError):
        raise ValueError(
            "moving_obb: expected an OBB or a (center, axes, half_extents) triple"
        ) from None
    c = np.asarray(center, dtype=np.float64)
    a = np.asarray(axes, dtype=np.float64)
    h = np.asarray(half, dtype=np.float64)
    if c.shape != (3,) or a.shape != (3, 3) or h.shape != (3,):
        raise ValueError(
            f"moving_obb: expected center (3,), axes (3, 3), half_extents (3,), got "
            f"{c.shape}, {a.shape}, {h.shape}"
        )
    if not (np.all(np.isfinite(c)) and np.all(np.isfinite(a)) and np.all(np.isfinite(h))):
        raise ValueError("moving_obb: non-finite values")
    if np.any(h < 0):
        raise ValueError(f"moving_obb: negative half extents {h}")
    if not np.allclose(a @ a.T, np.eye(3), atol=1e-6):
        raise ValueError("moving_obb: axes are not orthonormal rows")
    return _Box(c, a, h)


def _points(p, name: str) -> np.ndarray:
    p = np.asarray(p, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 3 or p.shape[0] == 0:
        raise ValueError(f"{name}: expected a non-empty (N, 3) array, got shape {p.shape}")
    if not np.all(np.isfinite(p)):
        raise ValueError(f"{name}: non-finite points")
    return p


def _axis_groups(axes: np.ndarray, orientation: str | None) -> list[int]:
    """OBB axis indices of the wanted orientation (``"H"``, ``"V"`` or ``None`` for all)."""
    if orientation is None:
        return [0, 1, 2]
    vertical = np.abs(axes[:, 1]) > VERTICAL_COS
    if orientation == "V":
        ks = [k for k in range(3) if vertical[k]]
        return ks or [int(np.argmax(np.abs(axes[:, 1])))]
    return [k for k in range(3) if not vertical[k]]


def _dedupe(
    origins: list[np.ndarray], directions: np.ndarray, kinds: list[str], tol: float
) -> tuple[np.ndarray, np.ndarray, tuple[str, ...]]:
    """Drop lines that coincide with an earlier kept one (parallel and within ``tol``)."""
    o = np.asarray(origins, dtype=np.float64).reshape(-1, 3)
    d = np.asarray(directions, dtype=np.float64).reshape(-1, 3)
    # same[i, j]: line i coincides with line j (parallel, i's origin within tol of line j)
    parallel = np.abs(d @ d.T) > 1.0 - 1e-9
    off = np.linalg.norm(np.cross(o[:, None] - o[None], d[None]), axis=-1) <= tol
    same = (parallel & off).tolist()
    keep: list[int] = []
    for i in range(len(o)):
        if not any(same[i][j] for j in keep):
            keep.append(i)
    return o[keep].reshape(-1, 3), d[keep].reshape(-1, 3), tuple(kinds[i] for i in keep)


def candidate_axes(
    moving_obb,
    fine_type: str | int,
    moving_points: np.ndarray | None = None,
    reference_points: np.ndarray | None = None,
    *,
    interaction_radius: float = 0.1,
    dedupe_tol: float = 1e-6,
) -> Candidates:
    """Candidate axis lines of a moving part for a predicted motion type (Sec. 3.3).

    Parameters
    ----------
    moving_obb : OBB or (center (3,), axes (3, 3), half_extents (3,))
        OBB of the moving part (rows of ``axes`` orthonormal), e.g.
        :func:`kinmo.geometry.fit_obb` or a :class:`~kinmo.data.graph.PartGraph`'s
        ``obb_center[i], obb_axes[i], obb_half_extents[i]``.
    fine_type : str or int
        A moving fine type (``"R_V_S"``, ...), an index into
        :data:`~kinmo.data.model.FINE_TYPES`, or a coarse type ``"R"``, ``"P"``, ``"PR"``.
    moving_points, reference_points : (N, 3) float64, optional
        Surface samples of the moving and the reference part. With both, centre-pivot types
        (and coarse ``R``) also get lines through the interaction-region centroid.
    interaction_radius : float
        Radius of the interaction region relative to the moving part's size: the absolute
        radius is ``interaction_radius * 2 * |half_extents|`` (a fraction of the OBB's
        diagonal), floored at 1e-9.
    dedupe_tol : float
        Lines closer than ``dedupe_tol * diagonal`` (and parallel) are merged.

    Returns
    -------
    Candidates
        In a fixed order: edges (grouped by OBB axis, as :func:`kinmo.data.labels.obb_edges`),
        then centre lines, interaction lines, prismatic axes.

    Raises
    ------
    ValueError
        A ``Fixed`` / ``None`` / unknown type, a malformed OBB or point array.

    Examples
    --------
    A door-like slab, 1 wide (x), 2 high (y), 0.05 thick (z): its 4 vertical edges are the
    side-pivot candidates of ``R_V_S``.

    >>> import numpy as np
    >>> c = candidate_axes((np.zeros(3), np.eye(3), np.array([0.5, 1.0, 0.025])), "R_V_S")
    >>> len(c), c.kinds[0], c.directions[0].tolist()
    (4, 'edge', [0.0, 1.0, 0.0])
    """
    if isinstance(fine_type, (int, np.integer)):
        if not 0 <= int(fine_type) < len(FINE_TYPES):
            raise ValueError(f"fine_type: index {fine_type} out of range 0..{len(FINE_TYPES) - 1}")
        fine_type = FINE_TYPES[int(fine_type)]
    motion = motion_of(str(fine_type))
    box = obb_of(moving_obb)
    parts = str(fine_type).split("_")
    orientation = parts[1] if len(parts) > 1 else None
    pivot = parts[2] if len(parts) > 2 else None  # "C", "S" or None (coarse R: both)
    diag = 2.0 * float(np.linalg.norm(box.half_extents))
    ks = _axis_groups(box.axes, orientation)

    origins: list[np.ndarray] = []
    directions: list[np.ndarray] = []
    kinds: list[str] = []

    def add(o: np.ndarray, d: np.ndarray, kind: str) -> None:
        origins.append(np.asarray(o, dtype=np.float64))
        directions.append(np.asarray(d, dtype=np.float64))  # made canonical below, at once
        kinds.append(kind)

    if motion == "R":
        if pivot in ("S", None):
            edges = obb_edges(box.center, box.axes, box.half_extents)  # (12, 2, 3), 4 per axis
            for k in ks:
                for e in edges[4 * k : 4 * k + 4]:
                    add(0.5 * (e[0] + e[1]), box.axes[k], "edge")
        if pivot in ("C", None):
            for k in ks:
                add(box.center, box.axes[k], "center")
            if moving_points is not None and reference_points is not None:
                from kinmo.geometry import interaction_region

                mp = _points(moving_points, "moving_points")
                rp = _points(reference_points, "reference_points")
                radius = max(interaction_radius * diag, 1e-9)
                region = interaction_region(mp, rp, radius)
                for k in ks:
                    add(region.centroid, box.axes[k], "interaction")
    else:  # P, PR: directions of the OBB axes, through the centre
        for k in ks:
            add(box.center, box.axes[k], "axis")

    # one call on all rows: row by row the same arithmetic as one call per line
    canonical = canonical_direction(np.asarray(directions, dtype=np.float64).reshape(-1, 3))
    o, d, kinds_t = _dedupe(origins, canonical, kinds, dedupe_tol * max(diag, 1e-12))
    return Candidates(o, d, kinds_t, str(fine_type))



def frame_box(points: np.ndarray, axes: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The bounding box of ``points`` whose axes are the rows of ``axes``.

    kinmo extension of the candidates (Sec. 3.3 uses the moving part's own OBB only): the
    moving part boxed in another frame, e.g. its reference part's OBB axes or the shape frame
    (``np.eye(3)``), gives candidate lines along *that* frame's directions. A laptop lid
    opened by 30° has an OBB tilted by 30° from its hinge; boxed in the base's frame, one of
    its edges is the hinge.

    Parameters
    ----------
    points : (N, 3) float64
        The moving part's surface samples (mesh frame), N >= 1.
    axes : (3, 3) float64
        Orthonormal rows (a rotation's transpose), e.g. ``graph.obb_axes[j]``.

    Returns
    -------
    center : (3,) float64
    axes : (3, 3) float64
        ``axes``, unchanged.
    half_extents : (3,) float64
        Half the extent of ``points`` along each row of ``axes`` (>= 0).

    Raises
    ------
    ValueError
        ``points`` is not (N, 3) with N >= 1 or has non-finite values; ``axes`` is not an
        orthonormal (3, 3) array.
    """
    p = _points(points, "points")
    r = np.asarray(axes, dtype=np.float64)
    if r.shape != (3, 3) or not np.all(np.isfinite(r)) or not np.allclose(r @ r.T, np.eye(3), atol=1e-6):
        raise ValueError(f"axes: expected orthonormal rows of shape (3, 3), got {r.shape}")
    local = p @ r.T
    lo, hi = local.min(axis=0), local.max(axis=0)
    return 0.5 * (lo + hi) @ r, r.copy(), 0.5 * (hi - lo)


def merge_candidates(first: Candidates, extra: Candidates, *, angle_deg: float, distance: float
                     ) -> Candidates:
    """``first`` followed by the lines of ``extra`` that no line of ``first`` already covers.

    A line of ``extra`` is covered when a line of ``first`` is within ``angle_deg`` of its
    direction and, for revolute motions (``R``, ``PR``: the axis position matters), passes
    within ``distance`` of its origin.

    Parameters
    ----------
    first, extra : Candidates
        For the same motion type.
    angle_deg : float
        Direction tolerance (degrees, >= 0).
    distance : float
        Position tolerance (mesh units, >= 0).

    Returns
    -------
    Candidates

    Raises
    ------
    ValueError
        The motion types differ.
    """
    if first.motion_type != extra.motion_type:
        raise ValueError(f"merge_candidates: {first.motion_type} vs {extra.motion_type}")
    cos = float(np.cos(np.radians(angle_deg)))
    positional = first.motion != "P"
    o, d, k = [first.origins], [first.directions], list(first.kinds)
    for i in range(len(extra)):
        ko, kd = np.vstack(o), np.vstack(d)
        para = np.abs(kd @ extra.directions[i]) >= cos - 1e-12
        if positional:
            off = np.linalg.norm(np.cross(extra.origins[i] - ko, kd), axis=1)
            para &= off <= distance
        if not para.any():
            o.append(extra.origins[i][None])
            d.append(extra.directions[i][None])
            k.append(extra.kinds[i])
    return Candidates(np.vstack(o), np.vstack(d), tuple(k), first.motion_type)
