"""In-memory model of a procedural articulated object, before it is written to disk.

A :class:`SynthObject` is a PartNet part tree of :class:`Node` (semantic names and texts as
PartNet writes them, meshes on the leaves) plus kinematic links (:class:`LinkSpec`): each
moving link groups one or more subtrees and carries a :class:`Motion` relative to the base
link, which holds every leaf no moving link claims.

Conventions (all generators follow them; :mod:`kinmo.synth.writer` relies on them):

- Frame: y-up, the front of the object faces +z, metres until :func:`normalize` rescales the
  object to PartNet-Mobility's size (bounding-box diagonal about 2, centred at the origin).
- The rest pose (the meshes as built) is joint value 0 and lies within every limit.
- Hinges: ``direction`` is a unit vector such that a positive rotation (right-hand rule)
  opens the part (a door swings outward, a lid lifts), limits ``(a, b)`` in degrees with
  ``a <= 0 <= b``; ``limit=None`` means unlimited (``noLimit``, e.g. knobs and turntables).
- Sliders: ``direction`` is a unit vector such that a positive translation opens (a drawer is
  pulled out, a lid or cap lifts), limits in mesh units with ``a <= 0 <= b``; ``rotates``
  marks a cylindrical joint (screw caps), with ``rotation_limit`` degrees or ``None``.
- Axis ``origin``: a point of the hinge line on the edge of the moving part, or the centre
  of the moving part for sliders and centre-pivoted parts.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field

import numpy as np
import trimesh


@dataclass
class Node:
    """A PartNet hierarchy node.

    Attributes
    ----------
    name : str
        Semantic name (``"cabinet_door"``).
    text : str
        PartNet label (``"Cabinet door"``).
    children : list of Node
        Child nodes; empty for a leaf.
    meshes : list of trimesh.Trimesh
        Leaf meshes (one OBJ file each); empty for inner nodes.
    """

    name: str
    text: str
    children: list[Node] = field(default_factory=list)
    meshes: list[trimesh.Trimesh] = field(default_factory=list)

    def add(self, child: Node) -> Node:
        """Append ``child`` and return it."""
        self.children.append(child)
        return child

    def leaf(self, name: str, text: str, meshes: list[trimesh.Trimesh]) -> Node:
        """Append a leaf with ``meshes`` and return it."""
        return self.add(Node(name, text, [], list(meshes)))

    def walk(self) -> Iterator[Node]:
        """All nodes of the subtree in depth-first pre-order."""
        yield self
        for c in self.children:
            yield from c.walk()

    def leaves(self) -> list[Node]:
        """Leaves of the subtree in pre-order."""
        return [n for n in self.walk() if not n.children]

    def all_meshes(self) -> list[trimesh.Trimesh]:
        """Meshes of all leaves of the subtree."""
        return [m for n in self.leaves() for m in n.meshes]


@dataclass
class Motion:
    """A joint of a moving link relative to its parent (see the module conventions).

    Attributes
    ----------
    kind : {"hinge", "slider"}
    origin : (3,) float64
        A point of the axis, object frame.
    direction : (3,) float64
        Unit axis direction; positive motion opens.
    limit : (float, float) or None
        ``(a, b)`` with ``a <= 0 <= b``: degrees (hinge) or mesh units (slider); ``None``
        for an unlimited hinge.
    rotates : bool
        Slider that also rotates about its axis (cylindrical joint).
    rotation_limit : float or None
        Rotation range of a rotating slider in degrees, ``None`` if unlimited.
    """

    kind: str
    origin: np.ndarray
    direction: np.ndarray
    limit: tuple[float, float] | None
    rotates: bool = False
    rotation_limit: float | None = None

    def __post_init__(self) -> None:
        if self.kind not in ("hinge", "slider"):
            raise ValueError(f"motion kind must be 'hinge' or 'slider', got {self.kind!r}")
        self.origin = np.asarray(self.origin, dtype=np.float64).reshape(3)
        d = np.asarray(self.direction, dtype=np.float64).reshape(3)
        self.direction = d / np.linalg.norm(d)
        if self.limit is not None:
            a, b = float(self.limit[0]), float(self.limit[1])
            if not a <= 0.0 <= b:
                raise ValueError(f"limit must satisfy a <= 0 <= b, got ({a}, {b})")
            self.limit = (a, b)
        elif self.kind == "slider":
            raise ValueError("sliders need a limit")

    def transform(self, value: float, turn_deg: float = 0.0) -> np.ndarray:
        """4x4 rigid transform of the moving part at joint ``value``.

        Parameters
        ----------
        value : float
            Degrees for hinges, mesh units for sliders.
        turn_deg : float
            Extra rotation about the axis for rotating sliders, degrees.

        Returns
        -------
        (4, 4) float64
        """
        if self.kind == "hinge":
            return trimesh.transformations.rotation_matrix(
                np.deg2rad(value), self.direction, self.origin
            )
        T = np.eye(4)
        T[:3, 3] = value * self.direction
        if self.rotates and turn_deg:
            T = T @ trimesh.transformations.rotation_matrix(
                np.deg2rad(turn_deg), self.direction, self.origin
            )
        return T


@dataclass
class LinkSpec:
    """A moving link: hierarchy subtrees moving rigidly together.

    Attributes
    ----------
    name : str
        ``mobility_v2.json`` link name (``"cabinet_door"``, ``"drawer"``, ``"knob"``...).
    semantic : str
        ``semantics.txt`` label (``"rotation_door"``, ``"drawer"``, ``"knob"``...).
    nodes : list of Node
        Subtree roots; the link's parts are their leaves.
    motion : Motion
        Joint to the parent link.
    parent : int or None
        Index of the parent moving link in :attr:`SynthObject.links`; ``None`` for the base.
    """

    name: str
    semantic: str
    nodes: list[Node]
    motion: Motion
    parent: int | None = None

    def leaves(self) -> list[Node]:
        """Leaves of all subtrees."""
        return [leaf for n in self.nodes for leaf in n.leaves()]


@dataclass
class SynthObject:
    """A procedural articulated object.

    Attributes
    ----------
    category : str
        ``model_cat`` (CamelCase, e.g. ``"StorageFurniture"``).
    root : Node
        The PartNet hierarchy.
    links : list of LinkSpec
        Moving links, in link-id order (the base link is written after them).
    base_joint : str
        Joint of the base link: ``"heavy"`` (furniture, appliances) or ``"free"``.
    base_semantic : str
        ``semantics.txt`` label of the base (``"furniture_body"``...).
    params : dict
        The sampled generator parameters (JSON-serialisable), for provenance.
    """

    category: str
    root: Node
    links: list[LinkSpec]
    base_joint: str
    base_semantic: str
    params: dict = field(default_factory=dict)

    def base_leaves(self) -> list[Node]:
        """Leaves owned by no moving link, in pre-order."""
        moving = {id(leaf) for link in self.links for leaf in link.leaves()}
        return [leaf for leaf in self.root.leaves() if id(leaf) not in moving]

    def check(self) -> None:
        """Validate the structure.

        Raises
        ------
        ValueError
            A leaf without meshes, an inner node with meshes, a leaf claimed by two links,
            a link without leaves, or a bad parent index.
        """
        for n in self.root.walk():
            if n.children and n.meshes:
                raise ValueError(f"inner node {n.name!r} has meshes")
            if not n.children and not n.meshes:
                raise ValueError(f"leaf {n.name!r} has no meshes")
        seen: set[int] = set()
        for i, link in enumerate(self.links):
            leaves = link.leaves()
            if not leaves:
                raise ValueError(f"link {i} ({link.name}) has no parts")
            for leaf in leaves:
                if id(leaf) in seen:
                    raise ValueError(f"leaf {leaf.name!r} belongs to two links")
                seen.add(id(leaf))
            if link.parent is not None and not 0 <= link.parent < len(self.links):
                raise ValueError(f"link {i} has a bad parent {link.parent}")
        if not self.base_leaves():
            raise ValueError("the base link has no parts")

    def bounds(self) -> np.ndarray:
        """(2, 3) float64 axis-aligned bounds of all meshes in the rest pose."""
        b = np.array([m.bounds for m in self.root.all_meshes()])
        return np.stack([b[:, 0].min(axis=0), b[:, 1].max(axis=0)])


def normalize(obj: SynthObject, diagonal: float) -> float:
    """Centre ``obj`` at the origin and scale it uniformly to a bounding-box diagonal.

    Meshes, axis origins and slider limits are transformed in place (PartNet-Mobility objects
    are stored at about unit size: diagonal ~2, centred).

    Parameters
    ----------
    obj : SynthObject
    diagonal : float
        Target diagonal of the rest-pose axis-aligned bounding box (mesh units).

    Returns
    -------
    float
        The scale factor applied (mesh units per metre).
    """
    lo, hi = obj.bounds()
    centre = (lo + hi) / 2.0
    scale = float(diagonal / np.linalg.norm(hi - lo))
    T = np.eye(4)
    T[:3, :3] *= scale
    T[:3, 3] = -centre * scale
    for m in obj.root.all_meshes():
        m.apply_transform(T)
    for link in obj.links:
        mo = link.motion
        mo.origin = (mo.origin - centre) * scale
        if mo.kind == "slider" and mo.limit is not None:
            mo.limit = (mo.limit[0] * scale, mo.limit[1] * scale)
    return scale
