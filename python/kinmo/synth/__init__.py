"""Procedural articulated objects in the PartNet-Mobility and PartNet formats.

``kinmo synth OUT --n N --seed S`` (or :func:`generate_dataset`) writes N randomised objects
of thirteen categories, each a folder exactly like a real PartNet-Mobility object (``meta.json``,
``result.json``, ``textured_objs/``, ``mobility_v2.json``, ``semantics.txt``) or, with
``partnet=True``, like a PartNet shape (``meta.json``, ``result.json``, ``objs/``). They give
unlimited training and test data with exact ground truth, covering every moving fine
motion type of Liu et al. 2023 but ``PR_H``:

========================  =====================================================  ==========
category                  moving parts                                           fine types
========================  =====================================================  ==========
``StorageFurniture``      side doors (left/right), flaps (bottom/top), drawers   R_V_S, R_H_S, P_H
``Refrigerator``          1-2 side doors, optional freezer drawer                R_V_S, P_H
``Oven``                  bottom-hinged door, rotary knobs, tray, drawer         R_H_S, R_H_C, P_H
``Microwave``             side (or bottom) door, knobs, turntable                R_V_S, R_H_C, R_V_C
``Dishwasher``            bottom-hinged door, sliding racks                      R_H_S, P_H
``Laptop``                lid hinged along the back edge of the base             R_H_S
``Table``                 1-3 drawers under the top                              P_H
``Bucket``                bail handle swinging about the axis through its pins   R_H_S
``KitchenPot``            lid lifting straight up                                P_V
``Bottle``                screw cap: slides up while turning (cylindrical)       PR_V
``Safe``                  side door carrying a dial and a lever (a chain)        R_V_S, R_H_C, R_H_S
``WashingMachine``        round side-hinged door, dials                          R_V_S, R_H_C
``TrashCan``              lid hinged at the back top edge, foot pedal            R_H_S
========================  =====================================================  ==========

Object ids
    Folder name and ``anno_id`` of object ``k`` of a run with seed ``S`` is
    ``"9" + f"{S:05d}" + f"{k:05d}"`` (:func:`synthetic_id`), e.g. ``90004200017``: numeric
    like PartNet ids, at least 11 digits and starting with 9, so it cannot collide with real
    PartNet / PartNet-Mobility annotation ids (at most 7 digits), and unique over all seeds
    (k < 100000). ``meta.json`` has ``user_id: "kinmo-synth"``.

Determinism
    Object ``k`` is generated from ``numpy.random.default_rng([seed, k])`` alone, its category
    from a seeded permutation of the categories (round robin, so every category appears
    when ``n >= len(categories)``): the same seed, ``k`` and categories give byte-identical
    files, independent of ``n``.

Geometry
    y-up, front +z, closed meshes (watertight, outward winding), parts touching but not
    overlapping, real-world proportions normalised like PartNet-Mobility (rest-pose bounding
    box centred, diagonal about 2). Joint conventions: see :mod:`kinmo.synth.assembly`.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from kinmo.io import write_json
from kinmo.synth.appliances import dishwasher, microwave, oven, refrigerator, safe, washing_machine
from kinmo.synth.assembly import LinkSpec, Motion, Node, SynthObject, normalize
from kinmo.synth.containers import bottle, bucket, kitchen_pot, trash_can
from kinmo.synth.furniture import storage_furniture, table
from kinmo.synth.laptop import laptop
from kinmo.synth.writer import write_object

#: Version of the generators; bumped whenever the output for a given seed changes.
SYNTH_VERSION = 1

#: Category name (``model_cat``) -> generator ``rng -> SynthObject`` (metres).
CATEGORIES: dict[str, Callable[[np.random.Generator], SynthObject]] = {
    "StorageFurniture": storage_furniture,
    "Refrigerator": refrigerator,
    "Oven": oven,
    "Microwave": microwave,
    "Dishwasher": dishwasher,
    "Laptop": laptop,
    "Table": table,
    "Bucket": bucket,
    "KitchenPot": kitchen_pot,
    "Bottle": bottle,
    "Safe": safe,
    "WashingMachine": washing_machine,
    "TrashCan": trash_can,
}

#: Range of the rest-pose bounding-box diagonal per category (mesh units), as measured on
#: the real PartNet-Mobility objects.
DIAGONAL: dict[str, tuple[float, float]] = {
    "Bucket": (2.1, 2.6),
    "KitchenPot": (2.6, 2.95),
    "Table": (1.7, 2.2),
    "Bottle": (1.95, 2.5),
}
_DEFAULT_DIAGONAL = (1.9, 2.15)

__all__ = [
    "CATEGORIES",
    "SYNTH_VERSION",
    "LinkSpec",
    "Motion",
    "Node",
    "SynthObject",
    "generate_dataset",
    "generate_object",
    "synthetic_id",
    "write_object",
]


def synthetic_id(seed: int, k: int) -> str:
    """The folder name / ``anno_id`` of object ``k`` of a run with ``seed``.

    Parameters
    ----------
    seed : int
        >= 0.
    k : int
        Object index, 0 <= k < 100000.

    Returns
    -------
    str
        ``"9" + f"{seed:05d}" + f"{k:05d}"``.

    Raises
    ------
    ValueError
        ``seed`` negative or ``k`` out of range.
    """
    if seed < 0:
        raise ValueError(f"seed must be >= 0, got {seed}")
    if not 0 <= k < 100000:
        raise ValueError(f"object index must be in [0, 100000), got {k}")
    return f"9{seed:05d}{k:05d}"


def _check_categories(categories: Sequence[str] | None) -> list[str]:
    if categories is None:
        return list(CATEGORIES)
    cats = list(dict.fromkeys(categories))
    bad = [c for c in cats if c not in CATEGORIES]
    if bad or not cats:
        raise ValueError(
            f"unknown categories {bad or '(none given)'}; choose from {', '.join(CATEGORIES)}"
        )
    return cats


def generate_object(category: str, seed: int, k: int = 0) -> SynthObject:
    """Generate one normalised object.

    Parameters
    ----------
    category : str
        A key of :data:`CATEGORIES`.
    seed, k : int
        The object is drawn from ``numpy.random.default_rng([seed, k])``.

    Returns
    -------
    SynthObject
        Centred, scaled to the category's diagonal range (mesh units); ``params`` holds the
        sampled parameters (metres before scaling) plus ``scale``.

    Raises
    ------
    ValueError
        Unknown category.
    """
    if category not in CATEGORIES:
        raise ValueError(f"unknown category {category!r}; choose from {', '.join(CATEGORIES)}")
    rng = np.random.default_rng([seed, k])
    obj = CATEGORIES[category](rng)
    lo, hi = DIAGONAL.get(category, _DEFAULT_DIAGONAL)
    scale = normalize(obj, float(rng.uniform(lo, hi)))
    obj.params = {
        k_: (float(v) if isinstance(v, (float, np.floating)) else v) for k_, v in obj.params.items()
    }
    obj.params["scale"] = scale
    obj.check()
    return obj


def generate_dataset(
    out: str | Path,
    n: int,
    seed: int,
    categories: Sequence[str] | None = None,
    partnet: bool = False,
    progress: bool = True,
    keep: Callable[[SynthObject], bool] | None = None,
    max_draws: int | None = None,
) -> list[Path]:
    """Generate ``n`` objects into ``out/<id>/`` and a manifest ``out/synth-<seed>.json``.

    Parameters
    ----------
    out : str or Path
        Output folder (created if missing). Existing object folders with the same ids are
        replaced; other content is left alone.
    n : int
        Number of objects, 0 <= n <= 100000.
    seed : int
        >= 0; see the module docstring for what it determines.
    categories : sequence of str, optional
        Subset of :data:`CATEGORIES` (default: all), used round robin in a seeded order.
    partnet : bool
        Write PartNet folders (``objs/``, no motion) instead of PartNet-Mobility ones.
    progress : bool
        Show a rich progress bar.
    keep : callable, optional
        ``SynthObject -> bool``: only objects it accepts are written (e.g. one kinematic
        structure, ``kinmo synth --structure``). Object ``k`` is still drawn from
        ``[seed, k]`` with its round-robin category, so the kept objects are those of an
        unfiltered run (ids with gaps) and the run stays deterministic; each category keeps
        its round-robin share of the ``n`` objects.
    max_draws : int, optional
        Bound on the objects drawn with ``keep`` (default ``100 * n + 100``).

    Returns
    -------
    list of Path
        The object folders, in index order.

    Raises
    ------
    ValueError
        Bad ``n``, ``seed`` or category names; or ``keep`` accepted fewer than ``n`` of
        ``max_draws`` objects (the message says how many).
    KinmoDataError
        ``out`` exists and is not a folder.
    OSError
        ``out`` cannot be written.
    """
    if not 0 <= n <= 100000:
        raise ValueError(f"n must be in [0, 100000], got {n}")
    if seed < 0:
        raise ValueError(f"seed must be >= 0, got {seed}")
    cats = _check_categories(categories)
    order = [cats[i] for i in np.random.default_rng(seed).permutation(len(cats))]
    from kinmo.io import output_dir

    out = output_dir(out)
    folders: list[Path] = []
    records: list[dict] = []
    draws = (100 * n + 100 if max_draws is None else max_draws) if keep is not None else n
    drawn = 0
    # next index k of each category: object k is always of category order[k % len(order)]
    next_k = {c: i for i, c in enumerate(order)}

    def one(slot: int) -> str:
        # the slot's category round robin; draws its objects until one is kept
        nonlocal drawn
        cat = order[slot % len(order)]
        while True:
            k = next_k[cat]
            if drawn >= draws or k >= 100000:
                raise ValueError(
                    f"only {len(folders)} of the {n} objects asked for passed the filter in {drawn} draws "
                    f"(categories {', '.join(cats)})"
                )
            next_k[cat] += len(order)
            drawn += 1
            obj = generate_object(cat, seed, k)
            if keep is not None and not keep(obj):
                continue
            oid = synthetic_id(seed, k)
            folders.append(write_object(obj, out / oid, oid, partnet=partnet))
            records.append(
                {"id": oid, "category": cat, "links": len(obj.links) + 1, "params": obj.params}
            )
            return cat

    if progress:
        from rich.progress import (
            BarColumn,
            MofNCompleteColumn,
            Progress,
            TextColumn,
            TimeElapsedColumn,
        )

        with Progress(
            TextColumn("[bold]synth[/]"),
            BarColumn(),
            MofNCompleteColumn(),
            TimeElapsedColumn(),
            TextColumn("{task.description}"),
        ) as bar:
            task = bar.add_task("", total=n)
            for slot in range(n):
                bar.update(task, description=one(slot))
                bar.advance(task)
    else:
        for slot in range(n):
            one(slot)
    folders.sort(key=lambda f: int(f.name))
    records.sort(key=lambda r: int(r["id"]))
    write_json(
        out / f"synth-{seed}.json",
        {
            "generator": "kinmo.synth",
            "version": SYNTH_VERSION,
            "seed": seed,
            "n": n,
            "drawn": drawn,
            "format": "partnet" if partnet else "partnet-mobility",
            "categories": cats,
            "objects": records,
        },
    )
    return folders
