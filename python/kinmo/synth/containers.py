"""Containers: Bucket (swinging bail handle), KitchenPot (lifting lid), Bottle (screw cap)
and TrashCan (hinged lid, foot pedal).

Solids of revolution about the vertical (y) axis, built with :func:`kinmo.synth.primitives.lathe`
so that coaxial parts (a cap around a neck, a lid skirt inside a pot) keep their clearance
after tessellation. Hierarchies follow SAPIEN's flat annotation for ``Bucket``,
``KitchenPot`` and ``TrashCan`` (``handle`` / ``lid`` / ``foot_pad`` + ``base_body``) and
PartNet's for bottles (``bottle -> normal_bottle -> body, neck, lid``).
"""

from __future__ import annotations

import numpy as np

from kinmo.synth.assembly import LinkSpec, Motion, Node, SynthObject
from kinmo.synth.components import cup, open_box, top_handle
from kinmo.synth.primitives import box, cylinder, lathe, tube

_UP = np.array([0.0, 1.0, 0.0])


def _arc(c: tuple[float, float], r: float, a0: float, a1: float, n: int) -> np.ndarray:
    """``n`` points of a circular arc in the x-y plane (z = 0), angles in degrees."""
    a = np.deg2rad(np.linspace(a0, a1, n))
    return np.stack([c[0] + r * np.cos(a), c[1] + r * np.sin(a), np.zeros(n)], axis=1)


def bucket(rng: np.random.Generator) -> SynthObject:
    """A (possibly tapered) bucket with a bail handle pivoting on pins at its rim.

    The handle is one swept tube: a pin entering towards the wall on each side (stopping
    just short of it), filleted into a semicircular bail over the top. It turns about the
    horizontal x axis through both pins, i.e. through its ends.

    Randomised: bottom radius 0.08-0.14 m, taper, height, wall and bottom thickness, pivot
    depth below the rim, tube radius, bail clearance, swing limits (70-90 degrees each way).

    Parameters
    ----------
    rng : numpy.random.Generator

    Returns
    -------
    SynthObject
        In metres.
    """
    Rb = rng.uniform(0.08, 0.14)
    Rt = Rb * rng.uniform(1.0, 1.25)
    H = rng.uniform(0.18, 0.32)
    tw = rng.uniform(0.003, 0.008)
    tbot = rng.uniform(0.005, 0.012)
    slope = (Rt - Rb) / H
    body = cup(Rb, Rt, H, tw, tbot, 64)
    r_t = rng.uniform(0.003, 0.006)
    yp = H - rng.uniform(0.015, 0.04)
    R_at = Rb + slope * (yp + r_t)  # wall radius at the top of the pin
    x_pin = R_at + rng.uniform(0.001, 0.003)
    r_f = r_t * rng.uniform(2.0, 3.0)
    Rh = Rt + r_f + r_t + rng.uniform(0.008, 0.025)
    path = np.concatenate(
        [
            np.linspace([-x_pin, yp, 0.0], [-(Rh - r_f), yp, 0.0], 4, endpoint=False),
            _arc((-(Rh - r_f), yp + r_f), r_f, -90.0, -180.0, 8)[:-1],
            _arc((0.0, yp + r_f), Rh, 180.0, 0.0, 48)[:-1],
            _arc((Rh - r_f, yp + r_f), r_f, 0.0, -90.0, 8),
            np.linspace([Rh - r_f, yp, 0.0], [x_pin, yp, 0.0], 4)[1:],
        ]
    )
    handle = tube(path, r_t, 16)
    lim = (-round(float(rng.uniform(70, 90)), 2), round(float(rng.uniform(70, 90)), 2))
    root = Node("Bucket", "Bucket")
    hn = root.leaf("handle", "handle", [handle])
    root.leaf("base_body", "base_body", [body])
    mo = Motion("hinge", (0.0, yp, 0.0), (1.0, 0.0, 0.0), lim)
    params = {
        "radius_bottom": Rb,
        "radius_top": Rt,
        "height": H,
        "wall": tw,
        "pivot": yp,
        "handle_radius": Rh,
        "tube": r_t,
    }
    return SynthObject(
        "Bucket", root, [LinkSpec("handle", "handle", [hn], mo)], "free", "bucket_body", params
    )


def kitchen_pot(rng: np.random.Generator) -> SynthObject:
    """A cooking pot with two side handles and a lid with a knob, lifting straight up.

    The lid rests on the rim; its skirt reaches into the pot with clearance from the wall.

    Randomised: radius 0.08-0.15 m, height, wall and bottom thickness, handle size, lid
    overhang and thickness, skirt depth and clearance, knob size, lift (slider limit).

    Parameters
    ----------
    rng : numpy.random.Generator

    Returns
    -------
    SynthObject
        In metres.
    """
    R = rng.uniform(0.08, 0.15)
    H = rng.uniform(0.07, 0.18)
    tw = rng.uniform(0.003, 0.007)
    tb = rng.uniform(0.004, 0.01)
    body = cup(R, R, H, tw, tb, 64)
    Lh = rng.uniform(0.03, 0.06)
    wh = rng.uniform(0.02, 0.04)
    hh = rng.uniform(0.01, 0.02)
    yh = H - rng.uniform(0.01, 0.03) - hh
    handles = [
        box((R, yh, -wh / 2), (R + Lh, yh + hh, wh / 2)),
        box((-R - Lh, yh, -wh / 2), (-R, yh + hh, wh / 2)),
    ]
    Rl = R + rng.uniform(0.002, 0.01)
    tl = rng.uniform(0.003, 0.008)
    Rs1 = R - tw - rng.uniform(0.002, 0.005)
    Rs0 = Rs1 - rng.uniform(0.002, 0.005)
    hs = min(rng.uniform(0.005, 0.02), 0.5 * (H - tb))
    lid = lathe(
        [
            (0.0, H + tl),
            (Rl, H + tl),
            (Rl, H),
            (Rs1, H),
            (Rs1, H - hs),
            (Rs0, H - hs),
            (Rs0, H),
            (0.0, H),
        ],
        sections=64,
    )
    rk = rng.uniform(0.01, 0.02)
    hk = rng.uniform(0.01, 0.025)
    knob = cylinder(rk, H + tl, H + tl + hk, (0.0, 0.0, 0.0), "y", 32)
    root = Node("KitchenPot", "KitchenPot")
    ln = root.leaf("lid", "lid", [lid, knob])
    root.leaf("base_body", "base_body", [body, *handles])
    lift = rng.uniform(0.02, 0.08)
    mo = Motion("slider", (0.0, H + tl / 2, 0.0), _UP, (0.0, lift))
    params = {
        "radius": R,
        "height": H,
        "wall": tw,
        "lid_overhang": Rl - R,
        "skirt": hs,
        "lift": lift,
    }
    return SynthObject(
        "KitchenPot", root, [LinkSpec("lid", "lid", [ln], mo)], "free", "pot_body", params
    )


def bottle(rng: np.random.Generator) -> SynthObject:
    """A bottle with a screw cap: the cap slides up its vertical axis while turning about it
    (a cylindrical joint: ``slider`` with ``rotates``).

    Randomised: radius 0.025-0.05 m, body height, shoulder height and shape, neck radius and
    height, cap height, clearance, wall and top thickness, lift and rotation range.

    Parameters
    ----------
    rng : numpy.random.Generator

    Returns
    -------
    SynthObject
        In metres.
    """
    R = rng.uniform(0.025, 0.05)
    Hb = rng.uniform(0.12, 0.26)
    hsh = rng.uniform(0.02, 0.06)
    rn = max(0.008, R * rng.uniform(0.3, 0.5))
    hn = rng.uniform(0.015, 0.035)
    bevel = R * rng.uniform(0.0, 0.15)
    s = np.linspace(0.0, 1.0, 8)[1:-1]
    shoulder = [(R - (R - rn) * (1 - np.cos(np.pi * u)) / 2, Hb + hsh * u) for u in s]
    prof = [(0.0, 0.0)]
    prof += [(R - bevel, 0.0), (R, bevel)] if bevel > 1e-4 else [(R, 0.0)]
    prof += [(R, Hb), *shoulder, (rn, Hb + hsh), (0.0, Hb + hsh)]
    body = lathe(prof, sections=48)
    ys = Hb + hsh
    neck = cylinder(rn, ys, ys + hn, (0.0, 0.0, 0.0), "y", 48)
    ynt = ys + hn
    hcav = hn * rng.uniform(0.5, 0.85)
    rb = rn + rng.uniform(0.0005, 0.0015)
    rc = rb + rng.uniform(0.0015, 0.004)
    ttop = rng.uniform(0.002, 0.005)
    cap = lathe(
        [
            (0.0, ynt + ttop),
            (rc, ynt + ttop),
            (rc, ynt - hcav),
            (rb, ynt - hcav),
            (rb, ynt),
            (0.0, ynt),
        ],
        sections=48,
    )
    root = Node("bottle", "Bottle")
    nb = root.add(Node("normal_bottle", "Normal Bottle"))
    nb.leaf("body", "Body", [body])
    nb.leaf("neck", "Neck", [neck])
    cn = nb.leaf("lid", "Lid", [cap])
    lift = hcav + rng.uniform(0.003, 0.02)
    turn = [180.0, 360.0, 720.0, None][int(rng.integers(0, 4))]
    mo = Motion(
        "slider",
        (0.0, ynt + (ttop - hcav) / 2, 0.0),
        _UP,
        (0.0, lift),
        rotates=True,
        rotation_limit=turn,
    )
    params = {
        "radius": R,
        "body_height": Hb,
        "shoulder": hsh,
        "neck_radius": rn,
        "neck_height": hn,
        "cap_depth": hcav,
        "lift": lift,
        "turn_deg": turn,
    }
    return SynthObject(
        "Bottle", root, [LinkSpec("lid", "rotation_lid", [cn], mo)], "free", "bottle_body", params
    )


def trash_can(rng: np.random.Generator) -> SynthObject:
    """A trash can: open box or cylinder body, a lid hinged along its back top edge, and
    optionally a foot pedal hinged along its back bottom edge at the front of the body.

    The lid is hinged on the body's outer back edge, so it can flip back up to 180 degrees
    without touching the body; the pedal presses down by up to 35 degrees and its hinge keeps
    it in front of the body. SAPIEN's flat hierarchy: ``Trashcan -> lid, foot_pad,
    base_body``.

    Randomised: box or round body, size, wall thickness, lid overhang, thickness and limit
    (90-180 degrees), lid handle (box bodies), pedal presence, size and limit.

    Parameters
    ----------
    rng : numpy.random.Generator

    Returns
    -------
    SynthObject
        In metres.
    """
    round_ = bool(rng.random() < 0.5)
    H = rng.uniform(0.3, 0.7)
    tw = rng.uniform(0.004, 0.012)
    tl = rng.uniform(0.008, 0.02)
    root = Node("Trashcan", "Trashcan")
    if round_:
        R = rng.uniform(0.1, 0.2)
        body = [cup(R, R, H, tw, tw, 64)]
        Rl = R + rng.uniform(0.0, 0.01)
        lid = [lathe([(0.0, H), (Rl, H), (Rl, H + tl), (0.0, H + tl)], 64)]
        half_x, zf = R, R
        hinge_origin = (0.0, H, -Rl)
    else:
        W = rng.uniform(0.2, 0.45)
        D = rng.uniform(0.2, 0.4)
        body = list(
            open_box(np.array([-W / 2, 0.0, -D / 2]), np.array([W / 2, H, D / 2]), tw).values()
        )
        ov = rng.uniform(0.0, 0.015)
        lid = [box((-W / 2 - ov, H, -D / 2), (W / 2 + ov, H + tl, D / 2 + ov))]
        if rng.random() < 0.6:
            lid += top_handle(rng, 0.0, D / 2 + ov - 0.04, H + tl, "x", 0.5 * W, "bar")
        half_x, zf = W / 2, D / 2
        hinge_origin = (0.0, H, -D / 2)
    ln = root.leaf("lid", "lid", lid)
    links = [
        LinkSpec(
            "lid",
            "lid",
            [ln],
            Motion(
                "hinge",
                hinge_origin,
                (-1.0, 0.0, 0.0),
                (0.0, round(float(rng.uniform(90, 180)), 2)),
            ),
        )
    ]
    if rng.random() < 0.5:
        Lp = rng.uniform(0.05, 0.1)
        wp = min(rng.uniform(0.08, 0.16), 1.2 * half_x)
        tp = rng.uniform(0.008, 0.015)
        lim = round(float(rng.uniform(15, 35)), 2)
        h0 = Lp * np.sin(np.deg2rad(lim)) + rng.uniform(
            0.003, 0.01
        )  # pressed, it stays above ground
        # back face on the body's front plane (a round body's tessellation has a vertex line
        # there, so the pedal touches it along that line)
        pedal = box((-wp / 2, h0, zf), (wp / 2, h0 + tp, zf + Lp))
        pn = root.leaf("foot_pad", "foot_pad", [pedal])
        links.append(
            LinkSpec(
                "foot_pad",
                "foot_pad",
                [pn],
                Motion("hinge", (0.0, h0, zf), (1.0, 0.0, 0.0), (0.0, lim)),
            )
        )
    root.leaf("base_body", "base_body", body)
    params = {"round": round_, "height": H, "wall": tw, "lid": tl, "pedal": len(links) == 2}
    return SynthObject("TrashCan", root, links, "free", "trashcan_body", params)
