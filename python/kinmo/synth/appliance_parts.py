"""Pieces shared by the appliance generators (:mod:`kinmo.synth.kitchen`, :mod:`kinmo.synth.appliances`).

A rotary knob on a front face (:func:`rotary_knob`), the five walls of a body open at the
front (:func:`body_walls`) and the feet or plinth below it (:func:`body_base`); object frame
(y-up, front +z, metres), named as PartNet annotates them.
"""

from __future__ import annotations

import numpy as np
import trimesh

from kinmo.synth.assembly import Motion, Node
from kinmo.synth.components import FRONT, foot_base, shell
from kinmo.synth.primitives import box, cylinder

__all__ = ["UP", "body_base", "body_walls", "rotary_knob"]

#: The up direction (y) of the object frame.
UP = np.array([0.0, 1.0, 0.0])


def rotary_knob(
    rng: np.random.Generator, cx: float, cy: float, z_face: float, r_max: float
) -> tuple[list[trimesh.Trimesh], Motion]:
    """A rotary knob on a front face, turning about its own axis (+z) without limit.

    Returns the knob meshes (a disc, optionally with a grip bar in front of it) and its
    motion: a hinge through the knob centre along the face normal, ``noLimit``.
    """
    r = min(rng.uniform(0.014, 0.026), r_max)
    h = rng.uniform(0.012, 0.025)
    meshes = [cylinder(r, z_face, z_face + h, (cx, cy, 0.0), "z", 32)]
    if rng.random() < 0.6:  # grip bar across the face
        gw, gh = 0.3 * r, rng.uniform(0.006, 0.012)
        meshes.append(
            box(
                (cx - gw / 2, cy - 0.85 * r, z_face + h),
                (cx + gw / 2, cy + 0.85 * r, z_face + h + gh),
            )
        )
    return meshes, Motion("hinge", (cx, cy, z_face), FRONT, None)


def body_walls(W: float, D: float, y0: float, y1: float, tw: float) -> list[trimesh.Trimesh]:
    """The 5 walls of a body ``W`` wide, ``D`` deep, from ``y0`` to ``y1``, open at the front
    ``z = D / 2`` (:func:`~kinmo.synth.components.shell`, all walls ``tw`` thick)."""
    lo, hi = np.array([-W / 2, y0, -D / 2]), np.array([W / 2, y1, D / 2])
    return list(shell(lo, hi, tw, tw).values())


def body_base(rng: np.random.Generator, parent: Node, W: float, D: float, hb: float, kind: str) -> None:
    """``base -> foot_base -> foot`` or ``base -> surface_base -> surface`` below a body."""
    b = parent.add(Node("base", "Base"))
    if kind == "feet":
        b.add(foot_base(rng, -W / 2, W / 2, -D / 2, D / 2, hb))
    else:
        sb = b.add(Node("surface_base", "Surface Base"))
        inset = rng.uniform(0.0, 0.03)
        sb.leaf(
            "surface",
            "Surface",
            [box((-W / 2 + inset, 0.0, -D / 2 + inset), (W / 2 - inset, hb, D / 2 - inset))],
        )
