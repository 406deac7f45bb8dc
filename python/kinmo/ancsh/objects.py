"""A category's objects mapped onto its ANCSH parts (Li et al. CVPR 2020, category level).

ANCSH is category-level: every object of a category must share one kinematic structure
(:mod:`kinmo.ancsh.structure`). This module finds a category's objects under a dataset root
and maps each onto the category's ANCSH parts (:func:`scan_category`,
:func:`object_parts_of`): rigid groups of links (:func:`kinmo.data.labels.rigid_groups`, the
same grouping as the renderer's per-point ``part`` ids, :mod:`kinmo.render.ancsh_gt`) become
parts, ordered canonically by :func:`kinmo.ancsh.structure.object_parts` with the rest-pose
centroid of each *rigid group* (:func:`link_centroids`; so a door and its handle count as one
body when doors are ordered top to bottom). It also names categories (:func:`category_key`,
:func:`resolve_category`). No torch: the training samples are in :mod:`kinmo.ancsh.dataset`.

Frames: mesh frame (y-up), mesh units.
"""

from __future__ import annotations

import re
import tempfile
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from kinmo.ancsh.structure import (
    NOT_EXPRESSIBLE,
    KinematicStructure,
    ObjectParts,
    category_structure,
    object_parts,
)
from kinmo.data.labels import rigid_groups
from kinmo.data.readers import find_shapes, read_meta, read_shape
from kinmo.errors import KinmoDataError, KinmoError
from kinmo.render.ancsh_gt import link_meshes
from kinmo.synth import SynthObject, write_object

__all__ = [
    "CategoryObjects",
    "category_key",
    "link_centroids",
    "object_parts_of",
    "resolve_category",
    "scan_category",
    "structure_filter",
    "synth_structure",
]


def category_key(name: str) -> str:
    """Case- and separator-insensitive form of a category name.

    ``"StorageFurniture"``, ``"storage_furniture"``, ``"storage-furniture"`` and
    ``"Storage Furniture"`` all give ``"storagefurniture"``.
    """
    return re.sub(r"[\s_\-]+", "", str(name)).lower()


def resolve_category(name: str, categories: Sequence[str]) -> str:
    """The category of ``categories`` that ``name`` designates.

    Parameters
    ----------
    name : str
        As typed by a user: any case, CamelCase or snake_case (``storage_furniture``).
    categories : sequence of str
        Known category names (PartNet-Mobility ``model_cat``, CamelCase).

    Returns
    -------
    str
        The matching entry of ``categories``.

    Raises
    ------
    KinmoError
        No category matches (the message lists the known ones).
    """
    want = category_key(name)
    for c in sorted(set(categories)):
        if category_key(c) == want:
            return c
    known = ", ".join(sorted(set(categories))) or "none"
    raise KinmoError(f"unknown category {name!r} (known: {known})")


def link_centroids(shape: Any) -> dict[int, np.ndarray]:
    """Rest-pose centroid of the rigid group of every link (mesh frame, y-up).

    The area-weighted mean of the surfaces of all links in the link's rigid group
    (:func:`kinmo.data.labels.rigid_groups`); a group without geometry gets the origin.

    Parameters
    ----------
    shape : kinmo.data.model.Shape
        A PartNet-Mobility object (``links`` set).

    Returns
    -------
    dict of int to (3,) float64
        Link id -> centroid of its group.

    Raises
    ------
    KinmoDataError
        A mesh is missing or malformed.
    """

    links = list(shape.links or [])
    groups = rigid_groups(links)
    meshes = link_meshes(shape, links)
    acc: dict[int, np.ndarray] = {}
    area: dict[int, float] = {}
    for lid, g in groups.items():
        for v, f in meshes.get(lid, ()):
            v = np.asarray(v, dtype=np.float64)
            f = np.asarray(f, dtype=np.int64)
            if len(v) == 0:
                continue
            if len(f):
                tri = v[f]
                a = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
                s, c = float(a.sum()), (a[:, None] * tri.mean(1)).sum(0)
            else:
                s, c = 0.0, np.zeros(3)
            if s <= 0:  # degenerate mesh: vertex mean, unit weight
                s, c = 1.0, v.mean(0)
            acc[g] = acc.get(g, np.zeros(3)) + c
            area[g] = area.get(g, 0.0) + s
    return {lid: (acc[g] / area[g] if g in acc else np.zeros(3)) for lid, g in groups.items()}


def object_parts_of(folder: str | Path) -> tuple[Any, ObjectParts | None]:
    """Read an object and map it onto ANCSH parts with the canonical part order.

    Parameters
    ----------
    folder : str or Path
        A PartNet-Mobility-format object folder (real, generated or pseudo-labelled).

    Returns
    -------
    shape : kinmo.data.model.Shape
    parts : ObjectParts or None
        None when the object cannot be expressed by ANCSH (no moving joint, a free moving
        part). A cylindrical joint is taken as prismatic (:func:`kinmo.ancsh.structure.object_parts`).

    Raises
    ------
    KinmoDataError
        Unreadable object, or not in the PartNet-Mobility format.
    """

    shape = read_shape(folder)
    if not shape.links:
        raise KinmoDataError(folder, "no mobility_v2.json: not a PartNet-Mobility object")
    parts = object_parts(shape.links)
    if parts is not None and parts.structure.n_parts > 2:
        # siblings are ordered by position: needs the centroids (mesh loading) only then
        parts = object_parts(shape.links, link_centroids(shape))
    return shape, parts


@dataclass
class CategoryObjects:
    """The objects of one category under a dataset root, mapped onto ANCSH parts.

    Attributes
    ----------
    category : str
        Canonical (CamelCase) name.
    structure : KinematicStructure or None
        The category's most common structure (:func:`kinmo.ancsh.structure.category_structure`).
    folders : dict of str to Path
        Object id -> folder, every object of the category.
    parts : dict of str to ObjectParts or None
        Object id -> its parts (None: not expressible).
    fitting : list of str
        Sorted ids of the objects with exactly ``structure``.
    failed : dict of str to str
        Object id -> reason, for objects of the category that could not be read.
    """

    category: str
    structure: KinematicStructure | None
    folders: dict[str, Path]
    parts: dict[str, ObjectParts | None]
    fitting: list[str]
    failed: dict[str, str] = field(default_factory=dict)

    def describe(self, oid: str) -> str:
        """One line telling why ``oid`` does (not) fit the category structure."""
        p = self.parts.get(oid)
        want = self.structure.signature() if self.structure else "none"
        if oid in self.failed:
            return f"{oid}: unreadable ({self.failed[oid]})"
        if p is None:
            return f"{oid}: {NOT_EXPRESSIBLE}"
        if oid in self.fitting:
            return f"{oid}: fits {want}"
        return f"{oid}: structure {p.structure.signature()}, not the category's {want}"


def synth_structure(obj: SynthObject) -> KinematicStructure | None:
    """The ANCSH kinematic structure of a generated object, as a written copy of it reads.

    The object is written in the PartNet-Mobility format to a temporary folder and read back
    by :func:`object_parts_of`, so the structure (part order included) is the one training
    and evaluation will see.

    Parameters
    ----------
    obj : kinmo.synth.SynthObject

    Returns
    -------
    KinematicStructure or None
        None when ANCSH cannot express the object (no moving joint).
    """
    with tempfile.TemporaryDirectory(prefix="kinmo-structure-") as tmp:
        folder = write_object(obj, Path(tmp) / "object", "0")
        parts = object_parts_of(folder)[1]
    return None if parts is None else parts.structure


def structure_filter(signature: str) -> Callable[[SynthObject], bool]:
    """A ``keep`` predicate for :func:`kinmo.synth.generate_dataset`: objects of one structure.

    Parameters
    ----------
    signature : str
        :meth:`KinematicStructure.signature`, e.g. ``"0<R-1"`` (one revolute child of the
        base: a laptop, a one-door refrigerator) or ``"0<R-1,0<R-2"``.

    Returns
    -------
    callable
        ``SynthObject -> bool``.

    Raises
    ------
    ValueError
        ``signature`` is not of the form ``p<T-c,...`` with T in R, P.
    """
    sig = signature.replace(" ", "")
    if not re.fullmatch(r"\d+<[RP]-\d+(,\d+<[RP]-\d+)*", sig):
        raise ValueError(f"structure {signature!r}: expected parent<R|P-child joints, e.g. 0<R-1 or 0<R-1,0<P-2")

    def keep(obj: SynthObject) -> bool:
        s = synth_structure(obj)
        return s is not None and s.signature() == sig

    return keep


def scan_category(
    root: str | Path, category: str, structure: KinematicStructure | None = None
) -> CategoryObjects:
    """Find the objects of a category under ``root`` and their ANCSH parts.

    Parameters
    ----------
    root : str or Path
        Dataset folder of PartNet-Mobility-format objects (possibly nested).
    category : str
        Any spelling accepted by :func:`resolve_category`.
    structure : KinematicStructure, optional
        Impose this structure (e.g. the one a model was trained with) instead of the most
        common one.

    Returns
    -------
    CategoryObjects

    Raises
    ------
    KinmoDataError
        ``root`` is not a folder.
    KinmoError
        No object of that category under ``root``.
    """

    root = Path(root)
    folders: dict[str, Path] = {}
    cats: set[str] = set()
    for f in find_shapes(root):
        if not (f / "mobility_v2.json").is_file():
            continue
        try:
            cat = read_meta(f)[0]
        except KinmoDataError:
            continue
        cats.add(cat)
        if category_key(cat) == category_key(category):
            folders[f.name] = f
    if not folders:
        raise KinmoError(
            f"{root}: no PartNet-Mobility object of category {category!r} "
            f"(categories there: {', '.join(sorted(cats)) or 'none'})"
        )
    name = resolve_category(category, sorted(cats))
    parts: dict[str, ObjectParts | None] = {}
    failed: dict[str, str] = {}
    for oid, f in sorted(folders.items()):
        try:
            parts[oid] = object_parts_of(f)[1]
        except KinmoDataError as e:
            failed[oid] = str(e)
            parts[oid] = None
    if structure is None:
        structure, fitting = category_structure(parts)
    else:
        fitting = sorted(i for i, p in parts.items() if p is not None and p.structure == structure)
    return CategoryObjects(name, structure, folders, parts, fitting, failed)
