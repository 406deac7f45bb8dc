"""Small URDF / MJCF assets written in a test's tmp_path (nothing downloaded): a four-link
cabinet of boxes, ROS package trees, OBJ meshes written by trimesh."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import trimesh

#: The box cabinet: link -> (centre, full size) in metres, z-up, at the rest pose.
CABINET = {
    "body": ((0.0, 0.0, 0.5), (0.6, 0.5, 1.0)),
    "door": ((0.31, 0.0, 0.7), (0.02, 0.48, 0.56)),
    "drawer": ((0.25, 0.0, 0.2), (0.1, 0.46, 0.2)),
    "handle": ((0.34, 0.0, 0.2), (0.04, 0.2, 0.03)),
}


def box_urdf(path: Path, scale: float = 1.0, geometry: str = "visual") -> Path:
    """The cabinet as a URDF of boxes: each link's box placed by its joint origin (fixed
    joints from ``body``), ``scale`` times the sizes in metres."""
    links, joints = [], []
    for name, (c, s) in CABINET.items():
        size = " ".join(repr(scale * x) for x in s)
        links.append(f'<link name="{name}"><{geometry}><geometry><box size="{size}"/></geometry>'
                     f'</{geometry}></link>')
        if name != "body":
            xyz = " ".join(repr(scale * x) for x in c)
            joints.append(f'<joint name="{name}_j" type="fixed"><parent link="body"/>'
                          f'<child link="{name}"/><origin xyz="{xyz}"/></joint>')
    body = " ".join(repr(scale * x) for x in CABINET["body"][0])
    links[0] = links[0].replace("<geometry>", f'<origin xyz="{body}"/><geometry>', 1)
    path.write_text(f'<robot name="cabinet">{"".join(links)}{"".join(joints)}</robot>')
    return path


def box_mjcf(path: Path, scale: float = 1.0) -> Path:
    """The cabinet as an MJCF model: the body's box in the world body, each other link a
    body with a hinge or slide joint (kinmo must ignore them) and a box geom."""
    bodies = []
    for name, (c, s) in list(CABINET.items())[1:]:
        pos = " ".join(repr(scale * x) for x in c)
        half = " ".join(repr(scale * x / 2) for x in s)
        joint = '<joint type="slide" axis="1 0 0"/>' if name == "drawer" else '<joint type="hinge" axis="0 0 1"/>'
        bodies.append(f'<body name="{name}" pos="{pos}">{joint}<geom type="box" size="{half}"/></body>')
    c, s = CABINET["body"]
    pos = " ".join(repr(scale * x) for x in c)
    half = " ".join(repr(scale * x / 2) for x in s)
    path.write_text(f'<mujoco model="cabinet"><worldbody><geom type="plane" size="5 5 0.1"/>'
                    f'<geom type="box" pos="{pos}" size="{half}"/>{"".join(bodies)}</worldbody></mujoco>')
    return path


def write_mesh(path: Path, extents=(1.0, 1.0, 1.0), offset=(0.0, 0.0, 0.0)) -> Path:
    """A box mesh written by trimesh (format from the suffix)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    trimesh.creation.box(extents=extents).apply_translation(offset).export(path)
    return path


def package(root: Path, name: str) -> Path:
    """A ROS package folder ``root`` with ``package.xml`` naming ``name``."""
    root.mkdir(parents=True, exist_ok=True)
    (root / "package.xml").write_text(f'<?xml version="1.0"?><package format="2"><name>{name}'
                                      "</name><version>0.0.1</version></package>")
    return root


def mesh_urdf(path: Path, filenames: dict[str, str]) -> Path:
    """A URDF with one link per ``name -> mesh filename``, joined by fixed joints to the first."""
    names = list(filenames)
    links = "".join(f'<link name="{n}"><visual><geometry><mesh filename="{f}"/></geometry>'
                    "</visual></link>" for n, f in filenames.items())
    joints = "".join(f'<joint name="j{k}" type="fixed"><parent link="{names[0]}"/><child link="{n}"/>'
                     "</joint>" for k, n in enumerate(names[1:]))
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(f'<robot name="r">{links}{joints}</robot>')
    return path


def bounds(parts) -> np.ndarray:
    """``(2, 3)`` min and max corner of all parts' vertices."""
    v = np.concatenate([p[1] for p in parts])
    return np.stack([v.min(0), v.max(0)])
