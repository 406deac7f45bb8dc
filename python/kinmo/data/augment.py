"""Hierarchy and name augmentations of PartNet-Mobility shapes (issue 22, part 1).

A user's segmented asset is flat (a root with one node per part) and its nodes have generic
names (``part_3``), where PartNet shapes have deep hierarchies and semantic names. Training
the motion GNN on augmented copies of its training shapes makes its prediction robust to both:

- :func:`flatten_shape`: the hierarchy replaced by a root with one leaf per *mobility link*
  (every leaf of the link's parts merged into one node: ``mode="link"``, a user GLB with a
  node per link) or one leaf per *PartNet leaf* (``mode="leaf"``, finer than a link, as a
  part segmenter's output). The links keep their joints; their ``parts`` name the new leaves,
  so :func:`kinmo.data.build.build_graph` labels the flat graph's sibling edges by the same
  rules (:mod:`kinmo.data.labels`) as the original's.
- :func:`generic_names`: every node renamed ``"unknown"`` (root) / ``part_<k>`` (leaves), the
  names a user's exporter gives; :class:`kinmo.features.SemanticVocab` maps both to index 0
  (unknown), which the GNN then sees in training.
- :func:`flat_variants`: seeded flattened (and possibly unnamed) variant graphs of training
  graphs, built from their source shapes (``graph.meta["source"]``).

Frames and units: unchanged (mesh frame, y-up).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace
from typing import Literal

import numpy as np

from kinmo.data.build import build_graph
from kinmo.data.graph import PartGraph
from kinmo.data.model import Link, PartHierarchy, PartNode, Shape
from kinmo.data.readers import read_shape

__all__ = ["FlatMode", "UNKNOWN_NAME", "flat_groups", "flatten_shape", "generic_names",
           "drop_names", "flat_variants"]

FlatMode = Literal["link", "leaf"]

#: Node name of an unnamed node (maps to the semantic vocabulary's index 0).
UNKNOWN_NAME = "unknown"


def flat_groups(shape: Shape, mode: FlatMode = "link") -> list[tuple[str, list[int]]]:
    """The leaves of the flattened hierarchy of a shape, as groups of PartNet leaves.

    Parameters
    ----------
    shape : Shape
        A PartNet-Mobility shape (``shape.links`` set).
    mode : {"link", "leaf"}
        ``"link"``: one group per link with parts (all PartNet leaves below its parts), then
        one group per PartNet leaf in no link; ``"leaf"``: one group per PartNet leaf.

    Returns
    -------
    list of (name, leaf ids)
        In a deterministic order (links by id, leaves in hierarchy pre-order); the name is the
        link's name (``"link"``) or the leaf's PartNet name (``"leaf"``).

    Raises
    ------
    ValueError
        ``mode`` is unknown, or ``mode="link"`` and the shape has no links.
    """
    h = shape.hierarchy
    leaves = [n for n in h.order if h.nodes[n].is_leaf]
    if mode == "leaf":
        return [(h.nodes[n].name, [n]) for n in leaves]
    if mode != "link":
        raise ValueError(f"mode must be 'link' or 'leaf', got {mode!r}")
    if shape.links is None:
        raise ValueError(f"shape {shape.id} has no links to flatten by")
    seen: set[int] = set()
    groups: list[tuple[str, list[int]]] = []
    for lk in sorted(shape.links, key=lambda lk: lk.id):
        g = [leaf for part in lk.parts for leaf in h.leaves(part) if leaf not in seen]
        if g:
            seen.update(g)
            groups.append((lk.name, list(dict.fromkeys(g))))
    groups += [(h.nodes[n].name, [n]) for n in leaves if n not in seen]
    return groups


def flatten_shape(shape: Shape, mode: FlatMode = "link", names: bool = True) -> Shape:
    """The shape with its hierarchy flattened to a root and one leaf per link or PartNet leaf.

    Parameters
    ----------
    shape : Shape
        A PartNet-Mobility shape (:func:`kinmo.data.readers.read_shape`).
    mode : {"link", "leaf"}
        See :func:`flat_groups`.
    names : bool
        Keep semantic names (the link's or leaf's name); ``False`` gives the generic names of
        :func:`generic_names` (leaf ``k`` ``part_<k>``). The root is ``"unknown"`` either
        way: a user's root node is named after the file.

    Returns
    -------
    Shape
        Same id, category, folders and meshes. Node ids: root 0, leaf ``k`` (0-based, order of
        :func:`flat_groups`) id ``k + 1``, its ``objs`` the union of its group's meshes. Every
        link's ``parts`` are the new leaves holding its PartNet leaves (joints unchanged).

    Raises
    ------
    ValueError
        As :func:`flat_groups`.
    """
    h = shape.hierarchy
    groups = flat_groups(shape, mode)
    nodes: dict[int, PartNode] = {}
    leaf_of: dict[int, int] = {}
    for k, (name, g) in enumerate(groups):
        objs = tuple(dict.fromkeys(o for leaf in g for o in h.nodes[leaf].objs))
        nid = k + 1
        nm = name if names else f"part_{k}"
        nodes[nid] = PartNode(nid, nm, nm, (), objs, 0)
        for leaf in g:
            leaf_of[leaf] = nid
    rname = UNKNOWN_NAME  # a user's root is named after the file, never a semantic name
    nodes[0] = PartNode(0, rname, rname, tuple(range(1, len(groups) + 1)), (), None)
    hier = PartHierarchy(nodes, 0, [0, *range(1, len(groups) + 1)])
    links = None
    if shape.links is not None:
        links = []
        for lk in shape.links:
            parts = tuple(dict.fromkeys(leaf_of[leaf] for part in lk.parts
                                        for leaf in h.leaves(part) if leaf in leaf_of))
            links.append(Link(lk.id, lk.parent, lk.name, parts, lk.joint))
    return replace(shape, hierarchy=hier, links=links)


def generic_names(n_nodes: int, is_leaf: np.ndarray) -> list[str]:
    """Generic node names: ``"unknown"`` for inner nodes, ``part_<k>`` for the ``k``-th leaf.

    Parameters
    ----------
    n_nodes : int
    is_leaf : (n_nodes,) bool

    Returns
    -------
    list of str
    """
    out, k = [], 0
    for v in range(n_nodes):
        if is_leaf[v]:
            out.append(f"part_{k}")
            k += 1
        else:
            out.append(UNKNOWN_NAME)
    return out


def drop_names(graph: PartGraph) -> PartGraph:
    """A copy of ``graph`` with :func:`generic_names` (arrays shared, ``meta["names_dropped"]``)."""
    meta = dict(graph.meta)
    meta["names_dropped"] = True
    return replace(graph, node_names=generic_names(graph.n_nodes, graph.is_leaf), meta=meta)


def flat_variants(
    graphs: Sequence[PartGraph],
    flatten_prob: float,
    drop_names_prob: float,
    seed: int = 0,
) -> list[PartGraph]:
    """Augmented training graphs: the originals plus flattened variants, names dropped at random.

    For each graph, with probability ``flatten_prob`` a flattened variant
    (:func:`flatten_shape`, ``"link"`` or ``"leaf"`` with equal odds) is built from its source
    shape (``meta["source"]``, read with :func:`kinmo.data.readers.read_shape`) with the
    graph's own sampling parameters (``meta``: ``n_points``, ``seed``, ``contact_tolerance_rel``,
    ``distance_cap_rel``) and appended. Then every graph, original or variant, has its names
    dropped (:func:`drop_names`) with probability ``drop_names_prob``.

    Parameters
    ----------
    graphs : sequence of PartGraph
        Labelled PartNet-Mobility graphs (a :func:`kinmo.data.build.build_graph` cache).
    flatten_prob, drop_names_prob : float
        In ``[0, 1]``.
    seed : int
        The draws are made by ``numpy.random.default_rng(seed)``: same inputs, same output.

    Returns
    -------
    list of PartGraph
        The originals (in order), then the variants; variants carry ``meta["flattened"]``
        (the mode). A flattened variant without any labelled sibling edge (a shape with one
        link) is not added, nor is one of a graph without ``meta["source"]`` (built in
        memory).

    Raises
    ------
    ValueError
        A probability outside ``[0, 1]``.
    KinmoDataError
        A source shape cannot be read or built.
    """

    for name, p in (("flatten_prob", flatten_prob), ("drop_names_prob", drop_names_prob)):
        if not 0.0 <= p <= 1.0:
            raise ValueError(f"{name} must be in [0, 1], got {p}")
    rng = np.random.default_rng(seed)
    out = list(graphs)
    if flatten_prob > 0:
        for g in graphs:
            if rng.random() >= flatten_prob:
                continue
            mode: FlatMode = "link" if rng.random() < 0.5 else "leaf"
            if not g.meta.get("source"):  # built in memory, no shape folder: no variant
                continue
            shape = read_shape(g.meta["source"])
            m = g.meta
            flat = build_graph(flatten_shape(shape, mode), n_points=int(m.get("n_points", 1024)),
                               seed=int(m.get("seed", 0)),
                               contact_tolerance=float(m.get("contact_tolerance_rel", 0.01)),
                               distance_cap=float(m.get("distance_cap_rel", 0.1)))
            flat.meta["flattened"] = mode
            if flat.has_labels and len(flat.sibling_edges) and np.any(flat.edge_link >= 0):
                out.append(flat)
    if drop_names_prob > 0:
        out = [drop_names(g) if rng.random() < drop_names_prob else g for g in out]
    return out
