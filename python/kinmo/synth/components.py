"""Reusable components: handles, hinged doors, drawers, box shells, open boxes, cups, feet.

All components are built in the object frame (y-up, front +z, metres) against a *front
plane* ``z = z_front``: the front face of the carcass they belong to. Overlay doors and drawer
fronts sit in front of it, touching it; inset ones sit inside the opening, flush with it.
Every mesh is a closed box or solid of revolution; parts of different components touch but
never overlap, and moving a component to its joint limits keeps it clear of its carcass
(hinges are placed on the door edge that keeps the swept volume outside the carcass, see
:func:`door`).

Length: over 500 lines, about 40 % of them docstrings: every component follows the front-plane
convention above (touching, never overlapping, clear of its carcass at its joint limits), which
the door, drawer, handle and shell code rely on together; splitting them would spread one
convention over several files.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import trimesh

from kinmo.synth.assembly import Motion, Node
from kinmo.synth.primitives import box, cylinder, lathe

#: Unit outward normal of every front plane.
FRONT = np.array([0.0, 0.0, 1.0])


@dataclass(frozen=True)
class Rect:
    """An axis-aligned rectangle of a front plane (metres): ``x0 < x1``, ``y0 < y1``."""

    x0: float
    x1: float
    y0: float
    y1: float

    @property
    def w(self) -> float:
        """Width (x extent)."""
        return self.x1 - self.x0

    @property
    def h(self) -> float:
        """Height (y extent)."""
        return self.y1 - self.y0

    @property
    def cx(self) -> float:
        """Centre x."""
        return (self.x0 + self.x1) / 2.0

    @property
    def cy(self) -> float:
        """Centre y."""
        return (self.y0 + self.y1) / 2.0

    def shrink(self, dx: float, dy: float | None = None) -> Rect:
        """The rectangle shrunk by ``dx`` on the left and right and ``dy`` top and bottom."""
        dy = dx if dy is None else dy
        return Rect(self.x0 + dx, self.x1 - dx, self.y0 + dy, self.y1 - dy)


def top_handle(
    rng: np.random.Generator,
    cx: float,
    cz: float,
    y_face: float,
    along: str,
    max_len: float,
    style: str,
) -> list[trimesh.Trimesh]:
    """A handle on a top face ``y = y_face`` (protruding towards +y), e.g. on a lid.

    Built as :func:`handle` on a front face, then turned by the rotation taking +z to +y
    (and +y to -z).

    Parameters
    ----------
    rng : numpy.random.Generator
    cx, cz : float
        Centre of the handle on the face (metres).
    y_face : float
        The top face plane.
    along : {"x", "z"}
        Direction of a bar handle.
    max_len : float
        Longest bar allowed (metres).
    style : {"bar", "knob"}

    Returns
    -------
    list of trimesh.Trimesh
        Closed meshes touching each other and the face.
    """
    meshes = handle(rng, cx, -cz, 0.0, "y" if along == "z" else "x", max_len, style)
    T = np.array([[1.0, 0, 0, 0], [0, 0, 1.0, y_face], [0, -1.0, 0, 0], [0, 0, 0, 1.0]])
    for m in meshes:
        m.apply_transform(T)
    return meshes


def handle(
    rng: np.random.Generator,
    cx: float,
    cy: float,
    z_face: float,
    along: str,
    max_len: float,
    style: str,
) -> list[trimesh.Trimesh]:
    """A handle on a front face: a bar on two posts (3 meshes) or a knob (2 meshes).

    Parameters
    ----------
    rng : numpy.random.Generator
        Sizes are drawn from it.
    cx, cy : float
        Centre of the handle on the face (metres).
    z_face : float
        The face plane the handle stands on (it protrudes towards +z).
    along : {"x", "y"}
        Direction of a bar handle.
    max_len : float
        Longest bar allowed (metres); the bar is shortened to it.
    style : {"bar", "knob"}

    Returns
    -------
    list of trimesh.Trimesh
        Closed meshes touching each other and the face, none overlapping.

    Raises
    ------
    ValueError
        Unknown ``style`` or ``along``.
    """
    if style == "knob":
        r_stem = rng.uniform(0.005, 0.008)
        l_stem = rng.uniform(0.012, 0.022)
        r_head = rng.uniform(0.012, 0.02)
        t_head = rng.uniform(0.008, 0.014)
        c = (cx, cy, 0.0)
        return [
            cylinder(r_stem, z_face, z_face + l_stem, c, "z", 24),
            cylinder(r_head, z_face + l_stem, z_face + l_stem + t_head, c, "z", 24),
        ]
    if style != "bar":
        raise ValueError(f"handle style must be 'bar' or 'knob', got {style!r}")
    length = min(max_len, rng.uniform(0.08, 0.32))
    sect = rng.uniform(0.01, 0.018)
    standoff = rng.uniform(0.02, 0.04)
    r_post = sect * rng.uniform(0.3, 0.45)
    inset = length * rng.uniform(0.08, 0.18) + r_post
    z0, z1 = z_face + standoff, z_face + standoff + sect
    if along == "y":
        bar = box((cx - sect / 2, cy - length / 2, z0), (cx + sect / 2, cy + length / 2, z1))
        posts = [(cx, cy - length / 2 + inset), (cx, cy + length / 2 - inset)]
    elif along == "x":
        bar = box((cx - length / 2, cy - sect / 2, z0), (cx + length / 2, cy + sect / 2, z1))
        posts = [(cx - length / 2 + inset, cy), (cx + length / 2 - inset, cy)]
    else:
        raise ValueError(f"along must be 'x' or 'y', got {along!r}")
    return [bar] + [cylinder(r_post, z_face, z0, (px, py, 0.0), "z", 16) for px, py in posts]


#: Unit vector from the hinge line towards the free edge, per hinge side.
_HINGE_U = {
    "left": np.array([1.0, 0.0, 0.0]),
    "right": np.array([-1.0, 0.0, 0.0]),
    "bottom": np.array([0.0, 1.0, 0.0]),
    "top": np.array([0.0, -1.0, 0.0]),
}


def hinge_motion(rect: Rect, z_hinge: float, side: str, limit_deg: float) -> Motion:
    """The hinge of a panel covering ``rect``, hinged on its ``side`` edge at ``z_hinge``.

    The direction is ``u x n`` (``u`` from the hinge towards the free edge, ``n = +z``), so
    a positive angle swings the panel outward; the origin is the midpoint of the hinge edge.

    Parameters
    ----------
    rect : Rect
    z_hinge : float
        Depth of the hinge line (back or front face of the panel).
    side : {"left", "right", "bottom", "top"}
    limit_deg : float
        Opening angle, degrees (> 0).

    Returns
    -------
    Motion
    """
    u = _HINGE_U[side]
    origin = {
        "left": (rect.x0, rect.cy, z_hinge),
        "right": (rect.x1, rect.cy, z_hinge),
        "bottom": (rect.cx, rect.y0, z_hinge),
        "top": (rect.cx, rect.y1, z_hinge),
    }[side]
    return Motion("hinge", np.array(origin), np.cross(u, FRONT), (0.0, float(limit_deg)))


@dataclass
class DoorGeometry:
    """Meshes and motion of a hinged door (see :func:`door`)."""

    surface: list[trimesh.Trimesh]
    glass: list[trimesh.Trimesh]
    handle: list[trimesh.Trimesh]
    motion: Motion
    params: dict = field(default_factory=dict)

    def node(
        self,
        name: str = "door",
        text: str = "Door",
        surface: tuple[str, str] = ("door_frame", "Door Frame"),
        glass: tuple[str, str] = ("glass", "Door Glass"),
    ) -> Node:
        """The PartNet subtree ``door -> {door_frame, glass, handle}``.

        The glass leaf is there only for a glass door, the handle leaf only for a door with a
        handle.

        Parameters
        ----------
        name, text : str
            Semantic name and label of the door node (``"cabinet_door"``, ``"Cabinet door"``).
        surface : (str, str)
            Name and label of the leaf of the door panel (or glass door frame).
        glass : (str, str)
            Name and label of the glass leaf.
        """
        d = Node(name, text)
        d.leaf(*surface, self.surface)
        if self.glass:
            d.leaf(*glass, self.glass)
        if self.handle:
            d.leaf("handle", "Handle", self.handle)
        return d

    def meshes(self) -> list[trimesh.Trimesh]:
        """All meshes (surface, glass, handle)."""
        return [*self.surface, *self.glass, *self.handle]


def door(
    rng: np.random.Generator,
    rect: Rect,
    z_back: float,
    thickness: float,
    side: str,
    outer_hinge: bool,
    limit_deg: float,
    handle_style: str | None,
    glass_border: float | None = None,
) -> DoorGeometry:
    """A door covering ``rect`` whose back face lies on ``z = z_back``.

    Hinge placement keeps the swing clear of the carcass: on an *outer* edge of the carcass
    (nothing beyond it) the hinge line is the back edge of the door, as in PartNet-Mobility,
    and any angle up to 180 degrees is collision-free; on an inner edge (a neighbour beyond
    the hinge) it is the front edge, and angles up to 90 degrees never cross the hinge plane.

    Parameters
    ----------
    rng : numpy.random.Generator
    rect : Rect
        Extent of the door in the front plane.
    z_back : float
        Back face of the door (the carcass front plane for overlay doors).
    thickness : float
        Door thickness (metres).
    side : {"left", "right", "bottom", "top"}
        Hinge edge.
    outer_hinge : bool
        Whether the hinge edge is on the outer boundary of the carcass.
    limit_deg : float
        Opening angle in degrees.
    handle_style : {"bar", "knob"} or None
        Handle near the free edge, or none.
    glass_border : float or None
        If given, the door is a frame of this border width around a glass pane (4 frame
        meshes + 1 pane, the pane thinner than the frame and centred in depth).

    Returns
    -------
    DoorGeometry
    """
    z_front = z_back + thickness
    if glass_border is None:
        surface = [box((rect.x0, rect.y0, z_back), (rect.x1, rect.y1, z_front))]
        glass: list[trimesh.Trimesh] = []
    else:
        b = glass_border
        inner = rect.shrink(b)
        surface = [
            box((rect.x0, rect.y0, z_back), (rect.x1, inner.y0, z_front)),
            box((rect.x0, inner.y1, z_back), (rect.x1, rect.y1, z_front)),
            box((rect.x0, inner.y0, z_back), (inner.x0, inner.y1, z_front)),
            box((inner.x1, inner.y0, z_back), (rect.x1, inner.y1, z_front)),
        ]
        tg = thickness * 0.4
        zc = z_back + thickness / 2
        glass = [box((inner.x0, inner.y0, zc - tg / 2), (inner.x1, inner.y1, zc + tg / 2))]
    handles: list[trimesh.Trimesh] = []
    if handle_style is not None:
        inset = min(
            rng.uniform(0.035, 0.07), 0.2 * (rect.w if side in ("left", "right") else rect.h)
        )
        if glass_border is not None:  # keep the handle on the frame, clear of the glass
            inset = glass_border / 2
        if side in ("left", "right"):
            hx = rect.x1 - inset if side == "left" else rect.x0 + inset
            # tall doors: handle at a comfortable height, else centred
            hy = rect.cy if rect.h < 0.9 else min(rect.y1 - 0.35, max(rect.y0 + 0.35, 1.0))
            handles = handle(rng, hx, hy, z_front, "y", 0.6 * rect.h, handle_style)
        else:
            hy = rect.y1 - inset if side == "bottom" else rect.y0 + inset
            handles = handle(rng, rect.cx, hy, z_front, "x", 0.6 * rect.w, handle_style)
    z_hinge = z_back if outer_hinge else z_front
    motion = hinge_motion(rect, z_hinge, side, limit_deg)
    return DoorGeometry(
        surface,
        glass,
        handles,
        motion,
        {
            "side": side,
            "outer_hinge": outer_hinge,
            "limit_deg": float(limit_deg),
            "handle": handle_style,
            "glass": glass_border is not None,
        },
    )


@dataclass
class DrawerGeometry:
    """Meshes and motion of a drawer (see :func:`drawer`)."""

    front: trimesh.Trimesh
    sides: list[trimesh.Trimesh]
    back: trimesh.Trimesh
    bottom: trimesh.Trimesh
    handle: list[trimesh.Trimesh]
    motion: Motion
    params: dict = field(default_factory=dict)

    def node(self, with_box_node: bool = True) -> Node:
        """The PartNet subtree ``drawer -> drawer_box -> {front, sides, back, bottom}, handle``.

        Parameters
        ----------
        with_box_node : bool
            False: the box leaves hang directly under ``drawer`` (no ``drawer_box``).
        """
        d = Node("drawer", "Drawer")
        parent = d.add(Node("drawer_box", "Drawer box")) if with_box_node else d
        parent.leaf("drawer_front", "Drawer front", [self.front])
        for s in self.sides:
            parent.leaf("drawer_side", "Drawer side", [s])
        parent.leaf("drawer_back", "Drawer back", [self.back])
        parent.leaf("drawer_bottom", "Drawer bottom", [self.bottom])
        if self.handle:
            d.leaf("handle", "Handle", self.handle)
        return d

    def meshes(self) -> list[trimesh.Trimesh]:
        """All meshes (front, sides, back, bottom, handle)."""
        return [self.front, *self.sides, self.back, self.bottom, *self.handle]


def drawer(
    rng: np.random.Generator,
    opening: Rect,
    z_front: float,
    depth: float,
    front_rect: Rect | None,
    t_front: float,
    handle_style: str | None,
) -> DrawerGeometry:
    """A drawer in a rectangular opening of a carcass, sliding out along +z.

    Parameters
    ----------
    rng : numpy.random.Generator
    opening : Rect
        The inner opening of the carcass cell (panel faces, metres).
    z_front : float
        Carcass front plane.
    depth : float
        Free depth behind the front plane (metres).
    front_rect : Rect or None
        Overlay front covering this rectangle in front of ``z_front``; ``None`` for an inset
        front inside the opening, flush with ``z_front``.
    t_front : float
        Front panel thickness.
    handle_style : {"bar", "knob"} or None

    Returns
    -------
    DrawerGeometry
        Slider along +z through the drawer centre, limits ``(0, travel)`` with travel 55-90%
        of the box depth (the drawer stays in its slot).
    """
    c_side = rng.uniform(0.003, 0.008)
    tb = min(rng.uniform(0.008, 0.015), 0.2 * opening.w, 0.2 * opening.h)
    if front_rect is None:
        gap = rng.uniform(0.002, 0.004)
        fr = opening.shrink(gap)
        front = box((fr.x0, fr.y0, z_front - t_front), (fr.x1, fr.y1, z_front))
        z_box = z_front - t_front
        face = z_front
    else:
        fr = front_rect
        front = box((fr.x0, fr.y0, z_front), (fr.x1, fr.y1, z_front + t_front))
        z_box = z_front
        face = z_front + t_front
    bx0, bx1 = opening.x0 + c_side, opening.x1 - c_side
    top_gap = min(rng.uniform(0.01, 0.04), 0.25 * opening.h)
    by0, by1 = opening.y0 + c_side, opening.y1 - top_gap
    back_clear = rng.uniform(0.005, 0.03)
    bz0 = z_front - depth + back_clear
    sides = [
        box((bx0, by0, bz0), (bx0 + tb, by1, z_box)),
        box((bx1 - tb, by0, bz0), (bx1, by1, z_box)),
    ]
    back = box((bx0 + tb, by0, bz0), (bx1 - tb, by1, bz0 + tb))
    bottom = box((bx0 + tb, by0, bz0 + tb), (bx1 - tb, by0 + tb, z_box))
    handles: list[trimesh.Trimesh] = []
    if handle_style is not None:
        handles = handle(rng, fr.cx, fr.cy, face, "x", 0.7 * fr.w, handle_style)
    box_depth = z_box - bz0
    travel = box_depth * rng.uniform(0.55, 0.9)
    centre = np.array([(bx0 + bx1) / 2, (by0 + by1) / 2, (bz0 + z_box) / 2])
    motion = Motion("slider", centre, FRONT, (0.0, float(travel)))
    return DrawerGeometry(
        front,
        sides,
        back,
        bottom,
        handles,
        motion,
        {
            "overlay": front_rect is not None,
            "handle": handle_style,
            "travel": float(travel),
        },
    )


def shell(lo: np.ndarray, hi: np.ndarray, t: float, t_back: float) -> dict[str, trimesh.Trimesh]:
    """A box open at the front (+z): 5 walls touching each other, not overlapping.

    Parameters
    ----------
    lo, hi : (3,) float
        Outer bounds (metres).
    t : float
        Thickness of the side, top and bottom walls.
    t_back : float
        Thickness of the back wall.

    Returns
    -------
    dict of str to trimesh.Trimesh
        ``left``, ``right`` (full height and depth), ``bottom``, ``top`` (between the sides,
        full depth), ``back`` (between the four).
    """
    x0, y0, z0 = lo
    x1, y1, z1 = hi
    return {
        "left": box((x0, y0, z0), (x0 + t, y1, z1)),
        "right": box((x1 - t, y0, z0), (x1, y1, z1)),
        "bottom": box((x0 + t, y0, z0), (x1 - t, y0 + t, z1)),
        "top": box((x0 + t, y1 - t, z0), (x1 - t, y1, z1)),
        "back": box((x0 + t, y0 + t, z0), (x1 - t, y1 - t, z0 + t_back)),
    }


def cup(
    r_bottom: float, r_top: float, height: float, wall: float, bottom: float, sections: int = 64
) -> trimesh.Trimesh:
    """A solid of revolution about +y open at the top: a (possibly tapered) pot, bucket or bin.

    Parameters
    ----------
    r_bottom, r_top : float
        Outer radius at the bottom (``y = 0``) and at the rim (``y = height``), metres.
    height : float
    wall : float
        Wall thickness, measured horizontally (the inner wall is the outer one moved inwards
        by ``wall``).
    bottom : float
        Bottom thickness.
    sections : int
        Segments around the axis.

    Returns
    -------
    trimesh.Trimesh
        Closed, one piece.
    """
    slope = (r_top - r_bottom) / height
    return lathe(
        [
            (0.0, 0.0),
            (r_bottom, 0.0),
            (r_top, height),
            (r_top - wall, height),
            (r_bottom - wall + slope * bottom, bottom),
            (0.0, bottom),
        ],
        sections=sections,
    )


def feet(
    rng: np.random.Generator, x0: float, x1: float, z0: float, z1: float, height: float
) -> list[trimesh.Trimesh]:
    """Four feet under a footprint, from ``y = 0`` up to ``height`` (touching the body).

    Parameters
    ----------
    rng : numpy.random.Generator
    x0, x1, z0, z1 : float
        Footprint of the body (metres).
    height : float
        Foot height.

    Returns
    -------
    list of trimesh.Trimesh
        Round or square feet inset from the corners.
    """
    s = min(rng.uniform(0.025, 0.05), 0.2 * (x1 - x0), 0.2 * (z1 - z0))
    inset = rng.uniform(0.01, 0.04)
    round_ = bool(rng.random() < 0.5)
    out = []
    for fx in (x0 + inset + s / 2, x1 - inset - s / 2):
        for fz in (z0 + inset + s / 2, z1 - inset - s / 2):
            if round_:
                out.append(cylinder(s / 2, 0.0, height, (fx, 0.0, fz), "y", 24))
            else:
                out.append(box((fx - s / 2, 0.0, fz - s / 2), (fx + s / 2, height, fz + s / 2)))
    return out


def foot_base(
    rng: np.random.Generator, x0: float, x1: float, z0: float, z1: float, height: float
) -> Node:
    """The PartNet subtree ``foot_base -> foot x 4`` of :func:`feet` (same arguments)."""
    fb = Node("foot_base", "Foot Base")
    for m in feet(rng, x0, x1, z0, z1, height):
        fb.leaf("foot", "Foot", [m])
    return fb


def open_box(
    lo: np.ndarray, hi: np.ndarray, t: float, t_bottom: float | None = None
) -> dict[str, trimesh.Trimesh]:
    """A box open at the top (+y): bottom and four walls, touching, not overlapping.

    Parameters
    ----------
    lo, hi : (3,) float
        Outer bounds (metres).
    t : float
        Wall thickness.
    t_bottom : float, optional
        Bottom thickness (default ``t``).

    Returns
    -------
    dict of str to trimesh.Trimesh
        ``bottom`` (full footprint), ``left``, ``right`` (full depth, on the bottom),
        ``back``, ``front`` (between the sides).
    """
    x0, y0, z0 = lo
    x1, y1, z1 = hi
    tb = t if t_bottom is None else t_bottom
    yb = y0 + tb
    return {
        "bottom": box((x0, y0, z0), (x1, yb, z1)),
        "left": box((x0, yb, z0), (x0 + t, y1, z1)),
        "right": box((x1 - t, yb, z0), (x1, y1, z1)),
        "back": box((x0 + t, yb, z0), (x1 - t, y1, z0 + t)),
        "front": box((x0 + t, yb, z1 - t), (x1 - t, y1, z1)),
    }
