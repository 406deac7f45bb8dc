"""Typed in-memory model of PartNet shapes and PartNet-Mobility objects.

A *shape* is a PartNet part hierarchy (``result.json``): a tree of semantic nodes whose
leaves reference OBJ meshes. A PartNet-Mobility *object* adds kinematic *links*
(``mobility_v2.json``), each a set of hierarchy nodes moving rigidly together and attached
to its parent link by a *joint*.

Frames: all coordinates are in the mesh frame of the OBJ files; PartNet objects are y-up
(+y is vertical).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import Enum
from pathlib import Path

import numpy as np

#: The paper's 10 fine motion types of a directed sibling edge (moving part, reference part),
#: Liu et al. 2023 Sec. 3.1: P = prismatic, R = revolute, PR = both (cylindrical);
#: H / V = horizontal / vertical axis; C / S = revolute pivot at the centre / a side.
FINE_TYPES: tuple[str, ...] = (
    "P_H", "P_V", "R_H_C", "R_H_S", "R_V_C", "R_V_S", "PR_H", "PR_V", "Fixed", "None",
)
#: The 5 coarse motion types.
COARSE_TYPES: tuple[str, ...] = ("P", "R", "PR", "Fixed", "None")
#: Fine type index -> coarse type index.
FINE_TO_COARSE: tuple[int, ...] = (0, 0, 1, 1, 1, 1, 2, 2, 3, 4)
FINE_INDEX = {name: i for i, name in enumerate(FINE_TYPES)}
COARSE_INDEX = {name: i for i, name in enumerate(COARSE_TYPES)}


class ShapeFormat(str, Enum):
    """On-disk format of a shape folder."""

    PARTNET = "partnet"
    """PartNet: ``result.json`` + ``objs/``, no motion."""
    PARTNET_MOBILITY = "partnet-mobility"
    """PartNet-Mobility: ``result.json`` + ``textured_objs/`` + ``mobility_v2.json``."""


class JointType(str, Enum):
    """PartNet-Mobility joint types (``mobility_v2.json`` field ``joint``)."""

    HINGE = "hinge"
    """Revolute."""
    SLIDER = "slider"
    """Prismatic; cylindrical (prismatic + revolute) when ``rotates`` is true."""
    FREE = "free"
    """The root link (free-floating base)."""
    HEAVY = "heavy"
    """Movable only as a whole, heavy; treated as fixed to its parent."""
    STATIC = "static"
    """Fixed to its parent."""
    JUNK = "junk"
    """An annotation artefact; treated as fixed to its parent."""


@dataclass(frozen=True)
class PartNode:
    """One node of the PartNet part hierarchy.

    Attributes
    ----------
    id : int
        PartNet node id (unique within the shape).
    name : str
        Semantic name, e.g. ``"door"``.
    text : str
        Human-readable label from the annotation.
    children : tuple of int
        Ids of the child nodes, in file order.
    objs : tuple of str
        Mesh names (without ``.obj``) of a leaf; empty for inner nodes.
    parent : int or None
        Id of the parent node, ``None`` for the root.
    """

    id: int
    name: str
    text: str
    children: tuple[int, ...]
    objs: tuple[str, ...]
    parent: int | None

    @property
    def is_leaf(self) -> bool:
        """True for a node without children."""
        return not self.children


@dataclass
class PartHierarchy:
    """A PartNet part tree.

    Attributes
    ----------
    nodes : dict of int to PartNode
        All nodes by id.
    root : int
        Id of the root node.
    order : list of int
        Node ids in depth-first pre-order (parents before children), the canonical node order
        of kinmo's part graphs.
    """

    nodes: dict[int, PartNode]
    root: int
    order: list[int] = field(default_factory=list)

    def leaves(self, node_id: int) -> list[int]:
        """Ids of the leaves below ``node_id`` (itself if it is a leaf), in pre-order."""
        out: list[int] = []
        stack = [node_id]
        while stack:
            n = self.nodes[stack.pop()]
            if n.is_leaf:
                out.append(n.id)
            else:
                stack.extend(reversed(n.children))
        return out

    def depth(self, node_id: int) -> int:
        """Number of edges from the root to ``node_id``."""
        d = 0
        p = self.nodes[node_id].parent
        while p is not None:
            d += 1
            p = self.nodes[p].parent
        return d

    def mesh_names(self, node_id: int) -> list[str]:
        """Mesh names of all leaves below ``node_id``."""
        return [o for leaf in self.leaves(node_id) for o in self.nodes[leaf].objs]


@dataclass(frozen=True)
class Joint:
    """A PartNet-Mobility joint (``jointData`` of a link), in the mesh frame.

    Attributes
    ----------
    type : JointType
    origin : (3,) float64 or None
        A point on the axis (mesh frame, mesh units); ``None`` for joints without an axis.
    direction : (3,) float64 or None
        Unit axis direction (normalised on reading; the file's is not always unit length).
    limit : tuple of float or None
        ``(a, b)``: lower and upper limit, degrees for hinges, mesh units for sliders;
        ``None`` when the joint has no limit (``noLimit``).
    rotates : bool
        For sliders: also rotates about the axis (cylindrical joint).
    rotation_limit : float or None
        For rotating sliders: rotation range in degrees, ``None`` if unlimited.
    """

    type: JointType
    origin: np.ndarray | None = None
    direction: np.ndarray | None = None
    limit: tuple[float, float] | None = None
    rotates: bool = False
    rotation_limit: float | None = None

    @property
    def is_moving(self) -> bool:
        """True for hinges and sliders."""
        return self.type in (JointType.HINGE, JointType.SLIDER)


@dataclass(frozen=True)
class Link:
    """A PartNet-Mobility link: hierarchy nodes moving rigidly together.

    Attributes
    ----------
    id : int
        Link id (``link_<id>`` in ``semantics.txt`` and URDF).
    parent : int
        Parent link id, -1 for the root.
    name : str
        Semantic name, e.g. ``"door"``.
    parts : tuple of int
        PartNet node ids forming the link.
    joint : Joint
        Joint to the parent link.
    """

    id: int
    parent: int
    name: str
    parts: tuple[int, ...]
    joint: Joint


@dataclass
class Shape:
    """A shape read from disk: hierarchy, mesh folder, and (PartNet-Mobility) links.

    Attributes
    ----------
    id : str
        Folder name (the PartNet annotation id).
    category : str
        ``model_cat`` from ``meta.json`` (CamelCase, e.g. ``"StorageFurniture"``).
    format : ShapeFormat
    path : Path
        The shape folder.
    mesh_dir : Path
        ``objs/`` (PartNet) or ``textured_objs/`` (PartNet-Mobility).
    hierarchy : PartHierarchy
    links : list of Link or None
        Kinematic links (PartNet-Mobility only).
    meta : dict
        ``meta.json`` as read.
    """

    id: str
    category: str
    format: ShapeFormat
    path: Path
    mesh_dir: Path
    hierarchy: PartHierarchy
    links: list[Link] | None = None
    meta: dict = field(default_factory=dict)

    def mesh_path(self, name: str) -> Path:
        """Path of the OBJ file of mesh ``name``."""
        return self.mesh_dir / f"{name}.obj"
