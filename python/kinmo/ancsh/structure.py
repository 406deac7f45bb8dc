"""Category-level kinematic structure for ANCSH.

ANCSH (Li et al. CVPR 2020) is category-level: every object of a category must share one
kinematic structure, a fixed number of rigid parts and joints of fixed types. Part 0 is the
base; joint ``j`` connects part ``j + 1`` (its child) to ``parents[j + 1]``.

Categories whose objects have several structures (PartNet-Mobility refrigerators: one door,
two doors, doors plus a freezer drawer) get one ANCSH model per structure with enough
objects (:func:`category_structures`, :func:`structure_groups`); each test object is evaluated
with the model of its own structure. ANCSH and Liu et al. (CVPR 2023, Sec. 4.3) instead pick
categories (and objects) with a single structure per category.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from kinmo.data.labels import rigid_groups
from kinmo.data.model import JointType


#: Why :func:`object_parts` returns None, for messages (``kinmo.ancsh.objects``, ``kinmo.ancsh.dataset``).
NOT_EXPRESSIBLE = "cannot be expressed by ANCSH (no moving part, or a joint neither revolute nor prismatic)"


@dataclass(frozen=True)
class KinematicStructure:
    """A category's kinematic structure.

    Attributes
    ----------
    parents : tuple of int
        Parent part of each part; ``parents[0] == -1`` (the base).
    joint_types : tuple of str
        ``"revolute"`` or ``"prismatic"`` for joint ``j`` (child part ``j + 1``).
    """

    parents: tuple[int, ...]
    joint_types: tuple[str, ...]

    def __post_init__(self) -> None:
        if len(self.parents) < 2 or self.parents[0] != -1:
            raise ValueError(f"structure needs a base part 0 with parent -1 and >= 1 child, got parents {self.parents}")
        if len(self.joint_types) != len(self.parents) - 1:
            raise ValueError(f"{len(self.parents)} parts need {len(self.parents) - 1} joints, got {len(self.joint_types)}")
        for k, p in enumerate(self.parents[1:], start=1):
            if not 0 <= p < k:
                raise ValueError(f"part {k}: parent {p} must be an earlier part")
        for t in self.joint_types:
            if t not in ("revolute", "prismatic"):
                raise ValueError(f"unknown joint type {t!r} (revolute or prismatic)")

    @property
    def n_parts(self) -> int:
        """Number of rigid parts K."""
        return len(self.parents)

    @property
    def n_joints(self) -> int:
        """Number of joints J = K - 1."""
        return len(self.joint_types)

    def signature(self) -> str:
        """Compact text form, e.g. ``"0<R-1,0<P-2"`` (parent<type-child)."""
        return ",".join(
            f"{self.parents[j + 1]}<{t[0].upper()}-{j + 1}" for j, t in enumerate(self.joint_types)
        )


@dataclass(frozen=True)
class ObjectParts:
    """How one PartNet-Mobility object maps onto ANCSH parts.

    Attributes
    ----------
    structure : KinematicStructure
    link_part : dict of int to int
        Link id → ANCSH part index (all links of a rigid group share the group's part).
    joint_links : tuple of int
        For joint ``j``: the id of the moving link heading part ``j + 1``.
    """

    structure: KinematicStructure
    link_part: dict[int, int]
    joint_links: tuple[int, ...]


#: Two sibling parts lie in one row (or column, or layer) of :func:`sibling_places` when their
#: centroids differ by at most this fraction of :func:`place_scale` along that axis. Without a
#: tolerance, modelling noise in height (1e-8 to 4e-8 mesh units between the temples of
#: PartNet-Mobility eyeglasses) decided the order of two temples, a cart's wheels or two doors
#: side by side (issue 38, ``docs/results/table2.md``, session 53).
PLACE_TOLERANCE = 0.05


def place_scale(centroids: dict) -> float:
    """The length :data:`PLACE_TOLERANCE` is a fraction of: the diagonal of the box spanned by
    the link centroids ``{link id: (3,) array}`` (mesh units; 1.0 when they span nothing)."""
    if len(centroids) < 2:
        return 1.0
    d = float(np.linalg.norm(np.ptp(np.asarray(list(centroids.values()), dtype=np.float64), axis=0)))
    return d if d > 0 else 1.0


def _bands(values: dict, tol: float) -> dict:
    """Rank of each key's band: values sorted ascending, a new band where the gap to the
    previous value exceeds ``tol`` (single linkage)."""
    out, band, prev = {}, -1, None
    for k, v in sorted(values.items(), key=lambda kv: (kv[1], kv[0])):
        if prev is None or v - prev > tol:
            band += 1
        out[k], prev = band, v
    return out


def sibling_places(centroids: dict, scale: float = 1.0) -> dict:
    """Place of each sibling part, for the canonical part order (:func:`object_parts`).

    Rows from top to bottom (height, mesh frame y-up), each row from left to right (x), each
    column from back to front (z). Parts whose centroids differ by at most
    :data:`PLACE_TOLERANCE` ``* scale`` along an axis share the row (column, layer): the next
    axis decides between them, so that noise in a coordinate never does.

    Parameters
    ----------
    centroids : dict of int to (3,) array
        Link id -> rest-pose centroid (mesh frame, mesh units).
    scale : float
        Object size the tolerance is a fraction of (:func:`place_scale`).

    Returns
    -------
    dict of int to tuple of int
        Link id -> ``(row, column, layer)`` ranks; ascending tuples give the order.
    """
    tol = PLACE_TOLERANCE * float(scale)
    pos = {k: tuple(float(x) for x in v) for k, v in centroids.items()}
    row = _bands({k: -p[1] for k, p in pos.items()}, tol)
    place = {}
    for r in set(row.values()):
        in_row = {k: pos[k] for k in pos if row[k] == r}
        col = _bands({k: p[0] for k, p in in_row.items()}, tol)
        for c in set(col.values()):
            in_col = {k: p for k, p in in_row.items() if col[k] == c}
            layer = _bands({k: p[2] for k, p in in_col.items()}, tol)
            for k in in_col:
                place[k] = (r, c, layer[k])
    return place


def object_parts(links: list, centroids: dict[int, "object"] | None = None) -> ObjectParts | None:
    """The kinematic structure of one object, with a canonical part order.

    Rigid groups (links joined by static / heavy / junk joints, see
    :func:`kinmo.data.labels.rigid_groups`) become parts; the group of the root link is part
    0. Each hinge (revolute) or slider (prismatic) starts a part. Children are numbered
    breadth-first; siblings are ordered by joint type, semantic name, then (when ``centroids``
    of the links are given, mesh frame, y-up) by place (:func:`sibling_places`: in rows from
    top to bottom, each row from left to right, then back to front), else by link id, so that
    e.g. the two doors of a refrigerator or the two temples of eyeglasses are numbered alike
    across objects.

    Parameters
    ----------
    links : list of kinmo.data.model.Link
    centroids : dict of int to (3,) array, optional
        Mean point of each link's surface at rest.

    Returns
    -------
    ObjectParts, or None when the object has no moving joint (or a moving joint that is
    neither a hinge nor a slider). A cylindrical joint (a slider that also rotates about its
    axis: a bottle's screw cap, a swivel chair's lift, a pump head) is a prismatic joint
    here: ANCSH's structures have no cylindrical type, so its scans hold the turn at rest
    (:func:`kinmo.ancsh.scans.render_objects`) and the part's pose and state are its
    translation alone. Before session 46 such objects were left out (11 of the 14 labelled
    bottles).
    """

    groups = rigid_groups(links)
    by_id = {lk.id: lk for lk in links}
    heads = sorted({g for g in groups.values()})
    root = next((h for h in heads if by_id[h].parent == -1), None)
    if root is None:
        return None
    moving = [by_id[h] for h in heads if h != root]
    if not moving or any(lk.joint.type not in (JointType.HINGE, JointType.SLIDER) for lk in moving):
        return None

    scale = place_scale(centroids) if centroids else 1.0

    def ordered(kids: list) -> list:
        # by joint type and name, then by place among the siblings of the same type and name
        same: dict = {}
        for lk in kids:
            same.setdefault((lk.joint.type.value, lk.name), []).append(lk)
        place: dict = {}
        if centroids:
            for group in same.values():
                place.update(sibling_places({lk.id: centroids[lk.id] for lk in group
                                             if lk.id in centroids}, scale))
        return sorted(kids, key=lambda lk: (lk.joint.type.value, lk.name,
                                            place.get(lk.id, (0, 0, 0)), lk.id))

    part_of_group = {root: 0}
    parents = [-1]
    types: list[str] = []
    joint_links: list[int] = []
    frontier = [root]
    while frontier:
        nxt = []
        for g in frontier:
            kids = ordered([lk for lk in moving if groups[lk.parent] == g])
            for lk in kids:
                part_of_group[lk.id] = len(parents)
                parents.append(part_of_group[g])
                types.append("revolute" if lk.joint.type == JointType.HINGE else "prismatic")
                joint_links.append(lk.id)
                nxt.append(lk.id)
        frontier = nxt
    link_part = {lid: part_of_group[g] for lid, g in groups.items() if g in part_of_group}
    return ObjectParts(KinematicStructure(tuple(parents), tuple(types)), link_part, tuple(joint_links))


def category_structure(objects: dict[str, ObjectParts | None]) -> tuple[KinematicStructure | None, list[str]]:
    """The most common structure of a category and the objects that fit it.

    Parameters
    ----------
    objects : dict of str to ObjectParts or None
        Object id → its parts (None: cannot be expressed).

    Returns
    -------
    structure : KinematicStructure or None
        Most common; ties broken by fewer parts, then by signature text (deterministic).
    fitting : list of str
        Sorted ids of the objects with exactly that structure.
    """
    every = category_structures(objects)
    return every[0] if every else (None, [])


def category_structures(objects: dict[str, ObjectParts | None]) -> list[tuple[KinematicStructure, list[str]]]:
    """Every structure of a category with the objects that have it, most common first.

    Parameters: as :func:`category_structure`.

    Returns
    -------
    list of (KinematicStructure, list of str)
        Most objects first; ties broken by fewer parts, then by signature text (the first
        entry is :func:`category_structure`'s); ids sorted.
    """
    by: dict[KinematicStructure, list[str]] = {}
    for i, o in objects.items():
        if o is not None:
            by.setdefault(o.structure, []).append(i)
    order = sorted(by, key=lambda s: (-len(by[s]), s.n_parts, s.signature()))
    return [(s, sorted(by[s])) for s in order]


@dataclass(frozen=True)
class StructureGroup:
    """The objects of one category with one structure, split into training and test.

    Attributes
    ----------
    structure : KinematicStructure
    train, test : tuple of str
        Sorted object ids on each side of the split.
    """

    structure: KinematicStructure
    train: tuple[str, ...]
    test: tuple[str, ...]

    def describe(self) -> str:
        """E.g. ``"3 training and 0 test objects fit 0<R-1"`` (long signatures shortened to
        their first three joints and the joint count)."""
        sig = self.structure.signature()
        if self.structure.n_joints > 4:
            sig = ",".join(sig.split(",")[:3]) + f",... ({self.structure.n_joints} joints)"
        return f"{len(self.train)} training and {len(self.test)} test objects fit {sig}"


def structure_groups(objects: dict[str, ObjectParts | None], test: set[str] | frozenset[str],
                     min_train: int = 2, min_test: int = 1) -> tuple[list[StructureGroup], list[StructureGroup]]:
    """The structures of a category that have enough objects for an ANCSH model.

    The rule of ``kinmo train all``: a structure gets its own model when at least
    ``min_train`` training objects and ``min_test`` test objects of the split have it.

    Parameters
    ----------
    objects : dict of str to ObjectParts or None
        Object id → its parts.
    test : set of str
        Test ids of the split (every other id is a training object).
    min_train, min_test : int

    Returns
    -------
    kept : list of StructureGroup
        Most common structure first (:func:`category_structures`).
    rest : list of StructureGroup
        The structures with too few objects, same order.
    """
    kept, rest = [], []
    for st, ids in category_structures(objects):
        g = StructureGroup(st, tuple(i for i in ids if i not in test), tuple(i for i in ids if i in test))
        (kept if len(g.train) >= min_train and len(g.test) >= min_test else rest).append(g)
    return kept, rest


def structure_slug(structure: KinematicStructure) -> str:
    """A folder name for a structure: ``"0<R-1,0<P-2"`` → ``"0R1-0P2"``."""
    return "-".join(f"{structure.parents[j + 1]}{t[0].upper()}{j + 1}" for j, t in enumerate(structure.joint_types))
