"""MJCF exporter (MuJoCo): nested bodies, hinge/slide joints, per-link meshes.

``mobility.xml`` plus ``meshes/link_<id>.obj`` (each link's leaf meshes merged, mesh frame:
the visual geom, group 1, no contacts) and ``meshes/link_<id>_collision_<k>.obj`` (its convex
pieces, :func:`kinmo.export.collision.collision_pieces`: the collision geoms, group 3; MuJoCo
collides convex shapes only, and the hull of a whole cabinet would fill its drawers' space),
written for and loaded by ``mujoco.MjModel.from_xml_path``.

Mapping (the frames of :mod:`kinmo.urdf`: world = mesh frame, y-up, mesh units; MuJoCo's
default gravity is along -z, so simulate with ``<option gravity="0 -9.81 0"/>`` or rotate the
root body to stand the object upright):

- one ``<body name="link_<id>">`` per link, nested as the mobility tree, its frame at the
  joint axis origin ``a_k`` at rest (``pos = a_k - a_parent``, no rotation); its mesh geom at
  ``pos = -a_k``;
- hinge -> ``<joint type="hinge">`` (range in radians, :func:`kinmo.urdf.hinge_limits_rad`;
  unlimited -> ``limited="false"``); slider -> ``type="slide"``; a slider that rotates
  (cylindrical) -> a ``slide`` and a ``hinge`` joint about the same axis in the same body
  (named ``joint_<id>`` and ``joint_<id>_rotation``); fixed labels -> no joint (welded);
- the root link is welded to the world (a fixed base, as the URDF's ``base``); a floating
  object would add ``<freejoint/>``.

Cannot express: joint labels ``free``/``heavy``/``static``/``junk`` (all welded), limits as
annotated (turn-shifted as in URDF), mass properties (placeholders: unit mass and inertia).
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

from kinmo.data.names import clean_xml_tree
from kinmo.export import ExportContext, register
from kinmo.export.kinematics import write_obj
from kinmo.export.collision import collision_pieces
from kinmo.export.urdf import pieces_bar
from kinmo.io import atomic_path, write_text
from kinmo.urdf import link_frame_origins, urdf_joints

__all__ = ["mjcf_string", "write_mjcf"]


def _xyz(v) -> str:
    return " ".join(repr(float(c) + 0.0) for c in v)


def mjcf_string(ctx: ExportContext, meshes: dict[int, str],
                collision: dict[int, list[str]] | None = None) -> str:
    """The MJCF XML of ``ctx`` (module docs).

    ``meshes``: link id -> visual mesh file name; ``collision``: link id -> convex piece file
    names (all relative to ``meshes/``, in the mesh frame).
    """

    joints = urdf_joints(ctx.links, ctx.shape.path)
    frames = link_frame_origins(ctx.links, ctx.shape.path)
    root = ET.Element("mujoco", model=ctx.name)
    ET.SubElement(root, "compiler", angle="radian", meshdir="meshes", inertiafromgeom="false")
    asset = ET.SubElement(root, "asset")
    collision = collision or {}
    for lid, fname in sorted(meshes.items()):
        ET.SubElement(asset, "mesh", name=f"link_{lid}", file=fname, inertia="shell")
        for k, piece in enumerate(collision.get(lid, [])):
            ET.SubElement(asset, "mesh", name=f"link_{lid}_collision_{k}", file=piece,
                          inertia="shell")
    world = ET.SubElement(root, "worldbody")
    bodies: dict[str, ET.Element] = {"base": world}
    by_id = {l.id: l for l in ctx.links}
    for j in joints:
        if j.child.endswith("_helper"):
            bodies[j.child] = bodies[j.parent]  # the helper's joints go into the link's body
            helper_joint = j
            continue
        lid = j.link_id
        parent_el = bodies[j.parent]
        link = by_id[lid]
        parent_frame = frames[link.parent] if link.parent != -1 else frames[lid] * 0
        body = ET.SubElement(parent_el, "body", name=f"link_{lid}",
                             pos=_xyz(frames[lid] - parent_frame))
        bodies[j.child] = body
        ET.SubElement(body, "inertial", pos="0 0 0", mass="1", diaginertia="1 1 1")
        moving = [helper_joint, j] if j.parent.endswith("_helper") else [j]
        for mj in moving:
            if not mj.is_moving:
                continue
            kind = "slide" if mj.type == "prismatic" else "hinge"
            el = ET.SubElement(body, "joint", name=mj.name, type=kind, pos="0 0 0",
                               axis=_xyz(mj.axis))
            if mj.lower is None:
                el.set("limited", "false")
            else:
                el.set("limited", "true")
                el.set("range", f"{float(mj.lower)!r} {float(mj.upper)!r}")
        if lid in meshes:
            ET.SubElement(body, "geom", name=f"link_{lid}", type="mesh", mesh=f"link_{lid}",
                          pos=_xyz(-frames[lid]), contype="0", conaffinity="0", group="1")
            for k in range(len(collision.get(lid, []))):
                ET.SubElement(body, "geom", name=f"link_{lid}_collision_{k}", type="mesh",
                              mesh=f"link_{lid}_collision_{k}", pos=_xyz(-frames[lid]),
                              group="3", rgba="0.5 0.5 0.5 0")
    clean_xml_tree(root)  # names from input files: no control characters (issue 21)
    ET.indent(root, space="  ")
    return ET.tostring(root, encoding="unicode") + "\n"


def write_mjcf(ctx: ExportContext) -> list[Path]:
    """Write ``mobility.xml`` and ``meshes/link_<id>.obj`` into ``ctx.out_dir``.

    Returns
    -------
    list of Path
        The MJCF file, then the mesh files (visual and convex collision pieces).

    Raises
    ------
    KinmoDataError
        Inconsistent links (as :func:`kinmo.urdf.urdf_joints`) or unreadable meshes.
    """

    mdir = ctx.out_dir / "meshes"
    mdir.mkdir(parents=True, exist_ok=True)
    files: list[Path] = []
    names: dict[int, str] = {}
    collision: dict[int, list[str]] = {}
    with pieces_bar(ctx) as bar:
        for lid, m in ctx.meshes.items():
            bar.advance()
            if len(m.faces) == 0:
                continue
            p = mdir / f"link_{lid}.obj"
            with atomic_path(p) as tmp:
                write_obj(tmp, m.vertices, m.faces)
            files.append(p)
            names[lid] = p.name
            pieces = collision_pieces(m, mdir / f"link_{lid}_collision", ctx.collision)
            files.extend(pieces)
            collision[lid] = [q.name for q in pieces]
    path = ctx.out_dir / "mobility.xml"
    write_text(path, mjcf_string(ctx, names, collision))
    return [path] + files


@register("mjcf", "MJCF (MuJoCo): nested bodies, hinge/slide joints, OBJ meshes, convex collision")
def _mjcf(ctx: ExportContext) -> list[Path]:
    return write_mjcf(ctx)
