"""Closed triangle meshes for procedural objects: boxes, solids of revolution, swept tubes.

Every builder returns a watertight :class:`trimesh.Trimesh` with consistent outward winding
(positive volume), so point-in-mesh tests and volume computations are meaningful on it.
Coordinates are in the object frame: y-up, +z is the front of an object, metres before
normalisation. Round shapes are tessellated with a fixed number of sections whose first
vertex lies at angle 0 (on the +x side of a y-axis lathe), so two coaxial lathes with the same
section count have aligned, similar polygons: a bore of radius ``r + c`` around a shaft of
radius ``r`` keeps its clearance after tessellation.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import trimesh

#: Default number of sections of round parts (bottle bodies, knobs, caps, pins).
SECTIONS = 48


def _mesh(vertices: np.ndarray, faces: np.ndarray) -> trimesh.Trimesh:
    """Build a mesh without trimesh's processing (no merging, no reordering) and orient it.

    Raises
    ------
    ValueError
        The mesh is not watertight (a bug of the builder).
    """
    mesh = trimesh.Trimesh(
        vertices=np.asarray(vertices, dtype=np.float64),
        faces=np.asarray(faces, dtype=np.int64),
        process=False,
    )
    if not (mesh.is_watertight and mesh.is_winding_consistent):
        raise ValueError("procedural mesh is not watertight with consistent winding")
    if mesh.volume < 0:
        mesh.invert()
    return mesh


def box(lo: Sequence[float], hi: Sequence[float]) -> trimesh.Trimesh:
    """An axis-aligned box.

    Parameters
    ----------
    lo, hi : (3,) float
        Opposite corners (object frame, metres), ``lo < hi`` componentwise.

    Returns
    -------
    trimesh.Trimesh
        8 vertices, 12 outward triangles.

    Raises
    ------
    ValueError
        An extent is not positive.
    """
    lo = np.asarray(lo, dtype=np.float64)
    hi = np.asarray(hi, dtype=np.float64)
    if np.any(hi - lo <= 0):
        raise ValueError(f"box extents must be positive, got lo={lo.tolist()} hi={hi.tolist()}")
    # corner i has coordinate a from hi when bit a of i is set
    v = np.array(
        [[(hi if (i >> a) & 1 else lo)[a] for a in range(3)] for i in range(8)], dtype=np.float64
    )
    # two triangles per face, outward (checked by _mesh)
    faces = np.array(
        [
            [0, 4, 6],
            [0, 6, 2],  # x = lo
            [1, 3, 7],
            [1, 7, 5],  # x = hi
            [0, 1, 5],
            [0, 5, 4],  # y = lo
            [2, 6, 7],
            [2, 7, 3],  # y = hi
            [0, 2, 3],
            [0, 3, 1],  # z = lo
            [4, 5, 7],
            [4, 7, 6],  # z = hi
        ],
        dtype=np.int64,
    )
    return _mesh(v, faces)


def lathe(
    profile: Sequence[Sequence[float]],
    sections: int = SECTIONS,
    center: Sequence[float] = (0.0, 0.0, 0.0),
    axis: str = "y",
) -> trimesh.Trimesh:
    """Revolve a 2D profile ``(r, h)`` about an axis: a closed solid of revolution.

    The profile is a polygon in the half plane ``r >= 0``. If its first and last points lie on
    the axis (``r == 0``) it is closed by the axis (a solid such as a disc, a cup or a bottle);
    otherwise it is a closed loop away from the axis (a ring). Points on the axis become single
    pole vertices. Consecutive duplicate points are not allowed.

    Parameters
    ----------
    profile : (K, 2) float
        ``(radius, height)`` pairs in metres; heights are measured along ``axis``.
    sections : int
        Number of angular sections (>= 3); section 0 lies at angle 0 (see module docstring).
    center : (3,) float
        Point of the axis where height 0 lies (object frame).
    axis : {"x", "y", "z"}
        Axis of revolution. The angle is measured from +x for ``"y"`` (towards -z), from +y
        for ``"x"`` and from +x for ``"z"``.

    Returns
    -------
    trimesh.Trimesh
        Watertight, outward oriented.

    Raises
    ------
    ValueError
        Fewer than 3 sections, negative radii, or a profile of fewer than 3 points.
    """
    p = np.asarray(profile, dtype=np.float64)
    if sections < 3:
        raise ValueError(f"sections must be >= 3, got {sections}")
    if p.ndim != 2 or p.shape[1] != 2 or len(p) < 3:
        raise ValueError(f"profile must be (K >= 3, 2), got shape {p.shape}")
    if np.any(p[:, 0] < 0):
        raise ValueError("profile radii must be >= 0")
    on_axis = p[:, 0] == 0.0
    closed_by_axis = bool(on_axis[0] and on_axis[-1])
    if np.any(on_axis[1:-1]) or (on_axis[0] != on_axis[-1]):
        raise ValueError("only the first and last profile points may lie on the axis")
    ang = 2.0 * np.pi * np.arange(sections) / sections
    cos, sin = np.cos(ang), np.sin(ang)
    verts: list[np.ndarray] = []
    index: list[np.ndarray] = []  # per profile point: (sections,) vertex ids
    n = 0
    for r, h in p:
        if r == 0.0:
            verts.append(np.array([[0.0, h, 0.0]]))
            index.append(np.full(sections, n))
            n += 1
        else:
            verts.append(np.stack([r * cos, np.full(sections, h), -r * sin], axis=1))
            index.append(n + np.arange(sections))
            n += sections
    faces: list[list[int]] = []
    k = len(p)
    segs = range(k - 1) if closed_by_axis else range(k)
    for i in segs:
        a, b = index[i], index[(i + 1) % k]
        for j in range(sections):
            j1 = (j + 1) % sections
            if a[j] == a[j1]:  # pole at a
                faces.append([a[j], b[j], b[j1]])
            elif b[j] == b[j1]:  # pole at b
                faces.append([a[j], b[j], a[j1]])
            else:
                faces.append([a[j], b[j], b[j1]])
                faces.append([a[j], b[j1], a[j1]])
    v = np.concatenate(verts, axis=0)
    # local frame: revolution about +y; map to the requested axis
    if axis == "y":
        v = v
    elif axis == "x":
        v = v[:, [1, 0, 2]] * np.array([1.0, 1.0, -1.0])
    elif axis == "z":
        v = v[:, [0, 2, 1]] * np.array([1.0, -1.0, 1.0])
    else:
        raise ValueError(f"axis must be 'x', 'y' or 'z', got {axis!r}")
    v = v + np.asarray(center, dtype=np.float64)
    return _mesh(v, np.asarray(faces, dtype=np.int64))


def cylinder(
    radius: float,
    h0: float,
    h1: float,
    center: Sequence[float] = (0.0, 0.0, 0.0),
    axis: str = "y",
    sections: int = SECTIONS,
) -> trimesh.Trimesh:
    """A solid cylinder along a coordinate axis from height ``h0`` to ``h1``.

    Parameters
    ----------
    radius : float
        Metres, > 0.
    h0, h1 : float
        Start and end heights along ``axis``, measured from ``center`` (``h0 < h1``).
    center : (3,) float
        A point of the cylinder axis (object frame).
    axis : {"x", "y", "z"}
    sections : int

    Returns
    -------
    trimesh.Trimesh

    Raises
    ------
    ValueError
        Non-positive radius or ``h1 <= h0``.
    """
    if radius <= 0 or h1 <= h0:
        raise ValueError(f"cylinder needs radius > 0 and h1 > h0, got {radius}, {h0}, {h1}")
    return lathe([(0, h0), (radius, h0), (radius, h1), (0, h1)], sections, center, axis)


def _frames(path: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Tangents and parallel-transported normals/binormals along a polyline (M, 3)."""
    d = np.gradient(path, axis=0)
    t = d / np.linalg.norm(d, axis=1, keepdims=True)
    ref = np.array([0.0, 0.0, 1.0]) if abs(t[0, 2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    n0 = np.cross(t[0], ref)
    n0 /= np.linalg.norm(n0)
    normals = [n0]
    for i in range(1, len(path)):
        n = normals[-1] - np.dot(normals[-1], t[i]) * t[i]
        normals.append(n / np.linalg.norm(n))
    nrm = np.array(normals)
    return t, nrm, np.cross(t, nrm)


def tube(path: Sequence[Sequence[float]], radius: float, sections: int = 16) -> trimesh.Trimesh:
    """A circular tube swept along an open polyline, capped at both ends.

    Parameters
    ----------
    path : (M, 3) float
        Centre line (object frame, metres), M >= 2, smooth enough that the tube does not
        intersect itself (curvature radius > ``radius``).
    radius : float
        Tube radius, metres.
    sections : int
        Points per ring.

    Returns
    -------
    trimesh.Trimesh
        Watertight, outward oriented; the end caps are flat discs perpendicular to the path.

    Raises
    ------
    ValueError
        Fewer than 2 path points or repeated consecutive points.
    """
    P = np.asarray(path, dtype=np.float64)
    if P.ndim != 2 or P.shape[1] != 3 or len(P) < 2:
        raise ValueError(f"path must be (M >= 2, 3), got {P.shape}")
    if np.any(np.linalg.norm(np.diff(P, axis=0), axis=1) == 0):
        raise ValueError("path has repeated consecutive points")
    _, nrm, bin_ = _frames(P)
    ang = 2.0 * np.pi * np.arange(sections) / sections
    rings = (
        P[:, None, :]
        + radius * np.cos(ang)[None, :, None] * nrm[:, None, :]
        + radius * np.sin(ang)[None, :, None] * bin_[:, None, :]
    )
    m = len(P)
    v = np.concatenate([rings.reshape(-1, 3), P[[0, -1]]], axis=0)
    c0, c1 = m * sections, m * sections + 1
    faces = []
    for i in range(m - 1):
        for j in range(sections):
            j1 = (j + 1) % sections
            a, b = i * sections + j, i * sections + j1
            c, d = (i + 1) * sections + j, (i + 1) * sections + j1
            faces += [[a, c, d], [a, d, b]]
    last = (m - 1) * sections
    for j in range(sections):
        j1 = (j + 1) % sections
        faces.append([c0, j, j1])
        faces.append([c1, last + j1, last + j])
    return _mesh(v, np.asarray(faces, dtype=np.int64))


def rotation(axis: Sequence[float], angle_deg: float, point: Sequence[float]) -> np.ndarray:
    """4x4 homogeneous rotation by ``angle_deg`` (right-hand rule) about a line.

    Parameters
    ----------
    axis : (3,) float
        Direction of the line (need not be unit length).
    angle_deg : float
        Degrees.
    point : (3,) float
        A point of the line.

    Returns
    -------
    (4, 4) float64
    """
    return trimesh.transformations.rotation_matrix(
        np.deg2rad(angle_deg),
        np.asarray(axis, dtype=np.float64),
        np.asarray(point, dtype=np.float64),
    )
