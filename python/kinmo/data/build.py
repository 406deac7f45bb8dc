"""Build the :class:`~kinmo.data.graph.PartGraph` of a shape (Liu et al. 2023 Sec. 3.1).

The graph has one node per hierarchy node (depth-first pre-order), parent-child edges, and
directed sibling edges (every ordered pair of distinct children of a node) carrying a
contact flag and the exact mesh-to-mesh distance. Geometry comes from the Rust core
(:mod:`kinmo.geometry`):

- meshes: every ``.obj`` named by a leaf, loaded once (:func:`~kinmo.geometry.load_objs`);
  a leaf listing several names is the union of those meshes, an inner node the union of its
  leaves' meshes;
- points: ``n_points`` area-uniform samples per node on that union
  (:func:`~kinmo.geometry.sample_surface_groups`, seeded per node), stored float32;
- OBB: :func:`~kinmo.geometry.fit_obb_batch` on the union of the node's mesh vertices;
- contact: :func:`~kinmo.geometry.contact_pairs` over the *leaf* meshes with tolerance
  ``distance_cap * diag``; the distance of two sibling nodes is the minimum over pairs of
  their leaves, ``distance_cap * diag`` when no pair is that close, and the siblings are in
  contact when it is ``<= contact_tolerance * diag``. ``diag`` is the diagonal of the
  shape's axis-aligned bounding box (``PartGraph.scale``).

PartNet-Mobility objects also get the ground-truth labels of :mod:`kinmo.data.labels`.

Frames and units: mesh frame of the OBJ files (y-up), mesh units.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from kinmo.data.graph import CACHE_VERSION, PartGraph
from kinmo.data.labels import label_sibling_edges
from kinmo.data.model import COARSE_TYPES, FINE_TYPES, Link, Shape, ShapeFormat
from kinmo import limits
from kinmo.errors import KinmoDataError
from kinmo.geometry import contact_pairs, fit_obb_batch, load_obj, load_objs, sample_surface_groups

__all__ = ["MeshesOnce", "build_graph", "links_to_json", "load_named_meshes", "load_shape_meshes"]


def links_to_json(links: list[Link]) -> list[dict]:
    """JSON-ready form of links, with unit axes and sorted limits (see the readers)."""
    out = []
    for lk in links:
        j = lk.joint
        out.append(
            {
                "id": lk.id,
                "parent": lk.parent,
                "name": lk.name,
                "joint": j.type.value,
                "parts": list(lk.parts),
                "origin": None if j.origin is None else [float(x) for x in j.origin],
                "direction": None if j.direction is None else [float(x) for x in j.direction],
                "limit": None if j.limit is None else [float(x) for x in j.limit],
                "rotates": bool(j.rotates),
                "rotation_limit": j.rotation_limit,
            }
        )
    return out


def _strip_path(message: str, path: Path) -> str:
    msg = " ".join(str(message).split())
    for prefix in (f"{path}: ", f"{path}:", str(path)):
        if msg.startswith(prefix):
            return msg[len(prefix):].strip() or msg
    return msg


def load_shape_meshes(paths: list[Path]) -> list[tuple[np.ndarray, np.ndarray]]:
    """Load OBJ files with :func:`kinmo.geometry.load_objs`, naming a bad file on failure.

    Parameters
    ----------
    paths : list of Path

    Returns
    -------
    list of (vertices (V, 3) float64, faces (F, 3) int64)

    Raises
    ------
    KinmoDataError
        A file is missing, unreadable, does not parse, has non-finite vertices or bad face
        indices, or has no faces (an empty file, or text that is not an OBJ); the error names
        that file. A shape with such a file fails as a whole, even when the file is one of
        several meshes of a leaf: a part silently missing its geometry would be cached as
        "ok".
    """

    try:
        meshes = load_objs(paths)
    except (OSError, ValueError):
        pass
    else:
        for p, (_, f) in zip(paths, meshes):
            if len(f) == 0:
                raise KinmoDataError(p, "no faces (an empty file, or not an OBJ file)")
        return meshes
    # Find the first failing file to name it (only on the failure path).
    for p in paths:
        try:
            load_obj(p)
        except (OSError, ValueError) as e:
            raise KinmoDataError(p, _strip_path(str(e), p)) from None
    raise KinmoDataError(paths[0].parent, "loading the meshes failed")  # pragma: no cover


def _check_part_limits(shape: Shape) -> None:
    """The ``parts`` and ``edges`` limits of :mod:`kinmo.limits` on the hierarchy alone."""
    h = shape.hierarchy
    where = shape.mesh_dir.parent
    leaves = sum(h.nodes[n].is_leaf for n in h.order)
    limits.check("parts", int(leaves), where)
    kids = [len(h.nodes[n].children) for n in h.order]
    limits.check("edges", int(sum(c * (c - 1) for c in kids)), where)


def load_named_meshes(shape: Shape) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Every mesh the shape's hierarchy names, read once: the one load that a command's
    stages (part graph, the selector's sweep, the exporters) share for one shape.

    The resource limits (:mod:`kinmo.limits`: parts and edges of the hierarchy and each
    file's size before reading, triangles after) are checked as :func:`build_graph` checks
    them.

    Returns
    -------
    dict of str to (vertices (V, 3) float64, faces (F, 3) int64)
        Mesh name (``<name>.obj`` in ``shape.mesh_dir``) -> mesh, mesh frame and units.

    Raises
    ------
    KinmoDataError
        As :func:`load_shape_meshes`, or a limit exceeded.
    """
    _check_part_limits(shape)
    names = list(dict.fromkeys(o for n in shape.hierarchy.order for o in shape.hierarchy.nodes[n].objs))
    paths = [shape.mesh_path(o) for o in names]
    for p in paths:
        limits.check_file(p)
    meshes = load_shape_meshes(paths)
    for p, (_, f) in zip(paths, meshes):
        limits.check("triangles", len(f), p)
    return dict(zip(names, meshes))


class MeshesOnce:
    """A shape's meshes by name (:func:`load_named_meshes`), read on the first call and
    kept: a command reads each shape's meshes once and passes them to the part graph, the
    selector's sweep and the exporters ("one path per data flow").

    Calling it returns ``dict of str to (vertices (V, 3) float64, faces (F, 3) int64)``;
    it raises :class:`~kinmo.errors.KinmoDataError` as :func:`load_named_meshes`."""

    def __init__(self, shape: Shape) -> None:
        self.shape = shape
        self._named: dict[str, tuple[np.ndarray, np.ndarray]] | None = None

    def __call__(self) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        if self._named is None:
            self._named = load_named_meshes(self.shape)
        return self._named


def _mesh_areas(meshes: list[tuple[np.ndarray, np.ndarray]]) -> np.ndarray:
    out = np.zeros(len(meshes))
    for k, (v, f) in enumerate(meshes):
        if len(f):
            t = v[f]
            out[k] = 0.5 * np.linalg.norm(np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]), axis=1).sum()
    return out


def build_graph(
    shape: Shape,
    n_points: int = 1024,
    seed: int = 0,
    contact_tolerance: float = 0.01,
    distance_cap: float = 0.1,
    meshes: Mapping[str, tuple[np.ndarray, np.ndarray]] | None = None,
) -> PartGraph:
    """Build the part graph of a shape read by :func:`kinmo.data.readers.read_shape`.

    Parameters
    ----------
    shape : Shape
    n_points : int
        Surface points per node, >= 1.
    seed : int
        Sampling seed; the same inputs and seed give the same graph.
    contact_tolerance : float
        Contact threshold as a fraction of the bounding-box diagonal, >= 0.
    distance_cap : float
        Distances above ``distance_cap * diag`` are clipped to it (fraction of the diagonal),
        ``>= contact_tolerance``.
    meshes : mapping of str to (vertices, faces), optional
        The shape's meshes by name, already read (:func:`load_named_meshes`); read here
        when not given.

    Returns
    -------
    PartGraph
        See :class:`~kinmo.data.graph.PartGraph`. ``meta`` holds ``cache_version``,
        ``source``, ``contact_tolerance`` and ``distance_cap`` (absolute,
        mesh units), ``contact_tolerance_rel`` and ``distance_cap_rel`` (fractions of the
        diagonal), ``n_points``, ``seed``, ``fine_types``, ``coarse_types``, ``counts``
        (``n_nodes``, ``n_leaves``, ``n_sibling_edges``, ``n_moving_joints``, ``n_meshes``) and,
        for PartNet-Mobility, ``links`` (:func:`links_to_json`).

    Raises
    ------
    KinmoDataError
        A mesh cannot be loaded (naming the ``.obj``), a leaf has no surface (zero area), or
        the shape is degenerate (zero-size bounding box).
    ValueError
        Bad parameters.
    """

    if n_points < 1:
        raise ValueError(f"n_points must be >= 1, got {n_points}")
    if not 0 <= contact_tolerance <= distance_cap:
        raise ValueError(
            f"need 0 <= contact_tolerance <= distance_cap, got {contact_tolerance}, {distance_cap}"
        )
    h = shape.hierarchy
    order = list(h.order)
    n_nodes = len(order)
    index = {nid: k for k, nid in enumerate(order)}
    nodes = [h.nodes[n] for n in order]
    parent = np.array([-1 if n.parent is None else index[n.parent] for n in nodes], np.int64)
    is_leaf = np.array([n.is_leaf for n in nodes], dtype=bool)
    depth = np.zeros(n_nodes, np.int64)
    for v in range(1, n_nodes):
        depth[v] = depth[parent[v]] + 1

    # Resource limits (kinmo.limits), before any mesh is read or edge allocated
    # (load_named_meshes checks them first; meshes read elsewhere are checked here).
    if meshes is None:
        named = load_named_meshes(shape)
    else:
        _check_part_limits(shape)
        named = meshes

    # Meshes: every OBJ once, in leaf pre-order.
    names: dict[str, int] = {}
    for n in nodes:
        for o in n.objs:
            names.setdefault(o, len(names))
    paths = [shape.mesh_path(o) for o in names]
    meshes = [named[o] for o in names]

    # Mesh indices under every node (post-order accumulation); leaf indices likewise.
    leaf_index = np.cumsum(is_leaf) - 1  # node index -> leaf index (valid for leaves)
    node_meshes: list[list[int]] = [[] for _ in range(n_nodes)]
    for v in range(n_nodes - 1, -1, -1):
        if is_leaf[v]:
            node_meshes[v] = [names[o] for o in nodes[v].objs]
        else:
            acc: list[int] = []
            for c in nodes[v].children:
                acc.extend(node_meshes[index[c]])
            node_meshes[v] = list(dict.fromkeys(acc))
    leaves = np.flatnonzero(is_leaf)
    # Pre-order: the subtree of v is the index range [v, v + size[v]).
    size = np.ones(n_nodes, np.int64)
    for v in range(n_nodes - 1, 0, -1):
        size[parent[v]] += size[v]

    all_vertices = np.concatenate([m[0] for m in meshes]) if meshes else np.zeros((0, 3))
    if all_vertices.shape[0] == 0:
        raise KinmoDataError(shape.mesh_dir, "the meshes have no vertices")
    lo, hi = all_vertices.min(0), all_vertices.max(0)
    diag = float(np.linalg.norm(hi - lo))
    if not diag > 0:
        raise KinmoDataError(shape.mesh_dir, "degenerate shape: zero-size bounding box")
    del all_vertices

    # Points.
    try:
        points = sample_surface_groups(meshes, node_meshes, n_points, seed)
    except ValueError:
        areas = _mesh_areas(meshes)
        for v in leaves:
            if areas[node_meshes[v]].sum() <= 0:
                raise KinmoDataError(
                    paths[node_meshes[v][0]],
                    f"leaf node {nodes[v].id} ({nodes[v].name!r}) has no surface (zero area)",
                ) from None
        raise
    points = np.asarray(points, dtype=np.float32)

    # OBBs on the union of each node's mesh vertices.
    obb_c, obb_a, obb_h = fit_obb_batch(
        [
            meshes[m[0]][0] if len(m) == 1 else np.concatenate([meshes[k][0] for k in m])
            for m in node_meshes
        ]
    )

    # Edges.
    child_edges = np.stack([parent[1:], np.arange(1, n_nodes)], axis=1).astype(np.int64)
    child_edges = child_edges.reshape(-1, 2)
    cap = distance_cap * diag
    tol = contact_tolerance * diag
    leaf_meshes = []
    for v in leaves:
        ms = [meshes[k] for k in node_meshes[v]]
        if len(ms) == 1:
            leaf_meshes.append(ms[0])
        else:
            offs = np.cumsum([0] + [m[0].shape[0] for m in ms[:-1]])
            leaf_meshes.append(
                (np.concatenate([m[0] for m in ms]),
                 np.concatenate([m[1] + o for m, o in zip(ms, offs)]))
            )
    n_leaves = len(leaves)
    dist = np.full((n_leaves, n_leaves), cap)
    if n_leaves > 1:
        pairs, pd = contact_pairs(leaf_meshes, cap)
        pairs = np.asarray(pairs, dtype=np.int64).reshape(-1, 2)
        pd = np.minimum(np.asarray(pd, dtype=np.float64), cap)
        dist[pairs[:, 0], pairs[:, 1]] = pd
        dist[pairs[:, 1], pairs[:, 0]] = pd
    del leaf_meshes

    edges: list[np.ndarray] = []
    dists: list[np.ndarray] = []
    for v in range(n_nodes):
        kids = [index[c] for c in nodes[v].children]
        if len(kids) < 2:
            continue
        # Leaves of v in pre-order are contiguous per child: reduce the leaf distance block.
        kid_leaves = [leaf_index[k + np.flatnonzero(is_leaf[k : k + size[k]])] for k in kids]
        flat = np.concatenate(kid_leaves)
        starts = np.cumsum([0] + [len(x) for x in kid_leaves[:-1]])
        block = dist[np.ix_(flat, flat)]
        block = np.minimum.reduceat(np.minimum.reduceat(block, starts, axis=0), starts, axis=1)
        k = len(kids)
        ii, jj = np.nonzero(~np.eye(k, dtype=bool))
        kid_arr = np.asarray(kids, dtype=np.int64)
        edges.append(np.stack([kid_arr[ii], kid_arr[jj]], axis=1))
        dists.append(block[ii, jj])
    if edges:
        sibling_edges = np.concatenate(edges)
        sibling_distance = np.concatenate(dists)
        o = np.lexsort((sibling_edges[:, 1], sibling_edges[:, 0]))
        sibling_edges, sibling_distance = sibling_edges[o], sibling_distance[o]
    else:
        sibling_edges = np.zeros((0, 2), np.int64)
        sibling_distance = np.zeros(0)
    sibling_distance = np.minimum(sibling_distance, cap).astype(np.float64)
    sibling_contact = sibling_distance <= tol

    node_ids = np.array(order, dtype=np.int64)
    n_moving = 0
    labels = None
    if shape.format is ShapeFormat.PARTNET_MOBILITY and shape.links is not None:
        labels = label_sibling_edges(
            h, shape.links, node_ids, sibling_edges, obb_c, obb_a, obb_h
        )
        n_moving = sum(1 for lk in shape.links if lk.joint.is_moving)

    meta = {
        "cache_version": CACHE_VERSION,
        "source": str(Path(shape.path).resolve()),
        "contact_tolerance": tol,
        "distance_cap": cap,
        "contact_tolerance_rel": float(contact_tolerance),
        "distance_cap_rel": float(distance_cap),
        "n_points": int(n_points),
        "seed": int(seed),
        "fine_types": list(FINE_TYPES),
        "coarse_types": list(COARSE_TYPES),
        "counts": {
            "n_nodes": n_nodes,
            "n_leaves": int(n_leaves),
            "n_sibling_edges": int(sibling_edges.shape[0]),
            "n_moving_joints": int(n_moving),
            "n_meshes": len(meshes),
        },
    }
    if shape.links is not None:
        meta["links"] = links_to_json(shape.links)
    json.dumps(meta)  # fail here, not at save time, if something is not serialisable
    return PartGraph(
        shape_id=shape.id,
        category=shape.category,
        format=shape.format.value,
        node_ids=node_ids,
        node_names=[n.name for n in nodes],
        parent=parent,
        is_leaf=is_leaf,
        depth=depth,
        points=points,
        obb_center=np.asarray(obb_c, dtype=np.float64),
        obb_axes=np.asarray(obb_a, dtype=np.float64),
        obb_half_extents=np.asarray(obb_h, dtype=np.float64),
        child_edges=child_edges,
        sibling_edges=sibling_edges,
        sibling_contact=sibling_contact,
        sibling_distance=sibling_distance,
        scale=diag,
        edge_fine=None if labels is None else labels.fine,
        edge_axis_origin=None if labels is None else labels.axis_origin,
        edge_axis_direction=None if labels is None else labels.axis_direction,
        edge_link=None if labels is None else labels.link,
        node_link=None if labels is None else labels.node_link,
        meta=meta,
    )
