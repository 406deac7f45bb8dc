"""Kitchen appliances: Refrigerator, Oven, Microwave and Dishwasher.

Each is a shell (walls around one or more cavities, open at the front +z) with overlay doors,
drawers, knobs and sliding racks, built in metres, y-up, and named as PartNet /
PartNet-Mobility annotate them: ``refrigerator -> body -> frame / door / body_interior``,
SAPIEN's flat ``Oven -> door / knob / tray / base_body``, ``microwave -> body -> frame / door /
side_controls / body_interior -> tray`` and ``dishwasher -> body -> frame / door /
body_interior -> shelf``.
"""

from __future__ import annotations

import numpy as np

from kinmo.synth.appliance_parts import UP, body_base, body_walls, rotary_knob
from kinmo.synth.assembly import LinkSpec, Motion, Node, SynthObject
from kinmo.synth.components import FRONT, Rect, door, drawer, feet, open_box
from kinmo.synth.primitives import box, cylinder

__all__ = ["dishwasher", "microwave", "oven", "refrigerator"]


def refrigerator(rng: np.random.Generator) -> SynthObject:
    """A refrigerator: one or two compartments, 1-2 doors or a door over a freezer drawer.

    Randomised: size (full height 1.2-1.9 m or a 0.5-0.9 m mini fridge), wall and door
    thickness, layout (single door, top or bottom freezer door, side-by-side, freezer
    drawer), hinge side, handles, inner shelves, base (feet or plinth), door limits.

    Parameters
    ----------
    rng : numpy.random.Generator

    Returns
    -------
    SynthObject
        In metres.
    """
    mini = bool(rng.random() < 0.2)
    W = rng.uniform(0.45, 0.6) if mini else rng.uniform(0.55, 0.95)
    H = rng.uniform(0.5, 0.9) if mini else rng.uniform(1.2, 1.9)
    D = rng.uniform(0.45, 0.6) if mini else rng.uniform(0.55, 0.75)
    tw = rng.uniform(0.03, 0.06)
    td = rng.uniform(0.04, 0.08)
    base_kind = str(rng.choice(["feet", "surface"]))
    hb = rng.uniform(0.02, 0.06)
    y0, y1 = hb, hb + H
    zf = D / 2
    layouts = (
        ["single"]
        if mini
        else ["single", "top_freezer", "bottom_freezer", "side_by_side", "freezer_drawer"]
    )
    layout = str(rng.choice(layouts))
    if layout == "side_by_side" and W < 0.7:
        layout = "top_freezer"
    reveal = rng.uniform(0.003, 0.006)

    root = Node("refrigerator", "Refrigerator")
    body = root.add(Node("body", "Body"))
    walls = body_walls(W, D, y0, y1, tw)
    interior = Node("body_interior", "Body Interior")
    z_in = -D / 2 + tw
    compartments: list[Rect] = []  # inner openings
    if layout in ("top_freezer", "bottom_freezer", "freezer_drawer"):
        frac = rng.uniform(0.28, 0.4)
        inner = H - 2 * tw
        if layout == "top_freezer":
            ys = y0 + tw + (1 - frac) * (inner - tw)
        else:
            ys = y0 + tw + frac * (inner - tw)
        walls.append(box((-W / 2 + tw, ys, z_in), (W / 2 - tw, ys + tw, zf)))
        compartments = [
            Rect(-W / 2 + tw, W / 2 - tw, y0 + tw, ys),
            Rect(-W / 2 + tw, W / 2 - tw, ys + tw, y1 - tw),
        ]
    elif layout == "side_by_side":
        xs = rng.uniform(-0.1, 0.05) * W
        walls.append(box((xs - tw / 2, y0 + tw, z_in), (xs + tw / 2, y1 - tw, zf)))
        compartments = [
            Rect(-W / 2 + tw, xs - tw / 2, y0 + tw, y1 - tw),
            Rect(xs + tw / 2, W / 2 - tw, y0 + tw, y1 - tw),
        ]
    else:
        compartments = [Rect(-W / 2 + tw, W / 2 - tw, y0 + tw, y1 - tw)]
    body.leaf("frame", "Frame", walls)

    links: list[LinkSpec] = []
    side = str(rng.choice(["left", "right"]))
    handle_style = "bar"

    def add_door(rect: Rect, hinge: str) -> None:
        g = door(
            rng, rect, zf, td, hinge, True, round(float(rng.uniform(90.0, 180.0)), 2), handle_style
        )
        dn = body.add(g.node())
        links.append(LinkSpec("door", "door", [dn], g.motion))

    if layout == "single":
        add_door(Rect(-W / 2, W / 2, y0, y1), side)
    elif layout in ("top_freezer", "bottom_freezer"):
        split = compartments[0].y1 + tw / 2
        add_door(Rect(-W / 2, W / 2, y0, split - reveal / 2), side)
        add_door(Rect(-W / 2, W / 2, split + reveal / 2, y1), side)
    elif layout == "side_by_side":
        split = compartments[0].x1 + tw / 2
        add_door(Rect(-W / 2, split - reveal / 2, y0, y1), "left")
        add_door(Rect(split + reveal / 2, W / 2, y0, y1), "right")
    else:  # fridge door above a freezer drawer
        split = compartments[0].y1 + tw / 2
        add_door(Rect(-W / 2, W / 2, split + reveal / 2, y1), side)
        g = drawer(
            rng,
            compartments[0],
            zf,
            zf - z_in,
            Rect(-W / 2, W / 2, y0, split - reveal / 2),
            td,
            handle_style,
        )
        body.add(node := g.node())
        links.append(LinkSpec("drawer", "drawer", [node], g.motion))
    # shelves in the compartments that have doors, set back from the door
    setback = rng.uniform(0.02, 0.06)
    shelf_rooms = compartments[1:] if layout == "freezer_drawer" else compartments
    for c in shelf_rooms:
        n_sh = int(rng.integers(0, 1 + min(4, int(c.h / 0.3))))
        ts = rng.uniform(0.006, 0.015)
        for ys in np.linspace(c.y0, c.y1, n_sh + 2)[1:-1]:
            interior.leaf(
                "shelf",
                "Shelf",
                [box((c.x0, ys - ts / 2, z_in), (c.x1, ys + ts / 2, zf - setback))],
            )
    if interior.children:
        body.children.insert(1, interior)
    body_base(rng, root, W, D, hb, base_kind)
    params = {
        "width": W,
        "height": H,
        "depth": D,
        "wall": tw,
        "door_thickness": td,
        "layout": layout,
        "mini": mini,
        "base": base_kind,
    }
    return SynthObject("Refrigerator", root, links, "heavy", "refrigerator_body", params)


def oven(rng: np.random.Generator) -> SynthObject:
    """An oven (range): cavity with a bottom-hinged glass door, a control panel with rotary
    knobs above it, optional sliding tray inside and storage drawer below; SAPIEN's flat
    hierarchy (``Oven -> door, knob..., tray, drawer, base_body``).

    Randomised: size, wall thickness, control panel height, knob count (2-6) and sizes,
    door thickness, glass border, handle, storage drawer, tray, feet, door limit.

    Parameters
    ----------
    rng : numpy.random.Generator

    Returns
    -------
    SynthObject
        In metres.
    """
    W = rng.uniform(0.5, 0.9)
    H = rng.uniform(0.6, 0.95)
    D = rng.uniform(0.5, 0.7)
    tw = rng.uniform(0.02, 0.04)
    td = rng.uniform(0.03, 0.06)
    has_feet = bool(rng.random() < 0.4)
    hb = rng.uniform(0.02, 0.05) if has_feet else 0.0
    has_drawer = bool(rng.random() < 0.4)
    has_tray = bool(rng.random() < 0.6)
    y0, y1 = hb, hb + H
    zf, z_in = D / 2, -D / 2 + tw
    h_cp = rng.uniform(0.08, 0.15)
    reveal = rng.uniform(0.003, 0.006)

    root = Node("Oven", "Oven")
    walls = body_walls(W, D, y0, y1, tw)
    # control panel: a divider under it and a front plate between the sides
    y_cp = y1 - tw - h_cp  # bottom of the control zone
    walls.append(box((-W / 2 + tw, y_cp - tw, z_in), (W / 2 - tw, y_cp, zf)))
    t_plate = rng.uniform(0.01, 0.03)
    walls.append(box((-W / 2 + tw, y_cp, zf - t_plate), (W / 2 - tw, y1 - tw, zf)))
    cav_y0 = y0 + tw
    links: list[LinkSpec] = []
    nodes_after: list[Node] = []
    if has_drawer:
        h_dr = rng.uniform(0.1, 0.18)
        walls.append(box((-W / 2 + tw, cav_y0 + h_dr, z_in), (W / 2 - tw, cav_y0 + h_dr + tw, zf)))
        opening = Rect(-W / 2 + tw, W / 2 - tw, cav_y0, cav_y0 + h_dr)
        split = cav_y0 + h_dr + tw / 2
        g = drawer(
            rng,
            opening,
            zf,
            zf - z_in,
            Rect(-W / 2, W / 2, y0, split - reveal / 2),
            td * 0.6,
            "bar",
        )
        dn = Node("drawer", "drawer", [], g.meshes())
        nodes_after.append(dn)
        links.append(LinkSpec("drawer", "drawer", [dn], g.motion))
        cav_y0 = cav_y0 + h_dr + tw
        door_y0, outer = split + reveal / 2, False
    else:
        door_y0, outer = y0, True
    cavity = Rect(-W / 2 + tw, W / 2 - tw, cav_y0, y_cp - tw)
    door_rect = Rect(-W / 2, W / 2, door_y0, y_cp - tw / 2 - reveal / 2)
    border = min(rng.uniform(0.05, 0.1), 0.3 * door_rect.h)
    g = door(
        rng, door_rect, zf, td, "bottom", outer, round(float(rng.uniform(80, 90)), 2), "bar", border
    )
    door_node = Node("door", "door", [], g.meshes())
    links.insert(0, LinkSpec("door", "door", [door_node], g.motion))
    # knobs
    n_k = int(rng.integers(2, 7))
    r_max = 0.4 * min(h_cp, W / (n_k + 1))
    ky = y_cp + h_cp / 2
    knob_nodes = []
    for kx in np.linspace(-W / 2, W / 2, n_k + 2)[1:-1]:
        meshes, mo = rotary_knob(rng, float(kx), ky, zf, r_max)
        kn = Node("knob", "knob", [], meshes)
        knob_nodes.append(kn)
        links.append(LinkSpec("knob", "knob", [kn], mo))
    tray_nodes = []
    if has_tray:
        c = rng.uniform(0.005, 0.012)
        tt = rng.uniform(0.006, 0.012)
        ty = cavity.y0 + rng.uniform(0.3, 0.6) * cavity.h
        bz0 = z_in + rng.uniform(0.01, 0.03)
        tray = box((cavity.x0 + c, ty, bz0), (cavity.x1 - c, ty + tt, zf - c))
        tn = Node("tray", "tray", [], [tray])
        tray_nodes.append(tn)
        travel = rng.uniform(0.4, 0.8) * (zf - c - bz0)
        mo = Motion(
            "slider",
            ((cavity.x0 + cavity.x1) / 2, ty + tt / 2, (bz0 + zf - c) / 2),
            FRONT,
            (0.0, travel),
        )
        links.append(LinkSpec("tray", "translation_tray", [tn], mo))
    if has_feet:
        walls += feet(rng, -W / 2, W / 2, -D / 2, D / 2, hb)
    root.children = [
        door_node,
        *knob_nodes,
        *tray_nodes,
        *nodes_after,
        Node("base_body", "base_body", [], walls),
    ]
    params = {
        "width": W,
        "height": H,
        "depth": D,
        "wall": tw,
        "door_thickness": td,
        "knobs": n_k,
        "drawer": has_drawer,
        "tray": has_tray,
        "feet": has_feet,
    }
    return SynthObject("Oven", root, links, "heavy", "oven_body", params)


def microwave(rng: np.random.Generator) -> SynthObject:
    """A microwave: cavity with a side (or bottom) hinged glass door, a control panel with
    1-2 rotary knobs and a display, and a turntable turning about the vertical axis.

    Randomised: size, walls, control panel width, door thickness and glass border, hinge
    (left 85 %, bottom 15 %), handle (bar or none), knobs, turntable size, feet.

    Parameters
    ----------
    rng : numpy.random.Generator

    Returns
    -------
    SynthObject
        In metres.
    """
    W = rng.uniform(0.45, 0.6)
    H = rng.uniform(0.26, 0.36)
    D = rng.uniform(0.33, 0.45)
    tw = rng.uniform(0.012, 0.025)
    td = rng.uniform(0.02, 0.04)
    has_feet = bool(rng.random() < 0.5)
    hb = rng.uniform(0.008, 0.02) if has_feet else 0.0
    y0, y1 = hb, hb + H
    zf, z_in = D / 2, -D / 2 + tw
    w_cp = rng.uniform(0.1, 0.16)
    xp = W / 2 - tw - w_cp  # divider between cavity and control compartment (its left face)
    reveal = rng.uniform(0.002, 0.004)

    root = Node("microwave", "Microwave")
    body = root.add(Node("body", "Body"))
    walls = body_walls(W, D, y0, y1, tw)
    walls.append(box((xp, y0 + tw, z_in), (xp + tw, y1 - tw, zf)))
    t_plate = rng.uniform(0.008, 0.02)
    walls.append(box((xp + tw, y0 + tw, zf - t_plate), (W / 2 - tw, y1 - tw, zf)))
    body.leaf("frame", "Frame", walls)
    links: list[LinkSpec] = []
    hinge = "left" if rng.random() < 0.85 else "bottom"
    door_rect = Rect(-W / 2, xp + tw / 2 - reveal / 2, y0, y1)
    border = min(rng.uniform(0.03, 0.07), 0.3 * door_rect.h)
    handle_style = "bar" if rng.random() < 0.6 else None
    limit = (
        round(float(rng.uniform(90, 120)), 2)
        if hinge == "left"
        else round(float(rng.uniform(80, 90)), 2)
    )
    g = door(rng, door_rect, zf, td, hinge, True, limit, handle_style, border)
    dn = body.add(g.node())
    links.append(LinkSpec("door", "door", [dn], g.motion))
    sc = body.add(Node("side_controls", "Side Controls"))
    cp_x = (xp + tw + W / 2 - tw) / 2
    n_k = int(rng.integers(1, 3))
    disp_h = rng.uniform(0.03, 0.05)
    disp_top = y1 - tw - 0.02
    sc.leaf(
        "display_panel",
        "Display Panel",
        [
            box(
                (cp_x - 0.35 * w_cp, disp_top - disp_h, zf),
                (cp_x + 0.35 * w_cp, disp_top, zf + rng.uniform(0.002, 0.005)),
            )
        ],
    )
    ky_hi = disp_top - disp_h - 0.01
    for ky in np.linspace(y0 + tw, ky_hi, n_k + 2)[1:-1]:
        meshes, mo = rotary_knob(
            rng, cp_x, float(ky), zf, 0.35 * min(w_cp, (ky_hi - y0 - tw) / (n_k + 1))
        )
        kn = sc.leaf("control_button", "Control Button", meshes)
        links.append(LinkSpec("control_button", "knob", [kn], mo))
    # turntable on the cavity floor, turning about the vertical axis through its centre
    cav = Rect(-W / 2 + tw, xp, z_in, zf)  # x and z extents of the cavity floor
    c = rng.uniform(0.01, 0.025)
    r_t = min(cav.w, cav.h) / 2 - c
    t_t = rng.uniform(0.005, 0.01)
    centre = (cav.cx, y0 + tw, cav.cy)
    interior = body.add(Node("body_interior", "Body Interior"))
    tray = interior.leaf("tray", "Tray", [cylinder(r_t, 0.0, t_t, centre, "y", 48)])
    links.append(LinkSpec("tray", "rotation_tray", [tray], Motion("hinge", centre, UP, None)))
    if has_feet:
        body_base(rng, root, W, D, hb, "feet")
    params = {
        "width": W,
        "height": H,
        "depth": D,
        "wall": tw,
        "door_thickness": td,
        "hinge": hinge,
        "knobs": n_k,
        "feet": has_feet,
        "handle": handle_style,
    }
    return SynthObject("Microwave", root, links, "heavy", "microwave_body", params)


def dishwasher(rng: np.random.Generator) -> SynthObject:
    """A dishwasher: bottom-hinged door, optional control panel strip above it, 1-2 sliding
    racks (``shelf``) inside.

    Randomised: size, walls, door thickness, control strip, handle, rack count and heights,
    rack travel, base (feet or plinth), door limit.

    Parameters
    ----------
    rng : numpy.random.Generator

    Returns
    -------
    SynthObject
        In metres.
    """
    W = rng.uniform(0.45, 0.6)
    H = rng.uniform(0.78, 0.87)
    D = rng.uniform(0.55, 0.62)
    tw = rng.uniform(0.02, 0.035)
    td = rng.uniform(0.04, 0.07)
    base_kind = str(rng.choice(["feet", "surface"]))
    hb = rng.uniform(0.02, 0.08)
    y0, y1 = hb, hb + H
    zf, z_in = D / 2, -D / 2 + tw
    strip = bool(rng.random() < 0.6)
    reveal = rng.uniform(0.002, 0.004)

    root = Node("dishwasher", "Dish Washer")
    body = root.add(Node("body", "Body"))
    walls = body_walls(W, D, y0, y1, tw)
    top_in = y1 - tw
    if strip:
        h_s = rng.uniform(0.06, 0.1)
        walls.append(box((-W / 2 + tw, top_in - h_s - tw, z_in), (W / 2 - tw, top_in - h_s, zf)))
        sc = body.add(Node("side_controls", "Side Controls"))
        sc.leaf(
            "control_panel",
            "Control Panel",
            [box((-W / 2 + tw, top_in - h_s, zf - 0.015), (W / 2 - tw, top_in, zf))],
        )
        door_top = top_in - h_s - tw / 2 - reveal / 2
        cav_top = top_in - h_s - tw
    else:
        door_top = y1
        cav_top = top_in
    body.children.insert(0, Node("frame", "Frame", [], walls))
    links: list[LinkSpec] = []
    rect = Rect(-W / 2, W / 2, y0, door_top)
    g = door(rng, rect, zf, td, "bottom", True, round(float(rng.uniform(80, 90)), 2), "bar")
    dn = body.add(g.node())
    links.append(LinkSpec("door", "rotation_door", [dn], g.motion))
    cav = Rect(-W / 2 + tw, W / 2 - tw, y0 + tw, cav_top)
    n_r = int(rng.integers(1, 3))
    interior = body.add(Node("body_interior", "Body Interior"))
    c = rng.uniform(0.008, 0.02)
    for frac in np.linspace(0, 1, n_r + 1)[:-1]:
        ry = cav.y0 + c + frac * cav.h + rng.uniform(0.0, 0.1) * cav.h / n_r
        wall_h = min(rng.uniform(0.06, 0.14), cav.h / n_r * 0.6)
        lo = np.array([cav.x0 + c, ry, z_in + c])
        hi = np.array([cav.x1 - c, ry + wall_h, zf - c])
        rack = interior.leaf(
            "shelf", "Shelf", list(open_box(lo, hi, rng.uniform(0.004, 0.008)).values())
        )
        travel = rng.uniform(0.5, 0.85) * (hi[2] - lo[2])
        mo = Motion("slider", (lo + hi) / 2, FRONT, (0.0, travel))
        links.append(LinkSpec("shelf", "shelf", [rack], mo))
    body_base(rng, root, W, D, hb, base_kind)
    params = {
        "width": W,
        "height": H,
        "depth": D,
        "wall": tw,
        "door_thickness": td,
        "strip": strip,
        "racks": n_r,
        "base": base_kind,
    }
    return SynthObject("Dishwasher", root, links, "heavy", "dishwasher_body", params)
