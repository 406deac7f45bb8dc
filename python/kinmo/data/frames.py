"""Frames and units of a user's asset, and the map into kinmo's mesh frame and back.

kinmo's models were trained on PartNet / PartNet-Mobility meshes: **y-up** (+y vertical),
centred near the origin, scaled so that the bounding-box diagonal is about 2 (the shared
objects' median is 2.06). A user's asset comes in its own convention:

==========  =======  ==========================================================
format      default  why
==========  =======  ==========================================================
glTF / GLB  ``y``    the glTF 2.0 specification: +Y up, metres
URDF        ``z``    ROS REP 103: +Z up, metres
MJCF        ``z``    MuJoCo: gravity along -Z by default, metres (:mod:`kinmo.assets.mjcf`)
OBJ, folder ``y``    no convention in the format; y-up is the common exporter default
==========  =======  ==========================================================

:class:`AssetFrame` is the similarity transform ``p_kinmo = s R (p - c)`` that takes the
asset's coordinates into kinmo's frame (``R`` a proper rotation taking the asset's up axis
to +y, ``c`` the bounding-box centre, ``s = 2 / diagonal``); :meth:`AssetFrame.links_to_asset`
maps predicted joints back, so that every output is in the asset's own frame and units.
:func:`guess_up` checks the declared up axis against the asset's support faces and returns
the axis the geometry suggests (a warning, never a silent change).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np

from kinmo.data.model import Joint, JointType, Link

__all__ = ["UP_AXES", "AssetFrame", "default_up", "guess_up", "quarter_turn"]


def quarter_turn(k: int) -> np.ndarray:
    """Rotation by ``k`` quarter turns about the vertical (+y), exact: ``(3, 3) float64`` of
    0 and +-1 (:func:`kinmo.features.yaw_rotation` of ``k * pi / 2`` without its rounding).
    Re-exported by :mod:`kinmo.features`; here so that torch-free modules can use it."""
    k = int(k) % 4
    c, s = (1.0, 0.0, -1.0, 0.0)[k], (0.0, 1.0, 0.0, -1.0)[k]
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


UpAxis = Literal["y", "z"]
#: The up axes ``--up`` accepts.
UP_AXES: tuple[str, ...] = ("y", "z")

#: How much larger the other axis's support area must be for :func:`guess_up` to speak.
#: Measured on the 235 shared PartNet-Mobility objects (y-up), each also turned z-up and read
#: as y-up: a ratio of 4 flags 26% of the correct y-up objects and 58% of the turned ones;
#: 100: 7% and 22%; 1000: 5% and 14%. Box-like objects rest as well on their backs as on
#: their bottoms, so support faces cannot tell the two apart reliably: the check is a hint
#: for the clear cases, kept rare on correct input.
GUESS_RATIO = 1000.0

#: kinmo's target bounding-box diagonal (PartNet-Mobility's objects: median 2.06).
TARGET_DIAGONAL = 2.0

# Rotation taking the asset's up axis to +y, as a proper rotation (det +1):
# z-up -> y-up is (x, y, z) -> (x, z, -y), a -90 degree turn about +x.
_ROTATIONS: dict[str, np.ndarray] = {
    "y": np.eye(3),
    "z": np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]]),
}


def default_up(suffix: str) -> UpAxis:
    """The up axis an input format declares (module table): ``"z"`` for ``.urdf``, else ``"y"``.

    Parameters
    ----------
    suffix : str
        File suffix with its dot (``".glb"``), any case; ``""`` for a folder of meshes.
    """
    return "z" if suffix.lower() == ".urdf" else "y"


@dataclass(frozen=True)
class AssetFrame:
    """The similarity ``p_kinmo = scale * rotation @ (p - center)`` (module docs).

    Attributes
    ----------
    up : {"y", "z"}
        The asset's up axis.
    rotation : (3, 3) float64
        Proper rotation taking the asset's up axis to kinmo's +y.
    center : (3,) float64
        Bounding-box centre of the asset, asset units.
    scale : float
        kinmo units per asset unit (``2 / diagonal``; 1 for an empty or point-like asset).
    """

    up: str
    rotation: np.ndarray
    center: np.ndarray
    scale: float

    @classmethod
    def fit(cls, vertices: Iterable[np.ndarray], up: str = "y", normalize: bool = True) -> AssetFrame:
        """The frame of an asset whose parts have ``vertices``.

        Parameters
        ----------
        vertices : iterable of (V, 3) float64
            Vertices of every part, asset frame and units.
        up : {"y", "z"}
            The asset's up axis.
        normalize : bool
            Centre and scale to kinmo's size (diagonal 2); ``False`` keeps position and units
            and only rotates.

        Raises
        ------
        ValueError
            ``up`` is not one of :data:`UP_AXES`, or a vertex is not finite.
        """
        if up not in _ROTATIONS:
            raise ValueError(f"up axis must be one of {', '.join(UP_AXES)}, not {up!r}")
        pts = [np.asarray(v, dtype=np.float64).reshape(-1, 3) for v in vertices]
        pts = [p for p in pts if len(p)]
        center, scale = np.zeros(3), 1.0
        if pts and normalize:
            lo = np.min([p.min(0) for p in pts], axis=0)
            hi = np.max([p.max(0) for p in pts], axis=0)
            if not (np.isfinite(lo).all() and np.isfinite(hi).all()):
                raise ValueError("non-finite vertex coordinates")
            center = (lo + hi) / 2.0
            diag = float(np.linalg.norm(hi - lo))
            if diag > 0.0:
                scale = TARGET_DIAGONAL / diag
        return cls(up=up, rotation=_ROTATIONS[up], center=center, scale=scale)

    def to_kinmo(self, points: np.ndarray) -> np.ndarray:
        """Points ``(N, 3) float64`` of the asset frame -> kinmo's frame."""
        p = np.asarray(points, dtype=np.float64)
        return self.scale * (p - self.center) @ self.rotation.T

    def to_asset(self, points: np.ndarray) -> np.ndarray:
        """Points ``(N, 3) float64`` of kinmo's frame -> the asset frame and units."""
        p = np.asarray(points, dtype=np.float64)
        return (p / self.scale) @ self.rotation + self.center

    def direction_to_asset(self, direction: np.ndarray) -> np.ndarray:
        """A direction ``(3,) float64`` of kinmo's frame -> the asset frame (length kept)."""
        return np.asarray(direction, dtype=np.float64) @ self.rotation

    def to_json(self) -> dict:
        """``{"up", "rotation", "center", "scale"}``: how the asset was read (``frame.json`` of
        ``kinmo predict FILE``), plain lists and floats."""
        return {"up": self.up, "rotation": self.rotation.tolist(), "center": self.center.tolist(),
                "scale": float(self.scale),
                "map": "p_kinmo = scale * (p_asset - center) @ rotation.T"}

    @property
    def is_identity(self) -> bool:
        """True when the map changes nothing (y-up, not centred or scaled)."""
        return self.up == "y" and self.scale == 1.0 and not self.center.any()

    def joint_to_asset(self, joint: Joint) -> Joint:
        """``joint`` (kinmo frame) in the asset frame: axis point and direction mapped, slider
        limits divided by the scale (hinge limits are angles and stay)."""
        origin = None if joint.origin is None else self.to_asset(joint.origin[None])[0]
        direction = None if joint.direction is None else self.direction_to_asset(joint.direction)
        limit = joint.limit
        if limit is not None and joint.type == JointType.SLIDER:
            limit = (limit[0] / self.scale, limit[1] / self.scale)
        return dataclasses.replace(joint, origin=origin, direction=direction, limit=limit)

    def links_to_asset(self, links: Sequence[Link]) -> list[Link]:
        """Every link's joint in the asset frame (:meth:`joint_to_asset`)."""
        return [dataclasses.replace(link, joint=self.joint_to_asset(link.joint)) for link in links]


def _support_area(vertices: np.ndarray, faces: np.ndarray, axis: int, sign: float, band: float) -> float:
    """Area of the faces facing ``-sign * e_axis`` within ``band`` of the lowest extreme along it."""
    tri = vertices[faces]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    area2 = np.linalg.norm(n, axis=1)
    ok = area2 > 0
    if not ok.any():
        return 0.0
    coord = sign * tri[..., axis].mean(axis=1)
    low = coord.min()
    facing = np.zeros(len(tri), dtype=bool)
    facing[ok] = (-sign * n[ok, axis] / area2[ok]) > np.cos(np.radians(15.0))
    return float(area2[facing & (coord <= low + band)].sum() / 2.0)


def guess_up(parts: Sequence[tuple[np.ndarray, np.ndarray]], up: str) -> str | None:
    """The up axis the geometry suggests, when it disagrees clearly with ``up``.

    An object standing in its frame rests on faces that look down along ``-up`` at its
    lowest extreme (a cabinet's bottom, a laptop's base). The support area below is the area
    of faces within 15 degrees of facing ``-axis`` and within 2% of the extent of the lowest
    extreme along ``axis``; for each candidate axis in :data:`UP_AXES` it is measured in the
    asset frame (``y``: the asset's y; ``z``: its z).

    Parameters
    ----------
    parts : sequence of ((V, 3) float64, (F, 3) int64)
        Vertices and faces of every part, in the asset frame.
    up : {"y", "z"}
        The declared up axis.

    Returns
    -------
    str or None
        The other axis when its support area is more than :data:`GUESS_RATIO` times the
        declared one's (and
        that one's is not zero for both), else ``None``: a heuristic for a warning, not a
        decision.
    """
    parts = [(np.asarray(v, dtype=np.float64), np.asarray(f, dtype=np.int64)) for v, f in parts if len(f)]
    if not parts:
        return None
    allv = np.concatenate([v for v, _ in parts])
    extent = float(np.linalg.norm(allv.max(0) - allv.min(0)))
    if extent <= 0:
        return None
    band = 0.02 * extent
    merged_v, merged_f, n = [], [], 0
    for v, f in parts:
        merged_v.append(v)
        merged_f.append(f + n)
        n += len(v)
    v, f = np.concatenate(merged_v), np.concatenate(merged_f)
    area = {ax: _support_area(v, f, {"y": 1, "z": 2}[ax], 1.0, band) for ax in UP_AXES}
    other = "z" if up == "y" else "y"
    if area[other] > GUESS_RATIO * area[up] and area[other] > 0:
        return other
    return None
