"""Laptop: a base with keyboard and touchpad, and a lid hinged along the back edge.

Hierarchy as PartNet annotates laptops: ``laptop -> screen_side -> {screen, screen_frame}``,
``laptop -> base_side -> {keyboard, touchpad -> touchpad_surface, base_frame}``. The rest pose
is open (as in PartNet-Mobility), the lid tilted back by 95-130 degrees from closed.
"""

from __future__ import annotations

import numpy as np

from kinmo.synth.assembly import LinkSpec, Motion, Node, SynthObject
from kinmo.synth.primitives import box, rotation


def laptop(rng: np.random.Generator) -> SynthObject:
    """A laptop in an open rest pose.

    The hinge line runs along x at the back edge of the base (``z = 0``), at the height of
    the keyboard top; the lid is built closed (screen face down on the keyboard, touching it)
    and rotated open about that line, so the line is an edge of the lid's box and closing it
    (the lower limit) lays the screen exactly on the keyboard.

    Randomised: width 0.28-0.40 m, depth 0.19-0.28 m, base and lid thickness, keyboard and
    touchpad margins and heights, screen bezels, rest opening angle (95-130 degrees) and
    maximal opening (up to 180 degrees).

    Parameters
    ----------
    rng : numpy.random.Generator

    Returns
    -------
    SynthObject
        In metres; hinge limits ``(-rest angle, max opening - rest angle)`` degrees, a
        positive angle opening the lid further.
    """
    W = rng.uniform(0.28, 0.4)
    D = rng.uniform(0.19, 0.28)
    tb = rng.uniform(0.012, 0.022)
    tl = rng.uniform(0.004, 0.009)
    kb_h = rng.uniform(0.001, 0.003)
    scr_h = rng.uniform(0.0005, 0.002)
    m = rng.uniform(0.01, 0.025)  # keyboard side margin
    kb_z0 = rng.uniform(0.01, 0.02)
    kb_z1 = kb_z0 + D * rng.uniform(0.4, 0.5)
    tp_w = W * rng.uniform(0.25, 0.4)
    tp_z0 = kb_z1 + rng.uniform(0.01, 0.02)
    tp_z1 = min(D - 0.01, tp_z0 + D * rng.uniform(0.22, 0.32))
    tp_h = kb_h * rng.uniform(0.3, 1.0)
    yh = tb + kb_h  # hinge height

    root = Node("laptop", "Laptop")
    screen_side = root.add(Node("screen_side", "Screen Side"))
    bez = rng.uniform(0.006, 0.015)
    bez_bottom = bez + rng.uniform(0.0, 0.015)
    screen = box((-W / 2 + bez, yh, bez_bottom), (W / 2 - bez, yh + scr_h, D - bez))
    frame = box((-W / 2, yh + scr_h, 0.0), (W / 2, yh + scr_h + tl, D))
    rest = round(float(rng.uniform(95.0, 130.0)), 2)
    max_open = round(float(rng.uniform(max(rest + 5.0, 135.0), 180.0)), 2)
    axis = np.array([-1.0, 0.0, 0.0])  # positive rotation opens (u = +z, n = +y: u x n = -x)
    origin = np.array([0.0, yh, 0.0])
    T = rotation(axis, rest, origin)
    screen.apply_transform(T)
    frame.apply_transform(T)
    screen_side.leaf("screen", "Screen", [screen])
    screen_side.leaf("screen_frame", "Screen Frame", [frame])
    base = root.add(Node("base_side", "Base Side"))
    base.leaf("keyboard", "Keyboard", [box((-W / 2 + m, tb, kb_z0), (W / 2 - m, tb + kb_h, kb_z1))])
    tp = base.add(Node("touchpad", "Touchpad"))
    tp.leaf(
        "touchpad_surface",
        "Touchpad Surface",
        [box((-tp_w / 2, tb, tp_z0), (tp_w / 2, tb + tp_h, tp_z1))],
    )
    base.leaf("base_frame", "Base Frame", [box((-W / 2, 0.0, 0.0), (W / 2, tb, D))])
    motion = Motion("hinge", origin, axis, (-rest, round(max_open - rest, 2)))
    params = {
        "width": W,
        "depth": D,
        "base": tb,
        "lid": tl,
        "rest_deg": rest,
        "max_open_deg": max_open,
    }
    return SynthObject(
        "Laptop",
        root,
        [LinkSpec("screen_side", "screen", [screen_side], motion)],
        "free",
        "laptop_base",
        params,
    )
