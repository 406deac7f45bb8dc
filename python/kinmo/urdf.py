"""URDF export of PartNet-Mobility objects (real, generated or predicted motions).

One URDF link per kinematic link (``mobility_v2.json`` entry), whose visual and collision
geometry are the OBJ meshes of the link's PartNet leaves, referenced by relative paths
(``textured_objs/original-3.obj``) so the URDF sits in the object folder next to its meshes.
The output is what Liu et al. 2023 predict (mobile parts, motion type, axis; Sec. 3) in the
format simulators load, and what :mod:`kinmo.render` loads in PyBullet to render partial scans
(ANCSH, Li et al. 2020).

Frames and conventions
----------------------
- **World frame = mesh frame.** The URDF root link ``base`` is the object's mesh frame: y-up
  (+y vertical), mesh units (PartNet-Mobility objects are about unit size). The root
  kinematic link is attached to ``base`` by a ``fixed`` joint at the identity. Simulators that
  are z-up can stand the object upright by giving the base the orientation quaternion
  ``(x, y, z, w) = (0.7071068, 0, 0, 0.7071068)`` (+90 deg about +x maps +y to +z); SAPIEN's own
  ``mobility.urdf`` files bake ``rpy="1.5708 0 -1.5708"`` into their base joint instead.
- **Link frames sit on their axes**, as in PartNet-Mobility's own URDFs: at the rest pose
  (every joint value 0, the meshes exactly as stored) the frame of link ``k`` is the mesh
  frame translated to ``a_k``, the ``axis.origin`` of its joint (fixed links inherit their
  parent's ``a``); the joint ``<origin>`` is ``a_k - a_parent`` and each mesh ``<origin>`` is
  ``-a_k``. All frames are axis-aligned with the mesh frame at rest, so each ``<axis>`` is the
  unit ``axis.direction`` of ``mobility_v2.json`` as written.
- **Sign.** A positive joint value rotates the link about ``+direction`` (right-hand rule,
  radians) or translates it along ``+direction`` (mesh units), exactly the motion
  ``mobility_v2.json`` describes; the value 0 is the rest pose.
- **Joint types.** ``hinge`` -> ``revolute`` with limits ``[min(a, b), max(a, b)]`` degrees ->
  radians, shifted by whole turns so that the interval contains the rest pose 0 when it can
  (annotations such as ``[-495, -225]`` become ``[-135, 135]``); ``continuous`` when
  ``noLimit`` or the range spans a full turn. ``slider`` -> ``prismatic`` with limits
  ``[min(a, b), max(a, b)]`` mesh units, mapped directly (the rest pose 0 may lie outside, e.g.
  dishwasher racks annotated ``[0.076, 0.66]``). A slider that ``rotates`` (cylindrical joint)
  becomes a ``prismatic`` joint to a geometry-less helper link ``link_<id>_helper``, then a
  ``revolute`` joint about the same axis (limits ``[0, rotationLimit]`` degrees -> radians,
  ``continuous`` when ``noRotationLimit``). ``free`` (a non-root link), ``heavy``, ``static``
  and ``junk`` -> ``fixed``.
- **Names.** Links ``base``, ``link_<id>``, ``link_<id>_helper``; joints ``joint_<id>`` (the
  joint that attaches ``link_<id>``, the prismatic one of a cylindrical joint, which attaches
  the helper) and ``joint_<id>_rotation`` (the revolute one of a cylindrical joint).
- **Annotation.** Each ``joint_<id>`` carries a ``<mobility_v2>`` element (ignored by URDF
  loaders) with what URDF cannot express: the link's name and joint label (``free``,
  ``heavy``, ``static``, ``junk`` all become ``fixed``), the limits as annotated (order and
  turn, ``noLimit``) and the rotation limit of a cylindrical joint, so that
  :func:`kinmo.export.urdf.read_urdf` gives ``mobility_v2.json`` back losslessly.
- **Collision.** By default each visual mesh is also a collision mesh; ``collision=`` gives
  other files per link instead (e.g. convex pieces, :mod:`kinmo.export.urdf`).
- Inertials are placeholders (unit mass, unit inertia at the link frame, PyBullet's own
  default, written out so loaders do not warn): the URDF describes kinematics and geometry,
  not mass properties. Visual elements are named ``<part name>-<part id>``.
"""

from __future__ import annotations

import math
import os
import xml.etree.ElementTree as ET
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path, PurePosixPath

import numpy as np

from kinmo.data.names import clean_xml_tree
from kinmo.data.model import JointType, Link, Shape
from kinmo.errors import KinmoDataError
from kinmo.io import write_text

__all__ = [
    "BASE_LINK",
    "UNBOUNDED_SLIDER",
    "UrdfJoint",
    "hinge_limits_rad",
    "link_frame_origins",
    "urdf_joints",
    "urdf_string",
    "write_urdf",
]

#: Name of the URDF root link (the world-fixed mesh frame).
BASE_LINK = "base"
#: ``effort`` and ``velocity`` written on every ``<limit>`` (required by the URDF spec; kinmo
#: describes kinematics only).
_EFFORT = 100.0
_VELOCITY = 10.0
#: Unbounded slider (``noLimit``): URDF prismatic joints need limits; use +-this many mesh units.
UNBOUNDED_SLIDER = 1000.0


@dataclass(frozen=True)
class UrdfJoint:
    """One URDF joint as written by :func:`urdf_string`.

    Attributes
    ----------
    name : str
        ``joint_<id>`` or ``joint_<id>_rotation``.
    type : str
        ``"revolute"``, ``"continuous"``, ``"prismatic"`` or ``"fixed"``.
    parent, child : str
        URDF link names.
    link_id : int
        The kinmo link this joint moves (``child`` is ``link_<link_id>`` or its helper).
    origin : (3,) float64
        Joint origin in the parent link frame (mesh units); frames carry no rotation.
    axis : (3,) float64 or None
        Unit axis in the joint frame (= the mesh frame at rest); ``None`` for fixed joints.
    lower, upper : float or None
        Limits (radians for revolute, mesh units for prismatic); ``None`` for continuous and
        fixed joints.
    """

    name: str
    type: str
    parent: str
    child: str
    link_id: int
    origin: np.ndarray
    axis: np.ndarray | None = None
    lower: float | None = None
    upper: float | None = None

    @property
    def is_moving(self) -> bool:
        """True for revolute, continuous and prismatic joints."""
        return self.type != "fixed"


def _link_name(link_id: int) -> str:
    return f"link_{link_id}"


def _ordered(links: Sequence[Link], where: str | Path) -> list[Link]:
    """Links with parents before children; raises on unknown parents, duplicates, cycles."""
    by_id: dict[int, Link] = {}
    for link in links:
        if link.id in by_id:
            raise KinmoDataError(where, f"duplicate link id {link.id}")
        by_id[link.id] = link
    for link in links:
        if link.parent != -1 and link.parent not in by_id:
            raise KinmoDataError(where, f"link {link.id}: parent {link.parent} is not a link")
    children: dict[int, list[int]] = {}
    for link in links:
        children.setdefault(link.parent, []).append(link.id)
    out: list[Link] = []
    stack = sorted(children.get(-1, []), reverse=True)
    while stack:
        lid = stack.pop()
        out.append(by_id[lid])
        stack.extend(sorted(children.get(lid, []), reverse=True))
    if len(out) != len(by_id):
        bad = sorted(set(by_id) - {l.id for l in out})
        raise KinmoDataError(where, f"links {bad} are not connected to a root (parent -1): cycle")
    return out


def _unit_axis(link: Link, where: str | Path) -> tuple[np.ndarray, np.ndarray]:
    j = link.joint
    if j.origin is None or j.direction is None:
        raise KinmoDataError(where, f"link {link.id}: {j.type.value} joint without an axis")
    o = np.asarray(j.origin, dtype=np.float64).reshape(-1)
    d = np.asarray(j.direction, dtype=np.float64).reshape(-1)
    if o.shape != (3,) or d.shape != (3,) or not (np.isfinite(o).all() and np.isfinite(d).all()):
        raise KinmoDataError(
            where, f"link {link.id}: axis origin/direction must be 3 finite numbers")
    n = float(np.linalg.norm(d))
    if n < 1e-12:
        raise KinmoDataError(where, f"link {link.id}: zero axis direction")
    return o, d / n


def _is_moving(link: Link) -> bool:
    return link.parent != -1 and link.joint.type in (JointType.HINGE, JointType.SLIDER)


def hinge_limits_rad(a_deg: float, b_deg: float) -> tuple[float, float] | None:
    """URDF revolute limits (radians) of a hinge annotated ``[a, b]`` degrees.

    The interval ``[min(a, b), max(a, b)]`` is shifted by the whole number of turns that brings
    it closest to the rest pose 0 (containing it when possible). Returns ``None`` (continuous
    joint) when it spans a full turn or more.
    """
    lo, hi = sorted((float(a_deg), float(b_deg)))
    if hi - lo >= 360.0 - 1e-9:
        return None

    def distance(k: int) -> float:  # from 0 to [lo + 360k, hi + 360k]
        return max(lo + 360.0 * k, 0.0) - min(hi + 360.0 * k, 0.0)

    turns = range(math.floor(-hi / 360.0) - 1, math.ceil(-lo / 360.0) + 2)
    k = min(turns, key=lambda k: (distance(k), abs(k)))
    return math.radians(lo + 360.0 * k), math.radians(hi + 360.0 * k)


def link_frame_origins(
    links: Sequence[Link], where: str | Path = "<links>"
) -> dict[int, np.ndarray]:
    """Rest-pose position ``a_k`` of every link frame in the mesh frame (see module docs).

    Parameters
    ----------
    links : sequence of Link
    where : str or Path
        Named in errors.

    Returns
    -------
    dict of int to (3,) float64
        Link id -> frame origin (mesh units). Moving links: their axis origin; fixed links and
        roots: their parent's (roots: 0). The frames carry no rotation at rest.
    """
    out: dict[int, np.ndarray] = {}
    for link in _ordered(links, where):
        if _is_moving(link):
            out[link.id] = _unit_axis(link, where)[0]
        elif link.parent == -1:
            out[link.id] = np.zeros(3)
        else:
            out[link.id] = out[link.parent].copy()
    return out


def urdf_joints(links: Sequence[Link], where: str | Path = "<links>") -> list[UrdfJoint]:
    """The URDF joints that :func:`urdf_string` writes for ``links``, parents first.

    Parameters
    ----------
    links : sequence of Link
        PartNet-Mobility links (axes in the mesh frame, hinge limits in degrees).
    where : str or Path
        Named in errors (the object folder).

    Returns
    -------
    list of UrdfJoint
        One per link (two for a cylindrical joint), conventions in the module docs.

    Raises
    ------
    KinmoDataError
        Duplicate ids, unknown parents, cycles, or a hinge/slider without a valid axis.
    """
    ordered = _ordered(links, where)
    frames = link_frame_origins(ordered, where)
    out: list[UrdfJoint] = []
    for link in ordered:
        child = _link_name(link.id)
        parent = BASE_LINK if link.parent == -1 else _link_name(link.parent)
        origin = frames[link.id] - (np.zeros(3) if link.parent == -1 else frames[link.parent])
        name = f"joint_{link.id}"
        if not _is_moving(link):
            out.append(UrdfJoint(name, "fixed", parent, child, link.id, origin))
            continue
        _, axis = _unit_axis(link, where)
        j = link.joint
        if j.type is JointType.HINGE:
            lim = None if j.limit is None else hinge_limits_rad(*j.limit)
            if lim is None:
                out.append(UrdfJoint(name, "continuous", parent, child, link.id, origin, axis))
            else:
                out.append(UrdfJoint(name, "revolute", parent, child, link.id, origin, axis, *lim))
            continue
        if j.limit is None:
            lo, hi = -UNBOUNDED_SLIDER, UNBOUNDED_SLIDER
        else:
            lo, hi = sorted(float(v) for v in j.limit)
        if not j.rotates:
            out.append(UrdfJoint(name, "prismatic", parent, child, link.id, origin, axis, lo, hi))
            continue
        helper = f"{child}_helper"
        out.append(UrdfJoint(name, "prismatic", parent, helper, link.id, origin, axis, lo, hi))
        rname = f"joint_{link.id}_rotation"
        r = j.rotation_limit
        if r is None or abs(float(r)) >= 360.0 - 1e-9:
            out.append(UrdfJoint(rname, "continuous", helper, child, link.id, np.zeros(3), axis))
        else:
            rlo, rhi = sorted((0.0, math.radians(float(r))))
            out.append(UrdfJoint(rname, "revolute", helper, child, link.id, np.zeros(3), axis,
                                 rlo, rhi))
    return out


def _xyz(v: np.ndarray) -> str:
    return " ".join(repr(float(c) + 0.0) for c in v)


def _inertial(link: ET.Element) -> None:
    el = ET.SubElement(link, "inertial")
    ET.SubElement(el, "origin", xyz="0 0 0", rpy="0 0 0")
    ET.SubElement(el, "mass", value="1.0")
    ET.SubElement(el, "inertia", ixx="1.0", ixy="0", ixz="0", iyy="1.0", iyz="0", izz="1.0")


def _mesh_prefix(shape: Shape, mesh_root: str | os.PathLike[str] | None) -> PurePosixPath:
    if mesh_root is None:
        try:
            rel = Path(shape.mesh_dir).relative_to(Path(shape.path))
        except ValueError:
            rel = Path(os.path.relpath(shape.mesh_dir, shape.path))
        return PurePosixPath(rel.as_posix())
    return PurePosixPath(Path(mesh_root).as_posix())


def _annotation(link: Link) -> dict[str, str]:
    """The ``<mobility_v2>`` attributes of a link (module docs: Annotation)."""
    j = link.joint
    att = {"joint": j.type.value, "name": link.name}
    if j.is_moving:
        att["limit"] = "none" if j.limit is None else " ".join(repr(float(v)) for v in j.limit)
        if j.type is JointType.SLIDER and j.rotates:
            r = j.rotation_limit
            att["rotation_limit"] = "none" if r is None else repr(float(r))
    return att


def urdf_string(
    shape: Shape,
    links: Sequence[Link] | None = None,
    mesh_root: str | os.PathLike[str] | None = None,
    *,
    name: str | None = None,
    collision: Mapping[int, Sequence[str]] | None = None,
) -> str:
    """The URDF of ``shape`` moving as ``links`` describe.

    Parameters
    ----------
    shape : Shape
        The object: part hierarchy (which leaf meshes form each link) and mesh folder.
    links : sequence of Link, optional
        Kinematic links (real, generated or predicted); default ``shape.links``.
    mesh_root : str or PathLike, optional
        Prefix of the mesh file names in the URDF (relative to the URDF's folder, or absolute).
        Default: ``shape.mesh_dir`` relative to ``shape.path`` (``textured_objs``), for a URDF
        written in the object folder.
    name : str, optional
        ``<robot name>``; default ``kinmo_<shape.id>``.
    collision : mapping of int to sequence of str, optional
        Link id -> collision mesh file names (as written, in the mesh frame) replacing the
        visual meshes as collision geometry of that link.

    Returns
    -------
    str
        The URDF XML (UTF-8 text). Frames, signs and joint types as in the module docs: the
        world frame is the mesh frame (y-up, mesh units), positive joint values rotate about /
        translate along ``+direction``, 0 is the rest pose.

    Raises
    ------
    KinmoDataError
        ``shape`` has no links and none are given, the links are inconsistent (duplicate ids,
        unknown parents, cycles, hinge/slider without a valid axis) or name a part that is not
        in the hierarchy (message names ``shape.path``).
    """
    where = shape.path
    if links is None:
        links = shape.links
    if not links:
        raise KinmoDataError(where, "no kinematic links to export (a PartNet shape needs links, "
                                    "e.g. predicted motions)")
    joints = urdf_joints(links, where)
    frames = link_frame_origins(links, where)
    prefix = _mesh_prefix(shape, mesh_root)
    by_id = {l.id: l for l in links}

    robot = ET.Element("robot", name=name or f"kinmo_{shape.id}")
    _inertial(ET.SubElement(robot, "link", name=BASE_LINK))
    for j in joints:
        child = ET.SubElement(robot, "link", name=j.child)
        _inertial(child)
        if j.child == _link_name(j.link_id):
            link = by_id[j.link_id]
            off = _xyz(-frames[link.id])
            for pid in link.parts:
                node = shape.hierarchy.nodes.get(pid)
                if node is None:
                    raise KinmoDataError(where, f"link {link.id}: part {pid} is not a node of "
                                                "the part hierarchy")
                for mesh in shape.hierarchy.mesh_names(pid):
                    fname = str(prefix / f"{mesh}.obj")
                    tags = ("visual",) if collision is not None else ("visual", "collision")
                    for tag in tags:
                        el = ET.SubElement(child, tag)
                        if tag == "visual":
                            el.set("name", f"{node.name}-{pid}")
                        ET.SubElement(el, "origin", xyz=off)
                        geo = ET.SubElement(el, "geometry")
                        ET.SubElement(geo, "mesh", filename=fname)
            for fname in (collision or {}).get(link.id, ()):
                el = ET.SubElement(child, "collision")
                ET.SubElement(el, "origin", xyz=off)
                ET.SubElement(ET.SubElement(el, "geometry"), "mesh", filename=fname)
        je = ET.SubElement(robot, "joint", name=j.name, type=j.type)
        ET.SubElement(je, "parent", link=j.parent)
        ET.SubElement(je, "child", link=j.child)
        ET.SubElement(je, "origin", xyz=_xyz(j.origin), rpy="0 0 0")
        if j.axis is not None:
            ET.SubElement(je, "axis", xyz=_xyz(j.axis))
        if j.type in ("revolute", "prismatic"):
            ET.SubElement(je, "limit", lower=repr(float(j.lower)), upper=repr(float(j.upper)),
                          effort=repr(_EFFORT), velocity=repr(_VELOCITY))
        if j.name == f"joint_{j.link_id}":
            ET.SubElement(je, "mobility_v2", _annotation(by_id[j.link_id]))
    clean_xml_tree(robot)  # names from input files: no control characters (issue 21)
    ET.indent(robot, space="  ")
    return '<?xml version="1.0"?>\n' + ET.tostring(robot, encoding="unicode") + "\n"


def write_urdf(
    shape: Shape,
    path: str | os.PathLike[str],
    links: Sequence[Link] | None = None,
    *,
    name: str | None = None,
    collision: Mapping[int, Sequence[str]] | None = None,
) -> Path:
    """Write the URDF of ``shape`` to ``path`` atomically, meshes referenced relative to it.

    Parameters
    ----------
    shape : Shape
    path : str or PathLike
        Output ``.urdf`` file. Mesh paths are written relative to its folder (e.g.
        ``textured_objs/original-3.obj`` when it is in the object folder), so the URDF loads
        from where it is written.
    links : sequence of Link, optional
        Default ``shape.links``.
    name : str, optional
        ``<robot name>``.
    collision : mapping of int to sequence of str, optional
        As :func:`urdf_string` (file names relative to ``path``'s folder).

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    KinmoDataError
        As :func:`urdf_string`.
    """
    path = Path(path)
    rel = os.path.relpath(Path(shape.mesh_dir).resolve(), path.resolve().parent)
    write_text(path, urdf_string(shape, links, mesh_root=rel, name=name, collision=collision))
    return path
