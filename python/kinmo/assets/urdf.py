"""URDF input: one part per link with geometry, placed at the rest pose (all joints at 0).

A link's geometry is its ``<visual>`` elements, or its ``<collision>`` elements when it has
no visual; each ``<geometry>`` is one of:

- ``<mesh filename scale>``: any mesh file trimesh reads (:func:`kinmo.assets.mesh.mesh_parts`),
  scaled. The file name is resolved by the containment rule (:mod:`kinmo.assets.refs`):
  ``package://NAME/rest`` inside the package NAME (:func:`kinmo.assets.refs.package_root`: the
  nearest folder above the URDF with a ``package.xml`` named NAME, else ``DIR/NAME`` for a
  ``--package-path DIR``, else, as before issue 36, ``NAME/rest`` inside the URDF's folder);
  a plain relative name, or ``file://`` followed by one, relative to the URDF's folder and
  inside it, or inside the ROS package holding the URDF (:func:`kinmo.assets.refs.enclosing_package`:
  ``../meshes/door.stl`` from ``pkg/urdf/``, as ROS packages lay meshes out).
- ``<box size>``, ``<cylinder radius length>`` (along local z), ``<sphere radius>`` and
  ``<capsule radius length>``: meshed with trimesh (:mod:`kinmo.assets.primitives`).

Each piece is placed by the ``<origin xyz rpy>`` of its element and the link's pose: the
product of the joint origins from the root (fixed-axis roll, pitch, yaw). Joint types and
axes are ignored (kinmo predicts them). The up axis is z (ROS REP 103), y for a URDF kinmo
wrote (its joints carry ``<mobility_v2>``, :mod:`kinmo.urdf`). Units are the file's (metres
by convention); :mod:`kinmo.data.frames` maps them.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from kinmo import limits
from kinmo.assets import Part, ReadOptions, merge, read_xml, register, xml_root
from kinmo.assets.mesh import mesh_parts
from kinmo.assets.primitives import primitive
from kinmo.assets.refs import enclosing_package, file_inside, package_root
from kinmo.data.frames import UpAxis, default_up
from kinmo.data.names import name_problem
from kinmo.errors import KinmoDataError
from kinmo.io import parse_xml

__all__ = ["link_poses", "mesh_file", "read_urdf"]

#: The attributes of each primitive, in :func:`kinmo.assets.primitives.primitive`'s order.
_PRIMITIVES: dict[str, tuple[str, ...]] = {
    "box": ("size",), "cylinder": ("radius", "length"), "capsule": ("radius", "length"),
    "sphere": ("radius",),
}
_KNOWN = "mesh, box, cylinder, sphere or capsule"


def _accepts(path: Path) -> bool:
    if not path.is_file():
        return False
    suffix = path.suffix.lower()
    return suffix == ".urdf" or (suffix == ".xml" and xml_root(path) == "robot")


def _up(path: Path) -> UpAxis:
    try:
        if parse_xml(path).getroot().find("joint/mobility_v2") is not None:
            return "y"  # kinmo's own URDFs are y-up (kinmo.urdf)
    except KinmoDataError:
        pass  # read_parts names the problem
    return default_up(".urdf")


def numbers(el: ET.Element, attr: str, n: int, default: str | None, source: Path, where: str
            ) -> np.ndarray:
    """The attribute ``attr`` of ``el`` as ``n`` finite numbers, ``(n,) float64``.

    Raises
    ------
    KinmoDataError
        Missing (and no default), or not ``n`` finite numbers: names the element and value.
    """
    text = el.get(attr, default)
    try:
        values = np.array([float(x) for x in (text or "").split()], dtype=np.float64)
    except ValueError:
        values = np.zeros(0)
    if values.shape != (n,) or not np.all(np.isfinite(values)):
        shown = "missing" if text is None else repr(text)
        raise KinmoDataError(source, f"{where}: <{el.tag} {attr}> is {shown}; it must be {n} "
                                     f"finite number(s) separated by spaces")
    return values


def origin(el: ET.Element | None, source: Path, where: str) -> np.ndarray:
    """The ``(4, 4) float64`` transform of an ``<origin xyz rpy>`` (identity when absent)."""
    T = np.eye(4)
    if el is not None:
        T[:3, :3] = Rotation.from_euler("xyz", numbers(el, "rpy", 3, "0 0 0", source, where)).as_matrix()
        T[:3, 3] = numbers(el, "xyz", 3, "0 0 0", source, where)
    return T


def link_poses(robot: ET.Element, source: Path) -> dict[str, np.ndarray]:
    """Each link's pose in the URDF's world frame at the rest pose, ``(4, 4) float64``: the
    product of joint origins from its root (a link no joint has as child is a root, at the
    identity).

    Raises
    ------
    KinmoDataError
        A bad ``<origin>``, or joints that form a cycle.
    """
    joints: dict[str, tuple[str, np.ndarray]] = {}
    for j in robot.findall("joint"):
        c, p = j.find("child"), j.find("parent")
        if c is not None and p is not None:
            joints[c.get("link", "")] = (p.get("link", ""),
                                         origin(j.find("origin"), source, f"joint {j.get('name', '')!r}"))
    pose: dict[str, np.ndarray] = {}
    for link in robot.findall("link"):
        chain, name = [], link.get("name", "")
        while name not in pose and name in joints:  # walk up to a posed link or a root
            if name in chain:
                raise KinmoDataError(source, f"the joints form a cycle through link {name!r} "
                                             "(a URDF's links form a tree): fix the parent/child links")
            chain.append(name)
            name = joints[name][0]
        T = pose.setdefault(name, np.eye(4))
        for c in reversed(chain):
            T = pose[c] = T @ joints[c][1]
    return pose


def mesh_file(source: Path, link: str, filename: str, options: ReadOptions) -> Path:
    """The file a ``<mesh filename>`` of link ``link`` names (module docs: the rule).

    Returns
    -------
    Path
        An existing file inside its root.

    Raises
    ------
    KinmoDataError
        A name refused by the rule, a package not found, or no such file: one line naming the
        fix.
    """
    what = f"link {link!r}: mesh {filename!r}"
    if filename.startswith("package://"):
        name, _, rest = filename[len("package://"):].partition("/")
        if (problem := name_problem(name)) is not None:
            raise KinmoDataError(source, f"{what} refused: its package name {problem} "
                                         "(package://NAME/path, NAME a plain name)")
        root = package_root(name, source, options.package_path)
        if root is None:  # as before issue 36: NAME/rest inside the URDF's folder
            path = file_inside(source.parent, f"{name}/{rest}", source, what,
                               f"paths stay inside package {name!r}")
            if path.is_file():
                return path
            nor = "".join(f" nor in {d}" for d in options.package_path)
            raise KinmoDataError(source, f"{what}: no package.xml named {name!r} above the file{nor}; "
                                         f"pass --package-path DIR holding {name}/")
        path = file_inside(root, rest, source, what, f"paths stay inside package {name!r}")
        where = f"in package {name!r} at {root}"
    else:
        rel = filename[len("file://"):] if filename.startswith("file://") else filename
        package = enclosing_package(source)
        root = source.parent if package is None else package
        path = file_inside(root, rel, source, what,
                           "mesh paths are relative inside the URDF's folder, or its ROS package's, or "
                           "package://NAME/...", base=source.parent)
        where = f"beside the URDF (looked for {path})"
    if not path.is_file():
        raise KinmoDataError(source, f"{what} not found {where}: add the file or fix the filename")
    return path


def _pieces(source: Path, link: str, el: ET.Element, T: np.ndarray, options: ReadOptions
            ) -> list[Part]:
    """The meshes of one ``<visual>`` / ``<collision>`` element, in the world frame."""
    geometry = el.find("geometry")
    shape = next(iter(geometry), None) if geometry is not None else None
    if shape is None:
        return []
    where = f"link {link!r}"
    T = T @ origin(el.find("origin"), source, where)
    if shape.tag == "mesh":
        path = mesh_file(source, link, shape.get("filename", ""), options)
        scale = numbers(shape, "scale", 3, "1 1 1", source, where)
        meshes = [(v * scale, f) for _, v, f in mesh_parts(path)]
    elif shape.tag in _PRIMITIVES:
        sizes = np.concatenate([numbers(shape, a, 3 if a == "size" else 1, None, source, where)
                                for a in _PRIMITIVES[shape.tag]])
        try:
            meshes = [primitive(shape.tag, sizes)]
        except ValueError as e:
            raise KinmoDataError(source, f"{where}: <{shape.tag}> {e}") from None
    else:
        raise KinmoDataError(source, f"{where}: unknown geometry <{shape.tag}> (kinmo reads "
                                     f"{_KNOWN}): replace it with a mesh")
    for _, f in meshes:
        limits.check("triangles", len(f), source)
    return [(link, v @ T[:3, :3].T + T[:3, 3], f) for v, f in meshes]


@register("urdf", "a URDF (a link per part)", _accepts, _up)
def read_urdf(path: Path, options: ReadOptions) -> list[Part]:
    """One part per link with geometry, in link order (module docs).

    Parameters
    ----------
    path : Path
        The URDF (root ``<robot>``).
    options : ReadOptions
        ``package_path`` for ``package://`` names.

    Returns
    -------
    list of Part
        Named after the links; vertices ``(V, 3) float64`` in the URDF's world frame and units.

    Raises
    ------
    KinmoDataError
        Not a readable URDF (XML refused by :func:`kinmo.io.parse_xml`, another root), a
        refused or missing mesh, a bad origin, size or scale, a joint cycle.
    """
    robot = read_xml(path, "robot", "URDF")
    poses = link_poses(robot, path)
    parts: list[Part] = []
    for link in robot.findall("link"):
        name = link.get("name", "")
        elements = link.findall("visual") or link.findall("collision")
        pieces = [p for el in elements for p in _pieces(path, name, el, poses[name], options)]
        if pieces:
            parts.append(merge(pieces, name))
            limits.check("parts", len(parts), path)
    return parts
