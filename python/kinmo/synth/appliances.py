"""Appliances: Refrigerator, Oven, Microwave, Dishwasher, Safe and WashingMachine.

Each is a shell (walls around one or more cavities, open at the front +z) with overlay doors,
knobs and buttons, built in metres, y-up, and named as PartNet / PartNet-Mobility annotate
them. The kitchen appliances (refrigerator, oven, microwave, dishwasher) are generated in
:mod:`kinmo.synth.kitchen` and re-exported here; this module holds the flat ``Safe -> door /
switch / handle / base_body`` (dial and lever jointed to the door) and ``WashingMachine ->
door / button / base_body``.
"""

from __future__ import annotations

import numpy as np

from kinmo.synth.appliance_parts import body_walls, rotary_knob
from kinmo.synth.assembly import LinkSpec, Motion, Node, SynthObject
from kinmo.synth.components import Rect, door, feet
from kinmo.synth.kitchen import dishwasher, microwave, oven, refrigerator
from kinmo.synth.primitives import box, cylinder, lathe

__all__ = ["dishwasher", "microwave", "oven", "refrigerator", "safe", "washing_machine"]


def safe(rng: np.random.Generator) -> SynthObject:
    """A safe: thick-walled body, a side-hinged door carrying a combination dial and a lever
    handle, both jointed to the door (a kinematic chain: base -> door -> dial / lever).

    The dial turns about its own axis (unlimited); the lever turns about its hub, from
    horizontal down to 60-90 degrees, sweeping a quarter circle below the hub, away from the
    dial above it. SAPIEN's flat hierarchy: ``Safe -> door, switch, handle, base_body``.

    Randomised: size, wall and door thickness, hinge side, door limit (90-170 degrees), dial
    size, lever length and limit, inner shelf, feet.

    Parameters
    ----------
    rng : numpy.random.Generator

    Returns
    -------
    SynthObject
        In metres.
    """
    W = rng.uniform(0.3, 0.6)
    H = rng.uniform(0.3, 0.7)
    D = rng.uniform(0.3, 0.5)
    tw = rng.uniform(0.03, 0.07)
    td = rng.uniform(0.04, 0.08)
    has_feet = bool(rng.random() < 0.4)
    hb = rng.uniform(0.01, 0.03) if has_feet else 0.0
    y0, y1 = hb, hb + H
    zf = D / 2
    walls = body_walls(W, D, y0, y1, tw)
    if H > 0.45 and rng.random() < 0.6:
        ys = rng.uniform(0.4, 0.6) * (H - 2 * tw) + y0 + tw
        walls.append(
            box(
                (-W / 2 + tw, ys, -D / 2 + tw),
                (W / 2 - tw, ys + tw / 3, zf - rng.uniform(0.01, 0.03)),
            )
        )
    if has_feet:
        walls += feet(rng, -W / 2, W / 2, -D / 2, D / 2, hb)
    side = str(rng.choice(["left", "right"]))
    rect = Rect(-W / 2, W / 2, y0, y1)
    g = door(rng, rect, zf, td, side, True, round(float(rng.uniform(90, 170)), 2), None)
    door_node = Node("door", "door", [], g.surface)
    links = [LinkSpec("door", "door", [door_node], g.motion)]
    zface = zf + td
    # lever near the free edge at mid height, pointing towards the door centre
    r_hub = rng.uniform(0.012, 0.02)
    arm_len = min(rng.uniform(0.08, 0.16), 0.45 * W)
    arm_w = rng.uniform(0.012, 0.02)
    h_hub, h_arm = rng.uniform(0.01, 0.02), rng.uniform(0.008, 0.015)
    inward = 1.0 if side == "left" else -1.0  # free edge is on the +x side for a left hinge
    px = (W / 2 if side == "left" else -W / 2) - inward * (0.03 + r_hub)
    py = y0 + rng.uniform(0.35, 0.5) * H
    x_end = px - inward * arm_len
    arm = box(
        (min(px, x_end), py - arm_w / 2, zface + h_hub),
        (max(px, x_end), py + arm_w / 2, zface + h_hub + h_arm),
    )
    lever = Node(
        "handle", "handle", [], [cylinder(r_hub, zface, zface + h_hub, (px, py, 0.0), "z", 32), arm]
    )
    # positive rotation swings the arm downwards: about +z for an arm pointing -x
    lever_dir = np.array([0.0, 0.0, inward])
    lever_lim = round(float(rng.uniform(60, 90)), 2)
    # dial above the lever's sweep
    r_dial = min(rng.uniform(0.025, 0.045), 0.2 * W)
    dy = py + max(r_hub, arm_w / 2) + r_dial + rng.uniform(0.02, 0.05)
    dy = min(dy, y1 - r_dial - 0.01)
    dx = (px + x_end) / 2
    dial_meshes, dial_motion = rotary_knob(rng, dx, dy, zface, r_dial)
    dial = Node("switch", "switch", [], dial_meshes)
    links.append(LinkSpec("switch", "knob", [dial], dial_motion, parent=0))
    links.append(
        LinkSpec(
            "handle",
            "handle",
            [lever],
            Motion("hinge", (px, py, zface), lever_dir, (0.0, lever_lim)),
            parent=0,
        )
    )
    root = Node("Safe", "Safe", [door_node, dial, lever, Node("base_body", "base_body", [], walls)])
    params = {
        "width": W,
        "height": H,
        "depth": D,
        "wall": tw,
        "door_thickness": td,
        "side": side,
        "feet": has_feet,
        "lever": arm_len,
        "dial": r_dial,
    }
    return SynthObject("Safe", root, links, "heavy", "safe_body", params)


def washing_machine(rng: np.random.Generator) -> SynthObject:
    """A front-loading washing machine: a round glass door hinged on its side in front of a
    front panel with a window onto the drum, and 1-2 dials on a control strip above.

    The door (a ring and a glass disc, coaxial lathes about z) is hinged on the vertical
    tangent at its left or right edge, on its front face, so it can swing up to 180 degrees
    without entering the panel; the dials sit above its sweep. SAPIEN's flat hierarchy:
    ``WashingMachine -> door, button..., base_body``.

    Randomised: size, walls, control strip height, door radius and thickness, hinge side and
    limit (100-180 degrees), window size, drum, dial count and size, feet.

    Parameters
    ----------
    rng : numpy.random.Generator

    Returns
    -------
    SynthObject
        In metres.
    """
    W = rng.uniform(0.55, 0.65)
    H = rng.uniform(0.8, 0.9)
    D = rng.uniform(0.5, 0.65)
    tw = rng.uniform(0.015, 0.03)
    tp = rng.uniform(0.01, 0.02)  # front panel thickness
    has_feet = bool(rng.random() < 0.5)
    hb = rng.uniform(0.01, 0.03) if has_feet else 0.0
    y0, y1 = hb, hb + H
    zf, z_in = D / 2, -D / 2 + tw
    h_cs = rng.uniform(0.1, 0.16)
    walls = body_walls(W, D, y0, y1, tw)
    xi0, xi1 = -W / 2 + tw, W / 2 - tw
    y_cs = y1 - tw - h_cs  # bottom of the control strip
    walls.append(box((xi0, y_cs, zf - tp), (xi1, y1 - tw, zf)))  # control strip plate
    # front panel below the strip, with a square window around (0, yc)
    pan_h = y_cs - (y0 + tw)
    R_d = min(0.45 * (xi1 - xi0), 0.42 * pan_h) * rng.uniform(0.85, 1.0)
    yc = y0 + tw + pan_h / 2
    s = R_d * rng.uniform(1.0, 1.25)  # window side: the door disc (radius R_d) covers it
    wx0, wx1, wy0, wy1 = -s / 2, s / 2, yc - s / 2, yc + s / 2
    walls += [
        box((xi0, y0 + tw, zf - tp), (xi1, wy0, zf)),
        box((xi0, wy1, zf - tp), (xi1, y_cs, zf)),
        box((xi0, wy0, zf - tp), (wx0, wy1, zf)),
        box((wx1, wy0, zf - tp), (xi1, wy1, zf)),
    ]
    # drum: a cup about z from the back wall to the panel, its mouth around the window
    r_in = s / np.sqrt(2) + rng.uniform(0.01, 0.03)
    t_dr = rng.uniform(0.005, 0.012)
    r_out = min(r_in + t_dr, 0.5 * (xi1 - xi0) - 0.005, yc - (y0 + tw) - 0.005)
    if r_out > r_in + 0.002:
        z0, z1 = z_in, zf - tp
        walls.append(
            lathe(
                [
                    (0.0, z0),
                    (r_out, z0),
                    (r_out, z1),
                    (r_in, z1),
                    (r_in, z0 + t_dr),
                    (0.0, z0 + t_dr),
                ],
                64,
                (0.0, yc, 0.0),
                "z",
            )
        )
    if has_feet:
        walls += feet(rng, -W / 2, W / 2, -D / 2, D / 2, hb)
    # door: ring + glass, coaxial about z through (0, yc)
    t_d = rng.uniform(0.03, 0.06)
    R_g = R_d * rng.uniform(0.6, 0.75)
    ring = lathe([(R_g, zf), (R_d, zf), (R_d, zf + t_d), (R_g, zf + t_d)], 64, (0.0, yc, 0.0), "z")
    glass = lathe(
        [
            (0.0, zf + 0.3 * t_d),
            (R_g, zf + 0.3 * t_d),
            (R_g, zf + 0.7 * t_d),
            (0.0, zf + 0.7 * t_d),
        ],
        64,
        (0.0, yc, 0.0),
        "z",
    )
    side = str(rng.choice(["left", "right"]))
    hx = -R_d if side == "left" else R_d
    direction = np.array([0.0, -1.0, 0.0]) if side == "left" else np.array([0.0, 1.0, 0.0])
    limit = round(float(rng.uniform(100, 180)), 2)
    door_node = Node("door", "door", [], [ring, glass])
    links = [
        LinkSpec(
            "door",
            "door",
            [door_node],
            Motion("hinge", (hx, yc, zf + t_d), direction, (0.0, limit)),
        )
    ]
    n_k = int(rng.integers(1, 3))
    dial_nodes = []
    for kx in (
        np.linspace(xi0, xi1, n_k + 2)[1:-1]
        if n_k > 1
        else [rng.uniform(0.1, 0.3) * (xi1 - xi0) + xi0]
    ):
        meshes, mo = rotary_knob(rng, float(kx), y_cs + h_cs / 2, zf, 0.4 * h_cs)
        kn = Node("button", "button", [], meshes)
        dial_nodes.append(kn)
        links.append(LinkSpec("button", "knob", [kn], mo))
    root = Node(
        "WashingMachine",
        "WashingMachine",
        [door_node, *dial_nodes, Node("base_body", "base_body", [], walls)],
    )
    params = {
        "width": W,
        "height": H,
        "depth": D,
        "wall": tw,
        "door_radius": R_d,
        "door_thickness": t_d,
        "side": side,
        "dials": n_k,
        "feet": has_feet,
    }
    return SynthObject("WashingMachine", root, links, "heavy", "washing_machine_body", params)
