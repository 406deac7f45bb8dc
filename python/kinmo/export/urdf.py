"""URDF exporter with convex collision pieces, and the URDF reader that inverts it.

The URDF itself is written by :func:`kinmo.urdf.write_urdf` (frames, signs, joint types and
names in :mod:`kinmo.urdf`): a single-parent tree (one URDF link per PartNet-Mobility link, a
geometry-less helper link per cylindrical joint), joint limits, the original OBJ meshes as
visuals. Collision geometry is a list of convex pieces per link (:mod:`kinmo.export.collision`:
by default the convex hull of each leaf mesh, concave leaves split into convex parts; V-HACD
or CoACD with ``--collision``):
``collision/link_<id>_<k>.obj`` is its ``k``-th piece, one ``<collision>`` element each
(simulators reject or slow down on concave triangle soups; every URDF loader takes a list of
convex meshes).

What URDF cannot express, and how kinmo keeps it: a cylindrical joint (slider that also
rotates, PartNet-Mobility ``rotates``; the paper's ``PR`` types) is a prismatic joint to a
helper link, then a revolute one; joint labels ``free``/``heavy``/``static``/``junk`` are all
``fixed``; hinge limits are shifted by whole turns to contain the rest pose, unlimited sliders
get +-1000 mesh units. The original values ride along in a ``<mobility_v2>`` element per joint
(ignored by URDF loaders), and :func:`read_urdf` restores them: ``mobility_v2.json`` -> URDF
-> :func:`read_urdf` is lossless (a URDF without those elements, e.g. from another tool, is
read from the standard tags alone).
"""

from __future__ import annotations

import math
import os
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any

import numpy as np

from kinmo.data.model import Joint, JointType, Link
from kinmo.errors import KinmoDataError
from kinmo.export import ExportContext, register
from kinmo.export.collision import collision_pieces
from kinmo.progress import CountingBar
from kinmo.urdf import BASE_LINK, write_urdf

__all__ = ["UrdfLink", "read_urdf", "read_urdf_tree", "write_urdf_convex"]

#: Links from which the convex decomposition of an export shows a progress bar.
PIECES_BAR_MIN_LINKS = 50


def pieces_bar(ctx: ExportContext) -> Any:
    """The progress bar (on stderr) of the collision geometry of ``ctx``'s links: a convex
    decomposition (``vhacd``, ``coacd``) takes seconds per link, so an object of many links
    shows its progress (issue 21, finding 5); none below :data:`PIECES_BAR_MIN_LINKS` links,
    nor without ``ctx.progress``."""

    n = len(ctx.meshes)
    return CountingBar(n, ctx.progress and n >= PIECES_BAR_MIN_LINKS,
                       f"collision ({ctx.collision})", ctx.name, counters={})


def write_urdf_convex(ctx: ExportContext, path: Path | None = None) -> list[Path]:
    """Write ``mobility.urdf`` with convex collision pieces (``ctx.collision``, a method of
    :mod:`kinmo.export.collision`) into ``ctx.out_dir``.

    Returns
    -------
    list of Path
        The URDF, then the collision OBJ files.
    """

    path = path or ctx.out_dir / "mobility.urdf"
    pieces: dict[int, list[str]] = {}
    files: list[Path] = []
    with pieces_bar(ctx) as bar:
        for lid, mesh in ctx.meshes.items():
            ps = collision_pieces(mesh, ctx.out_dir / "collision" / f"link_{lid}", ctx.collision)
            files.extend(ps)
            if ps:
                pieces[lid] = [os.path.relpath(p, path.parent) for p in ps]
            bar.advance()
    return [write_urdf(ctx.shape, path, ctx.links, name=ctx.name, collision=pieces)] + files


@register("urdf", "URDF (PyBullet, SAPIEN, ROS): visual OBJ meshes, convex collision pieces")
def _urdf(ctx: ExportContext) -> list[Path]:
    return write_urdf_convex(ctx)


class UrdfLink:
    """One URDF link as read by :func:`read_urdf_tree`.

    Attributes
    ----------
    name : str
    visuals : list of (str, str)
        ``(visual name, mesh file name)`` per visual.
    collisions : list of str
        Collision mesh file names.
    """

    def __init__(self, name: str) -> None:
        self.name = name
        self.visuals: list[tuple[str, str]] = []
        self.collisions: list[str] = []


def _floats(text: str | None, n: int, where: Path, what: str) -> np.ndarray:
    try:
        v = np.array([float(x) for x in (text or "").split()], dtype=np.float64)
    except ValueError:
        v = np.zeros(0)
    if v.shape != (n,) or not np.isfinite(v).all():
        raise KinmoDataError(where, f"{what}: expected {n} numbers, got {text!r}")
    return v


def read_urdf_tree(path: str | Path) -> tuple[dict[str, UrdfLink], list[ET.Element]]:
    """Parse a URDF: its links (visual/collision meshes) and ``<joint>`` elements.

    Raises
    ------
    KinmoDataError
        Not readable XML, not a ``<robot>``, or a link with two parents.
    """
    path = Path(path)
    try:
        root = ET.parse(path).getroot()
    except (OSError, ET.ParseError) as e:
        raise KinmoDataError(path, f"not a readable URDF: {e}") from None
    if root.tag != "robot":
        raise KinmoDataError(path, f"root element is <{root.tag}>, not <robot>")
    links: dict[str, UrdfLink] = {}
    for el in root.findall("link"):
        ul = UrdfLink(el.get("name", ""))
        for v in el.findall("visual"):
            m = v.find("geometry/mesh")
            if m is not None:
                ul.visuals.append((v.get("name", ""), m.get("filename", "")))
        for c in el.findall("collision"):
            m = c.find("geometry/mesh")
            if m is not None:
                ul.collisions.append(m.get("filename", ""))
        links[ul.name] = ul
    joints = root.findall("joint")
    seen: dict[str, str] = {}
    for j in joints:
        child = j.find("child")
        c = child.get("link", "") if child is not None else ""
        if c in seen:
            raise KinmoDataError(path, f"link {c!r} has two parents (joints {seen[c]!r} and "
                                       f"{j.get('name')!r})")
        seen[c] = j.get("name", "")
    return links, joints


def _link_id(name: str, where: Path) -> int:
    stem = name.removesuffix("_helper")
    if not stem.startswith("link_") or not stem[5:].lstrip("-").isdigit():
        raise KinmoDataError(where, f"link {name!r} is not named link_<id> (a kinmo URDF)")
    return int(stem[5:])


def read_urdf(path: str | Path) -> list[Link]:
    """The PartNet-Mobility links of a URDF written by kinmo (inverse of the exporter).

    Link ids come from the ``link_<id>`` names, parts from the visual names
    ``<part name>-<part id>``; axis origins are the joint frames' positions at rest, in the
    mesh frame. Where a ``<mobility_v2>`` element is present, joint labels, names and limits
    are taken from it (lossless); otherwise from the standard tags (``fixed`` -> ``static``,
    revolute limits radians -> degrees, ``continuous`` -> no limit).

    Parameters
    ----------
    path : str or Path
        A URDF from :func:`kinmo.urdf.write_urdf` / the ``urdf`` exporter.

    Returns
    -------
    list of Link
        In ascending id order, as :func:`kinmo.data.readers.read_links` returns them.

    Raises
    ------
    KinmoDataError
        Unreadable XML, a link with two parents, links not named ``link_<id>``, joints
        without origin/axis numbers (message names the file).
    """

    path = Path(path)
    ulinks, joints = read_urdf_tree(path)
    by_child = {j.find("child").get("link"): j for j in joints if j.find("child") is not None}
    frame: dict[str, np.ndarray] = {BASE_LINK: np.zeros(3)}

    def pos(name: str) -> np.ndarray:
        if name in frame:
            return frame[name]
        j = by_child.get(name)
        if j is None:
            frame[name] = np.zeros(3)
            return frame[name]
        o = j.find("origin")
        off = np.zeros(3) if o is None else _floats(o.get("xyz", "0 0 0"), 3, path,
                                                       f"joint {j.get('name')} origin")
        frame[name] = pos(j.find("parent").get("link")) + off
        return frame[name]

    out: list[Link] = []
    for name, ul in ulinks.items():
        if name == BASE_LINK or name.endswith("_helper"):
            continue
        lid = _link_id(name, path)
        j = by_child.get(name)
        helper_j = None
        if j is not None and j.find("parent").get("link", "").endswith("_helper"):
            helper_j = j
            j = by_child.get(j.find("parent").get("link"))
        parent_name = j.find("parent").get("link") if j is not None else BASE_LINK
        parent = -1 if parent_name == BASE_LINK else _link_id(parent_name, path)
        parts: list[int] = []
        pnames: list[str] = []
        for vname, _ in ul.visuals:
            pname, _, pid = vname.rpartition("-")
            if pid.lstrip("-").isdigit() and int(pid) not in parts:
                parts.append(int(pid))
                pnames.append(pname)
        ann = {} if j is None or j.find("mobility_v2") is None else dict(j.find("mobility_v2").attrib)
        jtype = j.get("type") if j is not None else "fixed"
        if jtype in ("revolute", "continuous"):
            kind = JointType.HINGE
        elif jtype == "prismatic":
            kind = JointType.SLIDER
        else:
            kind = JointType(ann["joint"]) if "joint" in ann else (
                JointType.FREE if parent == -1 else JointType.STATIC)
        joint = Joint(kind)
        if kind in (JointType.HINGE, JointType.SLIDER):
            ax = j.find("axis")
            d = _floats(ax.get("xyz") if ax is not None else "1 0 0", 3, path,
                        f"joint {j.get('name')} axis")
            d = d / np.linalg.norm(d)
            lim_el = j.find("limit")
            if "limit" in ann:
                limit = None if ann["limit"] == "none" else tuple(
                    sorted(_floats(ann["limit"], 2, path, "mobility_v2 limit")))
            elif jtype == "continuous" or lim_el is None:
                limit = None
            else:
                lo, hi = float(lim_el.get("lower", 0)), float(lim_el.get("upper", 0))
                limit = ((math.degrees(lo), math.degrees(hi)) if kind is JointType.HINGE
                         else (lo, hi))
            rotates, rot_limit = False, None
            if helper_j is not None:
                rotates = True
                if "rotation_limit" in ann:
                    rot_limit = (None if ann["rotation_limit"] == "none"
                                 else float(ann["rotation_limit"]))
                elif helper_j.get("type") == "revolute":
                    rl = helper_j.find("limit")
                    rot_limit = math.degrees(float(rl.get("upper", 0)))
            joint = Joint(kind, pos(name if helper_j is None else j.find("child").get("link")),
                          d, limit, rotates, rot_limit)
        out.append(Link(lid, parent, ann.get("name", name), tuple(parts), joint))
    return sorted(out, key=lambda l: l.id)
