"""Part graph → model tensors: the shape-normalised frame, node (OBB) and edge features.

The motion GNN (:mod:`kinmo.models.motion_gnn`) never sees mesh units. Every shape is mapped
to a **normalised frame**: translated so that the centre of its axis-aligned bounding box
(AABB, over the root node's surface samples) is the origin and divided by its scale, the
AABB diagonal :attr:`kinmo.data.graph.PartGraph.scale`. Orientation is kept: PartNet and
PartNet-Mobility objects are consistently aligned (y-up, front facing the same way), and the
fine motion types distinguish horizontal from vertical axes in that frame (Liu et al. 2023,
Sec. 3.1). The map back to the mesh frame is ``x_mesh = x_norm * scale + center``
(:meth:`GraphTensors.to_mesh`); directions are unchanged.

Features (all float32, normalised frame):

- **points** ``(V, P, 3)``: each node's surface samples minus its OBB centre, divided by the
  shape scale (the part's geometry and size, not its position).
- **node features** ``(V, NODE_DIM)``: OBB centre (3), OBB axes (3 rows, 9), OBB full side
  lengths (3), leaf flag (1), depth / 8 (1).
- **edge features** ``(Es, EDGE_DIM)`` of a directed sibling edge ``(i, j)``
  (:func:`edge_features`, computed from node tensors so that augmentations rotate them
  consistently): centre difference ``c_i - c_j`` (3) and its length (1), the same difference
  in ``i``'s and in ``j``'s OBB frame (3 + 3), ``|A_i A_j^T|`` (absolute dot products of the
  two boxes' axes, 9), both boxes' side lengths (3 + 3), contact flag (1), mesh distance
  divided by the scale (1).

Labels (PartNet-Mobility graphs): the fine type of each edge, the unit axis direction and the
axis origin in the normalised frame; NaN axes of ``Fixed`` / ``None`` edges become zeros with
a mask.

Length: over 500 lines, about 40 % of them docstrings: one topic, the tensors the motion GNN
sees: the normalised frame, the node and edge features, their yaw augmentation and the batch
share one frame and one tensor layout, which must change together.
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
import torch

from kinmo.data.frames import quarter_turn
from kinmo.data.graph import PartGraph
from kinmo.data.model import FINE_INDEX, FINE_TO_COARSE, FINE_TYPES
from kinmo.errors import KinmoDataError

__all__ = [
    "EDGE_DIM",
    "NODE_DIM",
    "GraphBatch",
    "GraphTensors",
    "SemanticVocab",
    "collate",
    "edge_features",
    "graph_tensors",
    "canonical_obb_axes",
    "moving_fine_mask",
    "quarter_turn",
    "rotating_fine_mask",
    "yaw_rotation",
]

#: Width of the node feature vector (OBB centre, axes, sizes, leaf flag, depth).
NODE_DIM = 17
#: Width of the edge feature vector (see the module docstring).
EDGE_DIM = 27

_R = ("R_H_C", "R_H_S", "R_V_C", "R_V_S", "PR_H", "PR_V")


def moving_fine_mask() -> torch.Tensor:
    """``(10,) bool``: fine types that have an axis (P, R and PR types)."""
    return torch.tensor([t not in ("Fixed", "None") for t in FINE_TYPES])


def rotating_fine_mask() -> torch.Tensor:
    """``(10,) bool``: fine types that rotate (R and PR), whose axis position matters."""
    return torch.tensor([t in _R for t in FINE_TYPES])


#: A trailing number of a node name (``door_2``, ``leg.3``, ``drawer 1``).
_TRAILING_NUMBER = re.compile(r"[\s_.\-]*\d+$")
#: Names that mean "unnamed" (index 0 of :class:`SemanticVocab`).
_UNNAMED = frozenset({"unknown", "part", ""})


class SemanticVocab:
    """Map of PartNet semantic node names (``"door"``, ``"drawer_front"``) to embedding indices.

    Index 0 is reserved for names unseen in training, and for unnamed nodes (``"unknown"``,
    and ``part_<k>`` after the digits go: :mod:`kinmo.data.augment`), which the GNN sees in
    training when names are dropped. Names are lower-cased and lose a trailing number
    (``"door_2"`` -> ``"door"``, :meth:`normalise`), so a user's numbered names still count.
    The vocabulary is built from the training graphs and saved in the checkpoint.

    Parameters
    ----------
    names : sequence of str
        Known names (deduplicated, sorted for determinism).
    """

    def __init__(self, names: Sequence[str] = ()) -> None:
        self.names: list[str] = sorted({m for n in names if (m := self.normalise(n))
                                        and m not in _UNNAMED})
        self._index = {n: i + 1 for i, n in enumerate(self.names)}

    def __len__(self) -> int:
        """Number of indices (known names + 1 for unknown)."""
        return len(self.names) + 1

    def index(self, name: str) -> int:
        """Index of ``name`` after :meth:`normalise` (0 when unknown)."""
        return self._index.get(self.normalise(name), 0)

    @staticmethod
    def normalise(name: str) -> str:
        """Lower case, a trailing number (with its ``_``, ``-``, ``.`` or space) removed:
        ``"Door_2"`` -> ``"door"``, ``"part_12"`` -> ``"part"``."""
        return _TRAILING_NUMBER.sub("", name.strip().lower())

    @classmethod
    def from_graphs(cls, graphs: Sequence[PartGraph]) -> SemanticVocab:
        """Vocabulary of every node name of ``graphs``."""
        return cls([n for g in graphs for n in g.node_names])


@dataclass
class GraphTensors:
    """One shape as model tensors in the normalised frame (see the module docstring).

    ``V`` nodes (pre-order, as in the :class:`~kinmo.data.graph.PartGraph`), ``P`` points per
    node, ``E`` directed sibling edges.

    Attributes
    ----------
    shape_id, category : str
    center : (3,) float64
        AABB centre of the shape, mesh frame.
    scale : float
        AABB diagonal, mesh units.
    points : (V, P, 3) float32
        Node samples relative to the node's OBB centre, divided by ``scale``.
    obb_center : (V, 3) float32
    obb_axes : (V, 3, 3) float32
        Orthonormal rows.
    obb_size : (V, 3) float32
        Full side lengths along the axis rows.
    is_leaf : (V,) bool
    depth : (V,) int64
    parent : (V,) int64
        -1 for the root.
    semantic : (V,) int64
        :class:`SemanticVocab` index of each node name (0 when no vocabulary was given).
    edges : (E, 2) int64
        Directed sibling edges ``(i, j)``: "i moves relative to j".
    contact : (E,) bool
    distance : (E,) float32
        Mesh distance divided by ``scale``.
    edge_fine : (E,) int64 or None
        Ground-truth fine type (:data:`~kinmo.data.model.FINE_TYPES` index).
    axis_origin : (E, 3) float32 or None
        Ground-truth axis point (normalised frame), zeros where the edge has no axis.
    axis_direction : (E, 3) float32 or None
        Ground-truth unit axis direction, zeros where the edge has no axis.
    has_axis : (E,) bool or None
        The edge's ground-truth type has an axis.
    """

    shape_id: str
    category: str
    center: np.ndarray
    scale: float
    points: torch.Tensor
    obb_center: torch.Tensor
    obb_axes: torch.Tensor
    obb_size: torch.Tensor
    is_leaf: torch.Tensor
    depth: torch.Tensor
    parent: torch.Tensor
    semantic: torch.Tensor
    edges: torch.Tensor
    contact: torch.Tensor
    distance: torch.Tensor
    edge_fine: torch.Tensor | None = None
    axis_origin: torch.Tensor | None = None
    axis_direction: torch.Tensor | None = None
    has_axis: torch.Tensor | None = None

    @property
    def n_nodes(self) -> int:
        """``V``."""
        return int(self.parent.shape[0])

    @property
    def n_edges(self) -> int:
        """``E``."""
        return int(self.edges.shape[0])

    def to_mesh(self, points: np.ndarray) -> np.ndarray:
        """Map normalised-frame points ``(..., 3)`` back to the mesh frame (float64)."""
        return np.asarray(points, dtype=np.float64) * self.scale + self.center

    def turned(self, k: int) -> GraphTensors:
        """The shape turned ``k`` quarter turns about the vertical through the normalised
        frame's origin (:func:`quarter_turn`), its OBB axes signed as a fit of the turned shape
        signs them (:func:`canonical_obb_axes`): the tensors of the same object given turned
        (issue 36: the facing augmentation of :attr:`kinmo.train.config.TrainConfig.augment_turn`)."""
        out = self.rotated(quarter_turn(k))
        out.obb_axes = canonical_obb_axes(out.obb_axes, out.obb_size)
        return out

    def rotated(self, rotation: np.ndarray) -> GraphTensors:
        """The same shape rotated about the normalised frame's origin (an augmentation).

        Parameters
        ----------
        rotation : (3, 3) float
            Proper rotation matrix ``R``; vectors map as ``x -> R x``.

        Returns
        -------
        GraphTensors
            Points, OBB centres and axes, and ground-truth axes rotated; ``center``/``scale``
            unchanged (the result no longer maps to the original mesh frame).
        """
        r = torch.as_tensor(np.asarray(rotation), dtype=torch.float32)
        rt = r.T
        out = replace(
            self,
            points=self.points @ rt,
            obb_center=self.obb_center @ rt,
            obb_axes=self.obb_axes @ rt,
        )
        if self.axis_origin is not None and self.axis_direction is not None:
            out.axis_origin = self.axis_origin @ rt
            out.axis_direction = self.axis_direction @ rt
        return out


#: :func:`canonical_obb_axes`: OBB sides whose lengths differ by at most this share of the
#: longest are tied (the Rust fit's ``1e-6`` on float64 half-extents, loosened for the float32
#: sizes of :class:`GraphTensors`).
TIE_RELATIVE = 1e-5

#: :func:`canonical_obb_axes` orders tied rows only when each is this close to a world axis
#: (cosine): the section of a square part is axis-aligned in a turned shape as in the shape,
#: while a cylinder's two equal axes lie at whatever angle the fit found.
ALIGNED_COS = math.cos(math.radians(1.0))


def canonical_obb_axes(axes: torch.Tensor, sizes: torch.Tensor | None = None) -> torch.Tensor:
    """OBB axis rows ordered and signed as :mod:`kinmo.geometry.obb` orders and signs them
    (its step 6): rows whose side lengths tie (within :data:`TIE_RELATIVE` of the longest)
    ordered by the world axis each is closest to, ``y``, then ``x``, then ``z`` (then the
    larger such component first); rows 0 and 1 with their largest-magnitude component positive
    (exact ties: ``y``, then ``x``, then ``z``), row 2 their cross product.

    Turning a shape permutes and negates coordinates, so its rotated OBB axes are those the
    Rust fit gives the turned shape up to this order and these signs. Without the order, a
    part with a square section (an oven in its cabinet, a block) got its two equal axes in
    one order when the shape was turned here and in the other when a turned shape was fitted,
    so the quarter-turn average of :mod:`kinmo.inference.gnn` differed with the facing the
    object came in (issue 36's rotation check).

    Parameters
    ----------
    axes : (V, 3, 3) float tensor
        Rows are the axes, sorted by side length, longest first (as fitted).
    sizes : (V, 3) float tensor, optional
        The side lengths of those rows; without, the rows keep their order.

    Returns
    -------
    (V, 3, 3) tensor, same dtype
    """
    a = axes.clone()
    if a.numel() == 0:
        return a
    if sizes is not None:
        a = _order_tied_rows(a, sizes)
    order = torch.tensor([1, 0, 2])  # tie order y, x, z
    for r in range(2):
        row = a[:, r, :]
        mag = row.abs()[:, order]
        big = mag.max(dim=1, keepdim=True).values
        first = torch.argmax((mag >= big).to(torch.int8), dim=1)  # first of the tied, in y, x, z order
        lead = row[:, order].gather(1, first[:, None])[:, 0]
        a[:, r, :] = torch.where((lead < 0)[:, None], -row, row)
    a[:, 2, :] = torch.linalg.cross(a[:, 0, :], a[:, 1, :])
    return a


def _order_tied_rows(axes: torch.Tensor, sizes: torch.Tensor) -> torch.Tensor:
    """``axes`` with each run of tied rows (sizes within :data:`TIE_RELATIVE` times the
    longest side of the run's first row, all rows within 1° of a world axis) sorted by the
    world axis each is closest to, y, x, z, then by the larger such component (the Rust fit's
    ``direction_rank``)."""
    s = sizes.detach().to(torch.float64).cpu().numpy()
    if not s.size:
        return axes
    out = axes.clone()
    rank_of = np.array([1, 0, 2])  # x -> 1, y -> 0, z -> 2
    for v in np.flatnonzero(np.abs(np.diff(s, axis=1)).min(axis=1) <= TIE_RELATIVE * s.max(axis=1)):
        a = axes[v].detach().to(torch.float64).cpu().numpy()
        tie = TIE_RELATIVE * s[v].max()
        idx, start = [0, 1, 2], 0
        while start < 3:
            end = start + 1
            while end < 3 and s[v, start] - s[v, end] <= tie:
                end += 1
            mag = np.abs(a[idx[start:end]])
            if end - start > 1 and mag.max(axis=1).min() < ALIGNED_COS:
                start = end  # a tied pair at a slant (a cylinder's section): kept as turned
                continue
            # dominant component, exact ties resolved y, x, z
            dom = [max((1, 0, 2), key=lambda k, m=m: (m[k], -rank_of[k])) for m in mag]
            key = [(rank_of[k], -m[k]) for k, m in zip(dom, mag)]
            idx[start:end] = [i for _, i in sorted(zip(key, idx[start:end]), key=lambda t: t[0])]
            start = end
        if idx != [0, 1, 2]:
            out[v] = axes[v][idx]
    return out


def yaw_rotation(angle: float) -> np.ndarray:
    """Rotation about the vertical (+y) axis by ``angle`` radians, ``(3, 3) float64``."""
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def shape_frame(graph: PartGraph) -> tuple[np.ndarray, float]:
    """Centre and scale of the normalised frame of ``graph``.

    Returns
    -------
    center : (3,) float64
        Centre of the AABB of the root node's points (all nodes' points if there are several
        roots), mesh frame.
    scale : float
        ``graph.scale`` (AABB diagonal, mesh units), or the points' AABB diagonal if that is
        not positive.

    Raises
    ------
    KinmoDataError
        The graph has no finite points.
    """
    roots = np.flatnonzero(np.asarray(graph.parent) < 0)
    pts = np.asarray(graph.points[roots] if len(roots) else graph.points, dtype=np.float64)
    pts = pts.reshape(-1, 3)
    if pts.size == 0 or not np.all(np.isfinite(pts)):
        raise KinmoDataError(graph.shape_id, "part graph has no or non-finite points")
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    scale = float(graph.scale)
    if not (math.isfinite(scale) and scale > 0.0):
        scale = float(np.linalg.norm(hi - lo))
    if scale <= 0.0:
        raise KinmoDataError(graph.shape_id, "part graph has zero size")
    return (lo + hi) / 2.0, scale


def graph_tensors(
    graph: PartGraph,
    vocab: SemanticVocab | None = None,
    n_points: int | None = None,
) -> GraphTensors:
    """Convert a part graph to model tensors in its normalised frame.

    Parameters
    ----------
    graph : PartGraph
    vocab : SemanticVocab, optional
        Maps node names to embedding indices; all zeros without one.
    n_points : int, optional
        Keep the first ``n_points`` samples of each node (the samples are i.i.d. area-uniform,
        so a prefix is a uniform subsample). All when ``None``.

    Returns
    -------
    GraphTensors

    Raises
    ------
    KinmoDataError
        Inconsistent array shapes, no points, or non-finite OBBs (naming the shape).
    """
    v = graph.n_nodes
    sid = graph.shape_id
    pts = np.asarray(graph.points)
    if pts.ndim != 3 or pts.shape[0] != v or pts.shape[2] != 3 or pts.shape[1] == 0:
        raise KinmoDataError(sid, f"points must be (V={v}, P, 3), got {pts.shape}")
    center, scale = shape_frame(graph)
    if n_points is not None:
        pts = pts[:, : max(1, int(n_points))]
    oc = (np.asarray(graph.obb_center, dtype=np.float64) - center) / scale
    ax = np.asarray(graph.obb_axes, dtype=np.float64)
    size = 2.0 * np.asarray(graph.obb_half_extents, dtype=np.float64) / scale
    if not (np.all(np.isfinite(oc)) and np.all(np.isfinite(ax)) and np.all(np.isfinite(size))):
        raise KinmoDataError(sid, "non-finite OBB in part graph")
    local = (pts.astype(np.float64) - np.asarray(graph.obb_center)[:, None, :]) / scale
    e = np.asarray(graph.sibling_edges, dtype=np.int64).reshape(-1, 2)
    if e.size and (e.min() < 0 or e.max() >= v):
        raise KinmoDataError(sid, "sibling edge index out of range")
    dist = np.asarray(graph.sibling_distance, dtype=np.float64) / scale
    names = graph.node_names
    sem = [vocab.index(n) for n in names] if vocab is not None else [0] * v
    gt = GraphTensors(
        shape_id=sid,
        category=graph.category,
        center=center,
        scale=scale,
        points=torch.from_numpy(local.astype(np.float32)),
        obb_center=torch.from_numpy(oc.astype(np.float32)),
        obb_axes=torch.from_numpy(ax.astype(np.float32)),
        obb_size=torch.from_numpy(size.astype(np.float32)),
        is_leaf=torch.from_numpy(np.asarray(graph.is_leaf, dtype=bool)),
        depth=torch.from_numpy(np.asarray(graph.depth, dtype=np.int64)),
        parent=torch.from_numpy(np.asarray(graph.parent, dtype=np.int64)),
        semantic=torch.tensor(sem, dtype=torch.int64),
        edges=torch.from_numpy(e),
        contact=torch.from_numpy(np.asarray(graph.sibling_contact, dtype=bool)),
        distance=torch.from_numpy(np.nan_to_num(dist, nan=1.0).astype(np.float32)),
    )
    if graph.has_labels:
        fine = np.asarray(graph.edge_fine, dtype=np.int64)
        if fine.shape != (e.shape[0],):
            raise KinmoDataError(sid, f"edge_fine must be ({e.shape[0]},), got {fine.shape}")
        if fine.size and (fine.min() < 0 or fine.max() >= len(FINE_TYPES)):
            raise KinmoDataError(sid, "edge_fine holds an unknown type index")
        o = np.asarray(graph.edge_axis_origin, dtype=np.float64)
        d = np.asarray(graph.edge_axis_direction, dtype=np.float64)
        has = np.isin(fine, [FINE_INDEX[t] for t in FINE_TYPES if t not in ("Fixed", "None")])
        ok = has & np.all(np.isfinite(o), axis=1) & np.all(np.isfinite(d), axis=1)
        if np.any(has & ~ok):
            raise KinmoDataError(sid, "a moving edge has a non-finite ground-truth axis")
        o_n = np.where(ok[:, None], (np.nan_to_num(o) - center) / scale, 0.0)
        n = np.linalg.norm(np.nan_to_num(d), axis=1, keepdims=True)
        d_n = np.where(ok[:, None], np.nan_to_num(d) / np.where(n > 0, n, 1.0), 0.0)
        gt.edge_fine = torch.from_numpy(fine)
        gt.axis_origin = torch.from_numpy(o_n.astype(np.float32))
        gt.axis_direction = torch.from_numpy(d_n.astype(np.float32))
        gt.has_axis = torch.from_numpy(ok)
    return gt


def node_features(obb_center: torch.Tensor, obb_axes: torch.Tensor, obb_size: torch.Tensor,
                  is_leaf: torch.Tensor, depth: torch.Tensor) -> torch.Tensor:
    """Node feature matrix ``(V, NODE_DIM) float32`` (module docstring).

    Parameters
    ----------
    obb_center : (V, 3) float32
    obb_axes : (V, 3, 3) float32
    obb_size : (V, 3) float32
    is_leaf : (V,) bool
    depth : (V,) int64
    """
    v = obb_center.shape[0]
    return torch.cat(
        [
            obb_center,
            obb_axes.reshape(v, 9),
            obb_size,
            is_leaf.to(obb_center.dtype)[:, None],
            depth.to(obb_center.dtype)[:, None] / 8.0,
        ],
        dim=1,
    )


def edge_features(
    edges: torch.Tensor,
    obb_center: torch.Tensor,
    obb_axes: torch.Tensor,
    obb_size: torch.Tensor,
    contact: torch.Tensor,
    distance: torch.Tensor,
) -> torch.Tensor:
    """Geometric features of directed sibling edges, ``(E, EDGE_DIM) float32``.

    Parameters
    ----------
    edges : (E, 2) int64
        ``(i, j)`` node indices.
    obb_center : (V, 3) float32
    obb_axes : (V, 3, 3) float32
        Orthonormal rows.
    obb_size : (V, 3) float32
    contact : (E,) bool
    distance : (E,) float32
        Normalised mesh distance.

    Returns
    -------
    (E, 27) float32
        See the module docstring for the layout.
    """
    i, j = edges[:, 0], edges[:, 1]
    dc = obb_center[i] - obb_center[j]
    ai, aj = obb_axes[i], obb_axes[j]
    in_i = torch.einsum("eab,eb->ea", ai, dc)
    in_j = torch.einsum("eab,eb->ea", aj, dc)
    dots = torch.einsum("eab,ecb->eac", ai, aj).abs().reshape(-1, 9)
    return torch.cat(
        [
            dc,
            dc.norm(dim=1, keepdim=True),
            in_i,
            in_j,
            dots,
            obb_size[i],
            obb_size[j],
            contact.to(dc.dtype)[:, None],
            distance[:, None],
        ],
        dim=1,
    )


@dataclass
class GraphBatch:
    """Several :class:`GraphTensors` concatenated into one disjoint graph.

    Node and edge indices are offset per graph. ``B`` graphs, ``V`` nodes, ``E`` edges in all.

    Attributes
    ----------
    graphs : list of GraphTensors
        The members (for their ids, frames and per-graph slicing).
    points : (V, P, 3) float32
    node_feat : (V, NODE_DIM) float32
    obb_center, obb_axes, obb_size : (V, 3), (V, 3, 3), (V, 3) float32
    parent : (V,) int64
        Batch index of the parent, -1 for roots.
    depth : (V,) int64
    semantic : (V,) int64
    node_graph : (V,) int64
        Graph index of each node.
    edges : (E, 2) int64
    edge_feat : (E, EDGE_DIM) float32
    edge_graph : (E,) int64
    node_offsets, edge_offsets : (B + 1,) int64
        ``graph b`` owns nodes ``node_offsets[b]:node_offsets[b+1]`` (same for edges).
    edge_fine, axis_origin, axis_direction, has_axis : tensors or None
        Concatenated labels when every member has them.
    """

    graphs: list[GraphTensors]
    points: torch.Tensor
    node_feat: torch.Tensor
    obb_center: torch.Tensor
    obb_axes: torch.Tensor
    obb_size: torch.Tensor
    parent: torch.Tensor
    depth: torch.Tensor
    semantic: torch.Tensor
    node_graph: torch.Tensor
    edges: torch.Tensor
    edge_feat: torch.Tensor
    edge_graph: torch.Tensor
    node_offsets: torch.Tensor
    edge_offsets: torch.Tensor
    edge_fine: torch.Tensor | None = None
    axis_origin: torch.Tensor | None = None
    axis_direction: torch.Tensor | None = None
    has_axis: torch.Tensor | None = None

    @property
    def n_nodes(self) -> int:
        """``V``."""
        return int(self.parent.shape[0])

    @property
    def n_edges(self) -> int:
        """``E``."""
        return int(self.edges.shape[0])

    def to(self, device: torch.device | str) -> GraphBatch:
        """Move every tensor to ``device`` (returns a new batch)."""
        kw = {}
        for name, val in self.__dict__.items():
            kw[name] = val.to(device) if isinstance(val, torch.Tensor) else val
        return GraphBatch(**kw)

    def edge_labels(self, types: str) -> torch.Tensor:
        """Ground-truth type index of each edge, ``(E,) int64``, fine or coarse.

        Raises
        ------
        ValueError
            The batch has no labels or ``types`` is not ``"fine"``/``"coarse"``.
        """
        if self.edge_fine is None:
            raise ValueError("batch has no ground-truth labels")
        if types == "fine":
            return self.edge_fine
        if types == "coarse":
            lut = torch.tensor(FINE_TO_COARSE, dtype=torch.int64, device=self.edge_fine.device)
            return lut[self.edge_fine]
        raise ValueError(f"types must be 'fine' or 'coarse', got {types!r}")


def collate(graphs: Sequence[GraphTensors], n_points: int | None = None,
            generator: torch.Generator | None = None) -> GraphBatch:
    """Concatenate graphs into a :class:`GraphBatch`.

    Parameters
    ----------
    graphs : sequence of GraphTensors
        At least one. All must have the same number of points per node (after subsampling).
    n_points : int, optional
        Subsample each node's points to this many: a random subset drawn with ``generator``
        when one is given (training), else the first ``n_points`` (evaluation).
    generator : torch.Generator, optional

    Returns
    -------
    GraphBatch

    Raises
    ------
    ValueError
        Empty input or inconsistent point counts.
    """
    if not graphs:
        raise ValueError("collate needs at least one graph")
    pts, nf, oc, oa, osz, par, dep, sem, ng, ed, ef, eg = ([] for _ in range(12))
    labels_ok = all(g.edge_fine is not None for g in graphs)
    lf, lo, ld, lh = [], [], [], []
    n_off = [0]
    e_off = [0]
    for b, g in enumerate(graphs):
        p = g.points
        if n_points is not None and p.shape[1] > n_points:
            if generator is not None:
                idx = torch.randperm(p.shape[1], generator=generator)[:n_points]
                p = p[:, idx]
            else:
                p = p[:, :n_points]
        pts.append(p)
        nf.append(node_features(g.obb_center, g.obb_axes, g.obb_size, g.is_leaf, g.depth))
        oc.append(g.obb_center)
        oa.append(g.obb_axes)
        osz.append(g.obb_size)
        par.append(torch.where(g.parent >= 0, g.parent + n_off[-1], g.parent))
        dep.append(g.depth)
        sem.append(g.semantic)
        ng.append(torch.full((g.n_nodes,), b, dtype=torch.int64))
        ed.append(g.edges + n_off[-1])
        ef.append(edge_features(g.edges, g.obb_center, g.obb_axes, g.obb_size, g.contact,
                                g.distance))
        eg.append(torch.full((g.n_edges,), b, dtype=torch.int64))
        if labels_ok:
            lf.append(g.edge_fine)
            lo.append(g.axis_origin)
            ld.append(g.axis_direction)
            lh.append(g.has_axis)
        n_off.append(n_off[-1] + g.n_nodes)
        e_off.append(e_off[-1] + g.n_edges)
    if len({p.shape[1] for p in pts}) != 1:
        raise ValueError("graphs have different numbers of points per node; pass n_points")
    batch = GraphBatch(
        graphs=list(graphs),
        points=torch.cat(pts),
        node_feat=torch.cat(nf),
        obb_center=torch.cat(oc),
        obb_axes=torch.cat(oa),
        obb_size=torch.cat(osz),
        parent=torch.cat(par),
        depth=torch.cat(dep),
        semantic=torch.cat(sem),
        node_graph=torch.cat(ng),
        edges=torch.cat(ed).reshape(-1, 2),
        edge_feat=torch.cat(ef).reshape(-1, EDGE_DIM),
        edge_graph=torch.cat(eg),
        node_offsets=torch.tensor(n_off, dtype=torch.int64),
        edge_offsets=torch.tensor(e_off, dtype=torch.int64),
    )
    if labels_ok:
        batch.edge_fine = torch.cat(lf)
        batch.axis_origin = torch.cat(lo).reshape(-1, 3)
        batch.axis_direction = torch.cat(ld).reshape(-1, 3)
        batch.has_axis = torch.cat(lh)
    return batch
