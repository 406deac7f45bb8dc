"""The part graph of a shape: the unit of kinmo's caches and models.

One :class:`PartGraph` per shape holds, for every node of the PartNet hierarchy, its surface
points and OBB, the parent-child edges, and the directed sibling edges with contact flag and
distance; for PartNet-Mobility objects also the ground-truth motion label of each sibling
edge (:mod:`kinmo.data.labels`). It is saved as one ``.npz`` file per shape
(:meth:`PartGraph.save`, atomic).

Frames and units: mesh frame of the OBJ files (PartNet objects are y-up), mesh units.
"""

from __future__ import annotations

import hashlib
import json
import zipfile
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any

import numpy as np

from kinmo.errors import KinmoDataError
from kinmo.io import atomic_path

#: Bump when the layout or the computation of cached graphs changes: older caches are redone.
#: 2: ``meta["checksum"]`` (:func:`arrays_checksum`) in every cached graph.
#: 3: OBBs of symmetric parts rolled into world alignment, ties decided the same way in every
#: quarter turn (:func:`kinmo.geometry.fit_obb`, issue 36's rotation criterion).
CACHE_VERSION = 3

_OPTIONAL = ("edge_fine", "edge_axis_origin", "edge_axis_direction", "edge_link", "node_link")


def arrays_checksum(arrays: dict[str, Any]) -> str:
    """Checksum of a cached graph's arrays: SHA-256 of every array's name, dtype, shape and
    bytes, in name order (``meta_json``, which stores the checksum, is left out).

    Parameters
    ----------
    arrays : dict of str to array_like
        The arrays of the ``.npz`` file.

    Returns
    -------
    str
        32 hex digits.
    """
    h = hashlib.sha256()
    for name in sorted(arrays):
        if name == "meta_json":
            continue
        a = np.asarray(arrays[name])
        h.update(f"{name}\0{a.dtype.str}\0{a.shape}\0".encode())
        h.update(a.tobytes())
    return h.hexdigest()[:32]


@dataclass
class PartGraph:
    """Part graph of one shape (Liu et al. 2023 Sec. 3.1).

    Nodes are all hierarchy nodes in depth-first pre-order (root first, parents before
    children). ``V`` nodes, ``P`` points per node (1024 by default), ``Ec`` parent-child edges,
    ``Es`` directed sibling edges.

    Attributes
    ----------
    shape_id, category, format : str
        Folder name, ``model_cat``, ``"partnet"`` or ``"partnet-mobility"``.
    node_ids : (V,) int64
        PartNet node ids.
    node_names : list of str
        Semantic names.
    parent : (V,) int64
        Index of the parent node, -1 for the root.
    is_leaf : (V,) bool
    depth : (V,) int64
        0 for the root.
    points : (V, P, 3) float32
        Area-uniform surface samples (leaves from their meshes, inner nodes from the union of
        their leaves' meshes); mesh frame.
    obb_center : (V, 3) float64
    obb_axes : (V, 3, 3) float64
        Orthonormal rows (right-handed), canonical order and signs (see
        :func:`kinmo.geometry.fit_obb`).
    obb_half_extents : (V, 3) float64
        Half side lengths along each axis row.
    child_edges : (Ec, 2) int64
        ``(parent, child)`` node indices.
    sibling_edges : (Es, 2) int64
        Directed ``(i, j)`` pairs of distinct nodes with the same parent, both directions
        present, sorted lexicographically. Edge ``(i, j)`` is read as "i moves relative to j".
    sibling_contact : (Es,) bool
        The two nodes' meshes come within ``meta["contact_tolerance"]``.
    sibling_distance : (Es,) float64
        Exact minimum mesh-to-mesh distance, clipped to ``meta["distance_cap"]``.
    scale : float
        Diagonal of the shape's axis-aligned bounding box (mesh units).
    edge_fine : (Es,) int64 or None
        Ground-truth fine type index into :data:`kinmo.data.model.FINE_TYPES` (PartNet-Mobility).
    edge_axis_origin, edge_axis_direction : (Es, 3) float64 or None
        Ground-truth axis (a point on it and its unit direction), NaN for ``Fixed`` / ``None``.
    edge_link : (Es,) int64 or None
        Id of the moving link of the edge's joint, -1 for ``Fixed`` / ``None``.
    node_link : (V,) int64 or None
        Link id of a node all of whose leaves belong to one link, -1 for nodes spanning links.
    meta : dict
        JSON-serialisable: ``cache_version``, ``source``, ``contact_tolerance``,
        ``distance_cap``, ``n_points``, ``seed``, ``links`` (the links as in
        ``mobility_v2.json`` with normalised axes), and anything else worth keeping.
    """

    shape_id: str
    category: str
    format: str
    node_ids: np.ndarray
    node_names: list[str]
    parent: np.ndarray
    is_leaf: np.ndarray
    depth: np.ndarray
    points: np.ndarray
    obb_center: np.ndarray
    obb_axes: np.ndarray
    obb_half_extents: np.ndarray
    child_edges: np.ndarray
    sibling_edges: np.ndarray
    sibling_contact: np.ndarray
    sibling_distance: np.ndarray
    scale: float
    edge_fine: np.ndarray | None = None
    edge_axis_origin: np.ndarray | None = None
    edge_axis_direction: np.ndarray | None = None
    edge_link: np.ndarray | None = None
    node_link: np.ndarray | None = None
    meta: dict[str, Any] = field(default_factory=dict)

    @property
    def n_nodes(self) -> int:
        """Number of nodes ``V``."""
        return int(self.node_ids.shape[0])

    @property
    def has_labels(self) -> bool:
        """True when ground-truth motion labels are present (PartNet-Mobility)."""
        return self.edge_fine is not None

    def leaves_of(self, index: int) -> np.ndarray:
        """Indices of the leaf nodes below node ``index`` (itself if a leaf), ``(k,) int64``."""
        below = np.zeros(self.n_nodes, dtype=bool)
        below[index] = True
        for v in range(index + 1, self.n_nodes):  # pre-order: descendants follow their ancestor
            p = self.parent[v]
            if p >= 0 and below[p]:
                below[v] = True
        return np.flatnonzero(below & self.is_leaf).astype(np.int64)

    def save(self, path: str | Path) -> None:
        """Write the graph as one ``.npz`` file (uncompressed: saving is a quarter of
        ``kinmo prepare``'s time when compressed, for 30% smaller files), atomically.

        ``meta["checksum"]`` of the written file is :func:`arrays_checksum` of its arrays
        (checked by :meth:`load`)."""
        arrays: dict[str, Any] = {}
        for f in fields(self):
            v = getattr(self, f.name)
            if f.name == "meta" or f.name == "node_names":
                continue
            if v is None:
                continue
            arrays[f.name] = np.asarray(v)
        arrays["node_names"] = np.asarray(self.node_names, dtype=np.str_)
        meta = dict(self.meta)
        meta.setdefault("cache_version", CACHE_VERSION)
        meta["checksum"] = arrays_checksum(arrays)
        arrays["meta_json"] = np.asarray(json.dumps(meta))
        with atomic_path(path) as tmp:
            with open(tmp, "wb") as fh:
                np.savez(fh, **arrays)

    @classmethod
    def load(cls, path: str | Path) -> PartGraph:
        """Read a graph written by :meth:`save`.

        The file is checked whole: its zip CRCs, and the checksum of its arrays
        (``meta["checksum"]`` in the file, cache version 2 on; older files have none; it is
        not kept in the loaded graph's ``meta``).

        Raises
        ------
        KinmoDataError
            If the file is missing, unreadable, corrupt (damaged archive, checksum mismatch)
            or lacks a field; one line naming the file.
        """
        path = Path(path)
        redo = "re-run `kinmo prepare` to rebuild it"
        try:
            with np.load(path, allow_pickle=False) as z:
                data = {k: z[k] for k in z.files}
        except FileNotFoundError:
            raise KinmoDataError(path, "part graph is missing") from None
        except (OSError, ValueError, EOFError, zipfile.BadZipFile, zipfile.LargeZipFile) as e:
            msg = " ".join(str(e).split()) or type(e).__name__
            raise KinmoDataError(path, f"corrupt or unreadable part graph ({msg}); {redo}") from None
        try:
            meta = json.loads(str(data["meta_json"]))
            if not isinstance(meta, dict):
                raise ValueError("meta_json is not an object")
        except KeyError:
            raise KinmoDataError(path, "part graph lacks field 'meta_json'") from None
        except ValueError as e:
            raise KinmoDataError(path, f"corrupt part graph (meta_json: {e}); {redo}") from None
        stored = meta.pop("checksum", None)  # the file's, not the graph's: save recomputes it
        if stored is None and int(meta.get("cache_version", 1)) >= 2:
            raise KinmoDataError(path, f"corrupt part graph (no checksum); {redo}")
        if stored is not None and stored != arrays_checksum(data):
            raise KinmoDataError(path, f"corrupt part graph (checksum mismatch); {redo}")
        try:
            kwargs: dict[str, Any] = {}
            for f in fields(cls):
                if f.name == "meta":
                    kwargs["meta"] = meta
                elif f.name == "node_names":
                    kwargs["node_names"] = [str(s) for s in data["node_names"]]
                elif f.name in ("shape_id", "category", "format"):
                    kwargs[f.name] = str(data[f.name])
                elif f.name == "scale":
                    kwargs["scale"] = float(data["scale"])
                elif f.name in _OPTIONAL:
                    kwargs[f.name] = data.get(f.name)
                else:
                    kwargs[f.name] = data[f.name]
        except KeyError as e:
            raise KinmoDataError(path, f"part graph lacks field {e}") from None
        return cls(**kwargs)
