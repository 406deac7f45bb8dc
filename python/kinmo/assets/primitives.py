"""Closed triangle meshes of the primitive shapes of URDF and MJCF geometry (trimesh.creation).

Every shape is centred on its local origin; cylinders and capsules lie along local +z, as
in URDF and MuJoCo. Sizes are in the asset's units and must be finite and positive.

==============  =========================================  ==================================
kind            sizes                                      URDF / MJCF
==============  =========================================  ==================================
``box``         three full edge lengths (x, y, z)          ``<box size>``; MJCF: 2 x half-sizes
``cylinder``    radius, length                             ``radius``, ``length``; MJCF:
                                                           radius, 2 x half-length
``capsule``     radius, length of the straight part        as the cylinder (ends add a radius)
``sphere``      radius                                     ``radius``
``ellipsoid``   three radii                                MJCF only
==============  =========================================  ==================================
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import trimesh

__all__ = ["SIZES", "primitive"]

#: Number of sizes each kind takes.
SIZES: dict[str, int] = {"box": 3, "cylinder": 2, "capsule": 2, "sphere": 1, "ellipsoid": 3}

#: Segments around cylinders and capsules; icosphere subdivisions of spheres and ellipsoids.
SECTIONS = 32
SUBDIVISIONS = 2


def primitive(kind: str, sizes: Sequence[float]) -> tuple[np.ndarray, np.ndarray]:
    """The mesh of a primitive shape (module table).

    Parameters
    ----------
    kind : str
        ``box``, ``cylinder``, ``capsule``, ``sphere`` or ``ellipsoid``.
    sizes : sequence of float
        ``SIZES[kind]`` finite positive numbers, asset units.

    Returns
    -------
    vertices : (V, 3) float64
        In the shape's local frame.
    faces : (F, 3) int64

    Raises
    ------
    ValueError
        An unknown kind, or sizes of the wrong count or not finite and positive (callers
        name the file and the element).
    """
    s = np.asarray(sizes, dtype=np.float64)
    if kind not in SIZES or s.shape != (SIZES[kind],) or not np.all(np.isfinite(s) & (s > 0)):
        raise ValueError(f"takes {SIZES.get(kind, '?')} finite positive size(s), not {s.tolist()}")
    if kind == "box":
        m = trimesh.creation.box(extents=s)
    elif kind == "cylinder":
        m = trimesh.creation.cylinder(radius=s[0], height=s[1], sections=SECTIONS)
    elif kind == "capsule":
        m = trimesh.creation.capsule(height=s[1], radius=s[0], count=[SECTIONS, SECTIONS])
    else:
        m = trimesh.creation.icosphere(subdivisions=SUBDIVISIONS)
        m.vertices = m.vertices * (s if kind == "ellipsoid" else s[0])
    return np.asarray(m.vertices, dtype=np.float64), np.asarray(m.faces, dtype=np.int64)
