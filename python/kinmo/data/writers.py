"""Writers of PartNet-Mobility motion files: ``mobility_v2.json`` and ``semantics.txt``.

Real, generated (procedural) and predicted (Liu et al. 2023, Sec. 3: the Motion GNN's mobile
parts, motion types and axes, turned into links) motions are all written in PartNet-Mobility's
own format, so every tool of the field that reads PartNet-Mobility objects (SAPIEN, ANCSH
preprocessing, kinmo's own readers and URDF export) reads kinmo's outputs unchanged.

Format (as in the released files):

- ``mobility_v2.json``: a JSON list with one entry per link, in ascending link id::

    {"id": 0, "parent": 1, "joint": "hinge", "name": "door",
     "parts": [{"id": 7, "name": "door_frame"}, ...],
     "jointData": {"axis": {"origin": [x, y, z], "direction": [dx, dy, dz]},
                   "limit": {"a": 0, "b": -180, "noLimit": false}}}

  ``jointData`` is ``{}`` for ``free``, ``heavy``, ``static`` and ``junk`` links. Sliders also
  carry ``"rotates"``, ``"noRotationLimit"`` and ``"rotationLimit"`` in ``limit`` (a slider that
  rotates is a cylindrical joint). Axes are in the mesh frame (y-up), origins in mesh units,
  hinge limits in degrees, slider limits in mesh units; written compactly (no spaces), like
  the released files.
- ``semantics.txt``: one line per link, ``link_<id> <joint> <semantic>``, where a rotating
  slider's joint is written ``slider+``.

All writes are atomic (:mod:`kinmo.io`).
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from kinmo.data.model import Joint, JointType, Link, PartHierarchy
from kinmo.errors import KinmoDataError
from kinmo.io import write_text

__all__ = [
    "mobility_v2_dict",
    "mobility_v2_json",
    "semantics_joint_name",
    "write_mobility_v2",
    "write_semantics",
]


def _num(x: float) -> int | float:
    """A JSON number: integral values as ints (``[0, -1, 0]`` like the released files)."""
    x = float(x)
    if not np.isfinite(x):
        raise ValueError(f"non-finite value {x}")
    if x.is_integer() and abs(x) < 2**53:
        return int(x)
    return x


def _vec(v: np.ndarray | None, what: str, link: Link) -> list[int | float]:
    if v is None:
        raise ValueError(f"link {link.id}: {link.joint.type.value} joint without an axis {what}")
    a = np.asarray(v, dtype=np.float64).reshape(-1)
    if a.shape != (3,) or not np.all(np.isfinite(a)):
        raise ValueError(f"link {link.id}: axis {what} must be 3 finite numbers, got {v!r}")
    return [_num(c) for c in a]


def _joint_data(link: Link) -> dict:
    j: Joint = link.joint
    if j.type not in (JointType.HINGE, JointType.SLIDER):
        return {}
    direction = _vec(j.direction, "direction", link)
    if not any(direction):
        raise ValueError(f"link {link.id}: zero axis direction")
    limit: dict = {}
    if j.limit is None:
        limit.update(a=0, b=0, noLimit=True)
    else:
        a, b = j.limit
        limit.update(a=_num(a), b=_num(b), noLimit=False)
    if j.type is JointType.SLIDER:
        limit["rotates"] = bool(j.rotates)
        no_rot = bool(j.rotates) and j.rotation_limit is None
        limit["noRotationLimit"] = no_rot
        limit["rotationLimit"] = 0 if j.rotation_limit is None else _num(j.rotation_limit)
    return {"axis": {"origin": _vec(j.origin, "origin", link), "direction": direction},
            "limit": limit}


def mobility_v2_dict(
    links: Sequence[Link], hierarchy: PartHierarchy | None = None
) -> list[dict]:
    """The ``mobility_v2.json`` content of ``links``, as JSON-ready Python objects.

    Parameters
    ----------
    links : sequence of Link
        Kinematic links (real, generated or predicted); written in ascending id order. Joint
        axes in the mesh frame (y-up), origins in mesh units; hinge limits in degrees, slider
        limits in mesh units, ``(a, b)`` written as given (``a`` is not required to be <= ``b``,
        as in the released files).
    hierarchy : PartHierarchy, optional
        Gives the ``name`` of every part entry; without it part names are ``""``.

    Returns
    -------
    list of dict
        One dict per link with keys ``id``, ``parent``, ``joint``, ``name``, ``parts``
        (``[{"id", "name"}]``) and ``jointData`` (``{}`` for free/heavy/static/junk links).

    Raises
    ------
    ValueError
        Duplicate link ids, a parent id that is not a link, a hinge/slider without an axis or
        with a zero or non-finite axis, or a part id missing from ``hierarchy``.
    """
    ids = [link.id for link in links]
    if len(set(ids)) != len(ids):
        raise ValueError(f"duplicate link ids in {sorted(ids)}")
    known = set(ids)
    out: list[dict] = []
    for link in sorted(links, key=lambda l: l.id):
        if link.parent != -1 and link.parent not in known:
            raise ValueError(f"link {link.id}: parent {link.parent} is not a link")
        parts = []
        for pid in link.parts:
            if hierarchy is not None and pid not in hierarchy.nodes:
                raise ValueError(f"link {link.id}: part {pid} is not a node of the hierarchy")
            name = hierarchy.nodes[pid].name if hierarchy is not None else ""
            parts.append({"id": int(pid), "name": name})
        out.append({
            "id": int(link.id),
            "parent": int(link.parent),
            "joint": link.joint.type.value,
            "name": link.name,
            "parts": parts,
            "jointData": _joint_data(link),
        })
    return out


def mobility_v2_json(links: Sequence[Link], hierarchy: PartHierarchy | None = None) -> str:
    """:func:`mobility_v2_dict` serialised compactly, like the released files (no newline)."""
    return json.dumps(mobility_v2_dict(links, hierarchy), separators=(",", ":"))


def write_mobility_v2(
    links: Sequence[Link], path: str | Path, hierarchy: PartHierarchy | None = None
) -> Path:
    """Write ``links`` as a PartNet-Mobility ``mobility_v2.json`` file, atomically.

    Parameters
    ----------
    links : sequence of Link
        See :func:`mobility_v2_dict`.
    path : str or Path
        Output file (parent folders are created).
    hierarchy : PartHierarchy, optional
        Source of the part names (``Shape.hierarchy``).

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    KinmoDataError
        The links are inconsistent (message names ``path`` and the problem).
    """
    path = Path(path)
    try:
        text = mobility_v2_json(links, hierarchy)
    except ValueError as e:
        raise KinmoDataError(path, str(e)) from None
    write_text(path, text)
    return path


def semantics_joint_name(joint: Joint) -> str:
    """The joint column of ``semantics.txt``: the joint type, ``slider+`` for a rotating slider."""
    if joint.type is JointType.SLIDER and joint.rotates:
        return "slider+"
    return joint.type.value


def write_semantics(
    links: Sequence[Link], path: str | Path, names: Mapping[int, str] | None = None
) -> Path:
    """Write a PartNet-Mobility ``semantics.txt``: ``link_<id> <joint> <semantic>`` per link.

    Parameters
    ----------
    links : sequence of Link
        Written in ascending id order.
    path : str or Path
        Output file, written atomically.
    names : mapping of int to str, optional
        Semantic label per link id (e.g. ``"rotation_door"``); defaults to ``Link.name``.

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    KinmoDataError
        Duplicate link ids, or a semantic label that is empty or contains whitespace (the file
        is whitespace-separated).
    """
    path = Path(path)
    lines = []
    seen: set[int] = set()
    for link in sorted(links, key=lambda l: l.id):
        if link.id in seen:
            raise KinmoDataError(path, f"duplicate link id {link.id}")
        seen.add(link.id)
        label = (names or {}).get(link.id, link.name)
        if not label or any(c.isspace() for c in label):
            raise KinmoDataError(path, f"link {link.id}: semantic label {label!r} is empty or "
                                       "contains whitespace")
        lines.append(f"link_{link.id} {semantics_joint_name(link.joint)} {label}")
    write_text(path, "\n".join(lines) + "\n")
    return path
