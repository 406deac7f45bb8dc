"""Forward kinematics of PartNet-Mobility links and the per-link meshes every exporter writes.

The motion ``mobility_v2.json`` describes (Liu et al. 2023 predict exactly this: mobile part,
joint type, axis; Sec. 3), as rigid transforms of the mesh frame, so that every exporter
(:mod:`kinmo.export`) and the viewer (:mod:`kinmo.view`) move parts identically and the tests
can check each simulator's poses against one reference.

Conventions (those of :mod:`kinmo.urdf`):

- Everything is in the mesh frame (y-up, mesh units). At the rest pose (every joint value 0)
  the meshes are exactly as stored.
- A hinge's value ``q`` (radians) rotates its link about the line through ``axis.origin``
  along ``axis.direction`` (right-hand rule); a slider's value (mesh units) translates it along
  ``+direction``; a rotating slider (cylindrical joint) has two values, translation then
  rotation about the same axis. ``free`` (the root), ``heavy``, ``static`` and ``junk`` links
  do not move relative to their parent.
- A child's motion is expressed in the rest frame and then carried by its parent:
  ``T_k(q) = T_parent(q) @ M_k(q_k)``.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from kinmo.data.model import JointType, Link, Shape
from kinmo.errors import KinmoDataError
from kinmo.render.ancsh_gt import link_meshes as leaf_meshes

__all__ = [
    "SLAB_THICKNESS",
    "JointValue",
    "LinkMesh",
    "axis_rotation",
    "joint_transform",
    "link_meshes",
    "link_poses",
    "moving_links",
    "simulator_safe",
    "write_obj",
]

#: A joint value: a float (hinge: radians, slider: mesh units) or, for a rotating slider, a
#: ``(translation, rotation)`` pair.
JointValue = float | tuple[float, float]


def axis_rotation(direction: np.ndarray, angle: float) -> np.ndarray:
    """Rotation matrix about a unit ``direction`` by ``angle`` radians (Rodrigues).

    Returns
    -------
    (3, 3) float64
    """
    d = np.asarray(direction, dtype=np.float64)
    d = d / np.linalg.norm(d)
    k = np.array([[0, -d[2], d[1]], [d[2], 0, -d[0]], [-d[1], d[0], 0]])
    return np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * (k @ k)


def moving_links(links: Sequence[Link]) -> list[Link]:
    """The links whose joint moves (hinges and sliders with a parent), in id order."""
    return sorted((l for l in links if l.parent != -1 and l.joint.is_moving), key=lambda l: l.id)


def joint_transform(link: Link, value: JointValue) -> np.ndarray:
    """The rigid motion ``M_k`` of one joint at ``value``, in the rest mesh frame.

    Parameters
    ----------
    link : Link
    value : float or (float, float)
        See :data:`JointValue`; ignored for links that do not move.

    Returns
    -------
    (4, 4) float64
        Homogeneous transform of mesh-frame points.
    """
    T = np.eye(4)
    if link.parent == -1 or not link.joint.is_moving:
        return T
    j = link.joint
    o = np.asarray(j.origin, dtype=np.float64)
    d = np.asarray(j.direction, dtype=np.float64)
    d = d / np.linalg.norm(d)
    if isinstance(value, tuple | list):
        t, r = float(value[0]), float(value[1])
    elif j.type is JointType.SLIDER:
        t, r = float(value), 0.0
    else:
        t, r = 0.0, float(value)
    if j.type is JointType.HINGE:
        t = 0.0
    R = axis_rotation(d, r)
    T[:3, :3] = R
    T[:3, 3] = o - R @ o + t * d
    return T


def link_poses(links: Sequence[Link], values: Mapping[int, JointValue] | None = None
               ) -> dict[int, np.ndarray]:
    """World transform of every link at the given joint values (rest pose: identity).

    Parameters
    ----------
    links : sequence of Link
    values : mapping of int to JointValue, optional
        Link id -> joint value; missing links stay at 0.

    Returns
    -------
    dict of int to (4, 4) float64
        ``T_k`` mapping rest mesh-frame points of link ``k`` to their moved positions.

    Raises
    ------
    KinmoDataError
        A parent that is not a link, or a cycle.
    """
    values = values or {}
    by_id = {l.id: l for l in links}
    out: dict[int, np.ndarray] = {}

    def pose(lid: int, seen: tuple[int, ...]) -> np.ndarray:
        if lid in out:
            return out[lid]
        if lid in seen:
            raise KinmoDataError("<links>", f"cycle through link {lid}")
        link = by_id[lid]
        M = joint_transform(link, values.get(lid, 0.0))
        if link.parent == -1:
            T = M
        elif link.parent not in by_id:
            raise KinmoDataError("<links>", f"link {lid}: parent {link.parent} is not a link")
        else:
            T = pose(link.parent, seen + (lid,)) @ M
        out[lid] = T
        return T

    for lid in by_id:
        pose(lid, ())
    return out


@dataclass(frozen=True)
class LinkMesh:
    """The merged triangle mesh of one link, in the rest mesh frame.

    Attributes
    ----------
    link_id : int
    vertices : (V, 3) float64
        Mesh frame (y-up), mesh units.
    faces : (F, 3) int64
    leaf_faces : tuple of int
        Faces of each leaf mesh (``textured_objs/*.obj``), in order: ``faces`` is their
        concatenation. Empty when the link is one piece (a flat link replaced by its slab).
    """

    link_id: int
    vertices: np.ndarray
    faces: np.ndarray
    leaf_faces: tuple[int, ...] = ()


def link_meshes(shape: Shape, links: Sequence[Link] | None = None,
                named: Mapping[str, tuple[np.ndarray, np.ndarray]] | None = None) -> dict[int, LinkMesh]:
    """Every link's leaf meshes (``textured_objs/*.obj``) merged into one mesh per link.

    The meshes are read by :func:`kinmo.render.ancsh_gt.link_meshes` (parallel Rust loading).

    Parameters
    ----------
    shape : Shape
    links : sequence of Link, optional
        Default ``shape.links``.
    named : mapping of str to (vertices, faces), optional
        The shape's meshes by name, already read (:func:`kinmo.data.build.load_named_meshes`);
        read here when not given.

    Returns
    -------
    dict of int to LinkMesh
        One entry per link (an empty mesh for a link without geometry).

    Raises
    ------
    KinmoDataError
        A link names a part missing from the hierarchy, or a mesh file cannot be read.
    """

    links = list(shape.links or [] if links is None else links)
    for link in links:
        bad = [pid for pid in link.parts if pid not in shape.hierarchy.nodes]
        if bad:
            raise KinmoDataError(shape.path, f"link {link.id}: part {bad[0]} is not a node of "
                                             "the part hierarchy")
    out: dict[int, LinkMesh] = {}
    if named is None:
        by_link = leaf_meshes(shape, links)
    else:
        by_link = {l.id: [named[m] for pid in l.parts for m in shape.hierarchy.mesh_names(pid)]
                   for l in links}
    for lid, meshes in by_link.items():
        vs, fs, n = [], [], 0
        for v, f in meshes:
            vs.append(v)
            fs.append(f + n)
            n += len(v)
        v = np.concatenate(vs) if vs else np.zeros((0, 3))
        f = np.concatenate(fs).astype(np.int64) if fs else np.zeros((0, 3), dtype=np.int64)
        leaves = tuple(len(x) for x in fs)
        if len(f):
            v2, f2 = simulator_safe(v, f, f"{shape.path}: link {lid}")
            if f2 is not f:  # replaced by a slab: one piece
                v, f, leaves = v2, f2, ()
        out[lid] = LinkMesh(lid, v, f, leaves)
    return out


#: Thickness of the slab substituted for a flat part, relative to its largest extent.
SLAB_THICKNESS = 1e-3

#: A point set is flat when the smallest singular value of its centred coordinates is at
#: most this fraction of the largest (:func:`simulator_safe`; the ``hull`` collision pieces).
FLAT_RELATIVE = 1e-9


def simulator_safe(vertices: np.ndarray, faces: np.ndarray, where: str) -> tuple[np.ndarray, np.ndarray]:
    """A link mesh every simulator loads (issue 21, finding 9).

    MuJoCo refuses meshes with fewer than 4 vertices or only coplanar ones, and convex
    decomposition of such a mesh is empty. The rule, the same as ``prepare`` / ``predict``
    apply to parts (a part without surface cannot be sampled):

    - zero surface area (a point, a segment, degenerate triangles): refused;
    - fewer than 4 distinct vertices, or all of them on one plane (rank < 3 of the centred
      vertices, relative tolerance :data:`FLAT_RELATIVE`): replaced by a thin box (slab) on
      the part's principal axes, as large as the part in its plane and
      :data:`SLAB_THICKNESS` times its largest extent thick;
    - anything else: unchanged.

    Parameters
    ----------
    vertices : (V, 3) float64
    faces : (F, 3) int64
    where : str
        Named in the error.

    Returns
    -------
    vertices : (V', 3) float64
    faces : (F', 3) int64

    Raises
    ------
    KinmoDataError
        Zero surface area.
    """
    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(faces, dtype=np.int64)
    tri = v[f]
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1).sum()
    extent = float(np.ptp(v, axis=0).max()) if len(v) else 0.0
    if not area > 1e-12 * max(extent, 1e-300) ** 2:
        raise KinmoDataError(where, "zero surface area (a point, a segment or degenerate "
                                    "triangles): refused, as prepare and predict refuse such parts")
    used = v[np.unique(f)]
    centre = used.mean(0)
    _, sv, axes = np.linalg.svd(used - centre, full_matrices=False)
    if len(used) >= 4 and sv[-1] > FLAT_RELATIVE * sv[0]:
        return v, f
    local = (used - centre) @ axes.T
    lo, hi = local.min(0), local.max(0)
    half = SLAB_THICKNESS * max(extent, 1e-9) / 2
    lo, hi = np.minimum(lo, -half), np.maximum(hi, half)
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1])
                        for z in (lo[2], hi[2])])  # index = 4x + 2y + z
    box_v = corners @ axes + centre
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    box_f = np.array([t for a, b, c, d in quads for t in ((a, b, c), (a, c, d))], dtype=np.int64)
    if np.linalg.det(axes) < 0:  # keep the faces outward
        box_f = box_f[:, ::-1]
    return box_v, box_f


def write_obj(path: str | Path, vertices: np.ndarray, faces: np.ndarray) -> None:
    """Write a triangle mesh as a plain Wavefront OBJ (``v`` and ``f`` lines, full precision).

    Parameters
    ----------
    path : str or Path
        Written directly (callers that need atomicity pass a temporary path).
    vertices : (V, 3) float64
    faces : (F, 3) int64
        Zero-based indices (written one-based).
    """
    with open(path, "w") as fh:
        fh.write("".join(f"v {x!r} {y!r} {z!r}\n" for x, y, z in np.asarray(vertices).tolist()))
        fh.write("".join(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in np.asarray(faces).tolist()))
