"""Furniture: StorageFurniture (cabinets with doors, flaps and drawers) and Table (desks with
apron drawers).

Both are built as PartNet annotates them (``storage_furniture -> cabinet -> cabinet_frame /
cabinet_door / drawer / shelf / cabinet_base``; ``table -> desk -> tabletop / drawer_base``)
in metres, y-up, front +z; :func:`kinmo.synth.normalize` rescales them afterwards.
"""

from __future__ import annotations

import numpy as np

from kinmo.synth.assembly import LinkSpec, Node, SynthObject
from kinmo.synth.components import DoorGeometry, Rect, door, drawer, foot_base, shell
from kinmo.synth.primitives import box

#: Gap between neighbouring overlay fronts (metres).
_REVEAL = (0.002, 0.004)


def _split(rng: np.random.Generator, total: float, k: int, jitter: float) -> np.ndarray:
    """``k`` positive widths summing to ``total``, each within ``1 +- jitter`` of equal."""
    w = 1.0 + rng.uniform(-jitter, jitter, size=k)
    return total * w / w.sum()


def _outer_limit(rng: np.random.Generator) -> float:
    """Opening angle of a side door hinged on an outer edge (degrees, 90-180)."""
    return round(float(rng.uniform(90.0, 180.0)), 2)


def _cabinet_door(cab: Node, links: list[LinkSpec], g: DoorGeometry) -> None:
    """Add a door (or flap) of a cabinet: its subtree under ``cab`` and its link."""
    dn = cab.add(
        g.node("cabinet_door", "Cabinet door", ("cabinet_door_surface", "Cabinet door surface"))
    )
    links.append(LinkSpec("cabinet_door", "rotation_door", [dn], g.motion))


def storage_furniture(rng: np.random.Generator) -> SynthObject:
    """A cabinet: carcass, 1-3 columns of doors, flaps, drawers or open shelves, a base.

    Randomised: outer size (0.4-1.6 m wide, 0.4-2.0 m tall, 0.3-0.65 m deep), panel and
    back thickness, base (none, four feet, plinth), column count and widths, per column a
    layout (door cell with one or two doors, drawer stack, drawers above a door, a flap hinged
    at the bottom or top, open shelves), hinge sides, handle styles (bar/knob) and sizes,
    inner shelves, door opening limits, drawer travel.

    Parameters
    ----------
    rng : numpy.random.Generator

    Returns
    -------
    SynthObject
        In metres (not normalised).
    """
    W = rng.uniform(0.4, 1.6)
    H = rng.uniform(0.4, 2.0)
    D = rng.uniform(0.3, 0.65)
    t = rng.uniform(0.012, 0.025)
    tb = rng.uniform(0.004, 0.012)
    base = str(rng.choice(["none", "feet", "plinth"], p=[0.4, 0.3, 0.3]))
    hb = 0.0 if base == "none" else rng.uniform(0.03, 0.1)
    y0, y1 = hb, hb + H
    zf, zb = D / 2, -D / 2
    handle_style = str(rng.choice(["bar", "knob"], p=[0.7, 0.3]))
    t_door = rng.uniform(0.015, 0.025)

    root = Node("storage_furniture", "Storage Furniture")
    cab = root.add(Node("cabinet", "Cabinet"))
    frame = cab.add(Node("cabinet_frame", "Cabinet frame"))
    walls = shell(np.array([-W / 2, y0, zb]), np.array([W / 2, y1, zf]), t, tb)
    frame.leaf("vertical_side_panel", "Vertical side panel", [walls["left"]])
    frame.leaf("vertical_side_panel", "Vertical side panel", [walls["right"]])
    frame.leaf("top_panel", "Top panel", [walls["top"]])
    frame.leaf("bottom_panel", "Bottom panel", [walls["bottom"]])
    frame.leaf("back_panel", "Back panel", [walls["back"]])
    z_in = zb + tb  # front face of the back panel
    depth = zf - z_in

    # columns: divider centres between them
    max_cols = 1 if W < 0.6 else (2 if W < 1.0 else 3)
    n_cols = int(rng.integers(1, max_cols + 1))
    inner_w = W - 2 * t - (n_cols - 1) * t
    widths = _split(rng, inner_w, n_cols, 0.25)
    cols = []  # (inner x0, inner x1, front x0, front x1, outer_left, outer_right)
    x = -W / 2 + t
    reveal = rng.uniform(*_REVEAL)
    for c in range(n_cols):
        xa, xb = x, x + widths[c]
        fx0 = -W / 2 if c == 0 else xa - t / 2 + reveal / 2
        fx1 = W / 2 if c == n_cols - 1 else xb + t / 2 - reveal / 2
        cols.append((xa, xb, fx0, fx1, c == 0, c == n_cols - 1))
        if c < n_cols - 1:
            frame.leaf(
                "vertical_divider_panel",
                "Vertical divider panel",
                [box((xb, y0 + t, z_in), (xb + t, y1 - t, zf))],
            )
        x = xb + t

    links: list[LinkSpec] = []
    layouts = []
    inner_h = H - 2 * t
    for xa, xb, fx0, fx1, out_l, out_r in cols:
        cw = xb - xa
        options = ["doors", "drawers", "mixed", "open"]
        probs = [0.4, 0.3, 0.22, 0.08]
        if inner_h < 0.7 and cw > 0.3:
            options.append("flap")
            probs = [0.3, 0.25, 0.15, 0.05, 0.25]
        lay = str(rng.choice(options, p=probs))
        layouts.append(lay)
        # rows as (kind, inner height); bottom to top
        if lay == "drawers":
            k = int(np.clip(round(inner_h / rng.uniform(0.15, 0.3)), 1, 6))
            rows = [("drawer", h) for h in _split(rng, inner_h - (k - 1) * t, k, 0.15)]
        elif lay == "mixed" and inner_h > 0.45:
            k = int(rng.integers(1, 3))
            hd = rng.uniform(0.12, 0.22)
            hd = min(hd, (inner_h - k * t) / (k + 1.5))
            rows = [("door", inner_h - k * (hd + t))] + [("drawer", hd)] * k
        elif lay == "flap":
            rows = [("flap", inner_h)]
        elif lay == "open":
            rows = [("open", inner_h)]
        else:
            rows = [("door", inner_h)]
        y = y0 + t
        for r, (kind, h) in enumerate(rows):
            ya, yb = y, y + h
            bottom_outer, top_outer = r == 0, r == len(rows) - 1
            fy0 = y0 if bottom_outer else ya - t / 2 + reveal / 2
            fy1 = y1 if top_outer else yb + t / 2 - reveal / 2
            opening = Rect(xa, xb, ya, yb)
            front = Rect(fx0, fx1, fy0, fy1)
            if r < len(rows) - 1:
                cab.leaf("shelf", "Shelf", [box((xa, yb, z_in), (xb, yb + t, zf))])
            if kind in ("door", "open", "flap") and h > 0.35:
                # inner shelves, set back from the front so nothing touches the door
                n_sh = int(rng.integers(0, 1 + min(3, int(h / 0.3))))
                setback = rng.uniform(0.01, 0.04)
                for ys in np.linspace(ya, yb, n_sh + 2)[1:-1]:
                    cab.leaf(
                        "shelf",
                        "Shelf",
                        [box((xa, ys - t / 2, z_in), (xb, ys + t / 2, zf - setback))],
                    )
            if kind == "drawer":
                g = drawer(rng, opening, zf, depth, front, t_door, handle_style)
                cab.add(node := g.node())
                links.append(LinkSpec("drawer", "drawer", [node], g.motion))
            elif kind == "door":
                pair = front.w > 0.6 or (front.w > 0.45 and rng.random() < 0.5)
                if pair:
                    mid = front.cx
                    halves = [
                        (Rect(front.x0, mid - reveal / 2, front.y0, front.y1), "left", out_l),
                        (Rect(mid + reveal / 2, front.x1, front.y0, front.y1), "right", out_r),
                    ]
                else:
                    if out_l and not out_r:
                        side = "left" if rng.random() < 0.8 else "right"
                    elif out_r and not out_l:
                        side = "right" if rng.random() < 0.8 else "left"
                    else:
                        side = str(rng.choice(["left", "right"]))
                    halves = [(front, side, out_l if side == "left" else out_r)]
                for rect, side, outer in halves:
                    lim = _outer_limit(rng) if outer else 90.0
                    g = door(rng, rect, zf, t_door, side, outer, lim, handle_style)
                    _cabinet_door(cab, links, g)
            elif kind == "flap":
                side = str(rng.choice(["bottom", "top"]))
                outer = bottom_outer if side == "bottom" else top_outer
                g = door(
                    rng,
                    front,
                    zf,
                    t_door,
                    side,
                    outer,
                    round(float(rng.uniform(75, 90)), 2),
                    handle_style,
                )
                _cabinet_door(cab, links, g)
            y = yb + t

    if not links:  # guarantee one moving part: a door on the first column
        xa, xb, fx0, fx1, out_l, _ = cols[0]
        g = door(rng, Rect(fx0, fx1, y0, y1), zf, t_door, "left", out_l, 90.0, handle_style)
        _cabinet_door(cab, links, g)

    if base != "none":
        cb = cab.add(Node("cabinet_base", "Cabinet Base"))
        if base == "feet":
            cb.add(foot_base(rng, -W / 2, W / 2, zb, zf, hb))
        else:
            pb = cb.add(Node("panel_base", "Panel Base"))
            sb = rng.uniform(0.0, 0.05)  # front setback
            ss = rng.uniform(0.0, 0.03)  # side setback
            tp = t
            xa, xb = -W / 2 + ss, W / 2 - ss
            za, zc = zb + ss, zf - sb
            pb.leaf("base_side_panel", "Base side panel", [box((xa, 0, zc - tp), (xb, hb, zc))])
            pb.leaf("base_side_panel", "Base side panel", [box((xa, 0, za), (xb, hb, za + tp))])
            pb.leaf(
                "base_side_panel",
                "Base side panel",
                [box((xa, 0, za + tp), (xa + tp, hb, zc - tp))],
            )
            pb.leaf(
                "base_side_panel",
                "Base side panel",
                [box((xb - tp, 0, za + tp), (xb, hb, zc - tp))],
            )

    params = {
        "width": W,
        "height": H,
        "depth": D,
        "panel": t,
        "back": tb,
        "base": base,
        "columns": n_cols,
        "layouts": layouts,
        "handle": handle_style,
        "door_thickness": t_door,
    }
    return SynthObject("StorageFurniture", root, links, "heavy", "furniture_body", params)


def table(rng: np.random.Generator) -> SynthObject:
    """A desk: tabletop on four legs, aprons, and 1-3 inset drawers under the top.

    Randomised: top size (0.8-1.6 x 0.5-0.85 m) and thickness, height, overhang, leg size,
    apron height, drawer count and widths, handle style, optional side stretchers, drawer
    travel.

    Parameters
    ----------
    rng : numpy.random.Generator

    Returns
    -------
    SynthObject
        In metres (not normalised).
    """
    W = rng.uniform(0.8, 1.6)
    D = rng.uniform(0.5, 0.85)
    H = rng.uniform(0.68, 0.78)
    t_top = rng.uniform(0.02, 0.04)
    o = rng.uniform(0.0, 0.06)
    s = rng.uniform(0.035, 0.06)
    a = rng.uniform(0.1, 0.17)
    ta = min(rng.uniform(0.015, 0.025), 0.6 * s)
    ts = rng.uniform(0.008, 0.015)
    td = rng.uniform(0.012, 0.02)
    handle_style = str(rng.choice(["bar", "knob"], p=[0.6, 0.4]))
    xl, zl = W / 2 - o, D / 2 - o  # outer faces of the legs
    yt = H - t_top  # underside of the top
    ya = yt - a  # bottom of the aprons

    root = Node("table", "Table")
    desk = root.add(Node("desk", "Desk"))
    top = desk.add(Node("tabletop", "Tabletop"))
    surf = top.add(Node("tabletop_surface", "Tabletop surface"))
    surf.leaf("board", "Board", [box((-W / 2, yt, -D / 2), (W / 2, H, D / 2))])
    base = desk.add(Node("drawer_base", "Drawer Base"))
    for sx in (-1, 1):
        for sz in (-1, 1):
            lx = (xl - s, xl) if sx > 0 else (-xl, -xl + s)
            lz = (zl - s, zl) if sz > 0 else (-zl, -zl + s)
            base.leaf("leg", "Leg", [box((lx[0], 0.0, lz[0]), (lx[1], yt, lz[1]))])
    base.leaf(
        "vertical_side_panel",
        "Vertical side panel",
        [box((-xl, ya, -zl + s), (-xl + ta, yt, zl - s))],
    )
    base.leaf(
        "vertical_side_panel",
        "Vertical side panel",
        [box((xl - ta, ya, -zl + s), (xl, yt, zl - s))],
    )
    base.leaf("back_panel", "Back panel", [box((-xl + s, ya, -zl), (xl - s, yt, -zl + ta))])
    base.leaf("shelf", "Shelf", [box((-xl + s, ya, -zl + ta), (xl - s, ya + ts, zl))])
    inner = 2 * (xl - s)
    k = int(rng.integers(1, 1 + max(1, min(3, int(inner / 0.35)))))
    widths = _split(rng, inner - (k - 1) * td, k, 0.2)
    links: list[LinkSpec] = []
    x = -xl + s
    depth = 2 * zl - ta
    for i in range(k):
        opening = Rect(x, x + widths[i], ya + ts, yt)
        g = drawer(rng, opening, zl, depth, None, rng.uniform(0.012, 0.02), handle_style)
        base.add(node := g.node())
        links.append(LinkSpec("drawer", "drawer", [node], g.motion))
        x += widths[i]
        if i < k - 1:
            other = base.add(Node("other", "Drawer divider (other)"))
            other.leaf("other_leaf", "other_leaf", [box((x, ya + ts, -zl + ta), (x + td, yt, zl))])
            x += td
    stretch = bool(rng.random() < 0.5)
    if stretch:
        hs = rng.uniform(0.02, 0.04)
        ys = rng.uniform(0.08, 0.25)
        w = s * 0.5
        for cx in (-xl + s / 2, xl - s / 2):
            base.leaf(
                "bar_stretcher",
                "Bar Stretcher",
                [box((cx - w / 2, ys, -zl + s), (cx + w / 2, ys + hs, zl - s))],
            )
    params = {
        "width": W,
        "depth": D,
        "height": H,
        "top": t_top,
        "overhang": o,
        "leg": s,
        "apron": a,
        "drawers": k,
        "handle": handle_style,
        "stretchers": stretch,
    }
    return SynthObject("Table", root, links, "heavy", "furniture_body", params)
