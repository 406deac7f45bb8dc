"""The train/test split and the ANCSH plan of ``kinmo train all`` (which models are trained on
which objects), and where ``kinmo eval --category`` finds a category's runs."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path
from typing import Any

from kinmo.ancsh.objects import category_key
from kinmo.ancsh.structure import object_parts, structure_groups
from kinmo.data.readers import find_shapes, read_shape
from kinmo.errors import KinmoDataError, KinmoError
from kinmo.runs import DEFAULT_RUN
from kinmo.train.split import make_split

__all__ = ["ANCSH_PLAN_FILE", "CategoryRuns", "ancsh_plan", "category_runs", "default_categories",
           "structure_split"]


def ancsh_plan(labeled: Path, split_file: Path | None = None, categories: list[str] | None = None,
               min_train: int = 2) -> tuple[dict[str, list[Any]], dict[str, str]]:
    """Which ANCSH models ``kinmo train all`` trains: one per category and kinematic structure.

    ANCSH is category-level with one structure, so a category whose objects have several
    structures (Refrigerator, StorageFurniture) gets one model per structure that has at least
    ``min_train`` training objects and one test object of the split
    (:func:`kinmo.ancsh.structure.structure_groups`); each test object is evaluated with the
    model of its structure. With ``categories`` given (``--category``), only those are
    planned, by the same rule; one that no structure qualifies gets one model anyway, of its
    most common structure with a training and a test object, else with a training object
    (evaluate that on other objects with ``kinmo eval --category C --data DIR``).

    Parameters
    ----------
    labeled : Path
        PartNet-Mobility dataset folder.
    split_file : Path, optional
        ``split.json`` whose ``test`` ids are held out (missing: every object is training).
    categories : list of str, optional
        Categories to plan, any spelling; default every category of ``labeled``.
    min_train : int

    Returns
    -------
    plan : dict of str to list of StructureGroup
        Category (canonical name) → its structures to train, most common first; sorted.
    skipped : dict of str to str
        Category → why it gets no model (the counts of its most common structures).

    Raises
    ------
    KinmoError
        A named category has no object under ``labeled``.
    """

    per = _object_structures(labeled)
    test: set[str] = set()
    if split_file is not None and split_file.is_file():
        test = set(json.loads(split_file.read_text()).get("test", []))
    wanted = None
    if categories:
        names = {category_key(c): c for c in per}
        wanted = set()
        for c in categories:
            if category_key(c) not in names:
                raise KinmoError(f"{labeled}: no object of category {c!r} (categories: {', '.join(sorted(per))})")
            wanted.add(names[category_key(c)])
    plan: dict[str, list[Any]] = {}
    skipped: dict[str, str] = {}
    for cat, objs in sorted(per.items()):
        if wanted is not None and cat not in wanted:
            continue
        kept, rest = structure_groups(objs, test, min_train=min_train)
        if not kept and wanted is not None:  # named: the best structure there is
            kept = ([g for g in rest if g.train and g.test] or [g for g in rest if g.train])[:1]
            rest = [g for g in rest if g not in kept]
        if kept:
            plan[cat] = kept
        elif not rest:
            skipped[cat] = "no object with a revolute/prismatic structure"
        else:
            more = f"; {len(rest) - 3} more structures" if len(rest) > 3 else ""
            skipped[cat] = "; ".join(g.describe() for g in rest[:3]) + more
    return plan, skipped


def _object_structures(labeled: Path) -> dict[str, dict[str, Any]]:
    """Category → object id → its ANCSH parts (None: not expressible) of every readable
    PartNet-Mobility object under ``labeled``."""

    per: dict[str, dict[str, Any]] = {}
    for path in find_shapes(labeled):
        try:
            shape = read_shape(path)
        except KinmoDataError:
            continue
        per.setdefault(shape.category, {})[shape.id] = object_parts(shape.links or [])
    return per


def structure_split(labeled: Path, test_fraction: float = 0.25, seed: int = 0) -> Any:
    """The train/test split of ``kinmo train all``, stratified by category and kinematic structure.

    :func:`kinmo.train.split.make_split` over strata ``<category>|<structure>`` for the
    structures (:func:`kinmo.ancsh.structure.object_parts`) that at least two objects of the
    category share, and ``<category>|other`` for the rest of the category (single structures,
    objects ANCSH cannot express). So every structure with 3 or more objects has at least 2
    training and 1 test object, and ANCSH can be trained and evaluated per structure
    (:func:`ancsh_plan`); a plain category-stratified split can leave a category's test
    objects all of structures without training objects (Refrigerator on the shared data).

    Parameters
    ----------
    labeled : Path
        PartNet-Mobility dataset folder.
    test_fraction : float
    seed : int

    Returns
    -------
    kinmo.train.split.Split
        Its ``categories`` are the real categories.
    """
    from collections import Counter

    per = _object_structures(labeled)
    key = {(c, i): (o.structure.signature() if o is not None else None) for c, objs in per.items()
           for i, o in objs.items()}
    count = Counter((c, s) for (c, _), s in key.items() if s is not None)
    ids = [i for (_, i) in key]
    strata = [f"{c}|{s}" if s is not None and count[(c, s)] >= 2 else f"{c}|other" for (c, _), s in key.items()]
    sp = make_split(ids, strata, test_fraction, seed)
    sp.categories = {i: c for (c, i) in key}
    return sp


def default_categories(labeled: Path, split_file: Path | None = None, min_train: int = 2) -> tuple[list[str], dict[str, str]]:
    """Categories with enough data for ANCSH (:func:`ancsh_plan`).

    A category qualifies when one of its kinematic structures has at least ``min_train``
    training objects and one test object of the split.

    Returns
    -------
    categories : list of str
        Sorted.
    skipped : dict of str to str
        Category → reason it was left out.
    """
    plan, skipped = ancsh_plan(labeled, split_file, min_train=min_train)
    return sorted(plan), skipped


#: File under ``OUT/ancsh/`` listing the trained categories with their structures and the
#: categories left out with the reason (read by ``kinmo eval --category``).
ANCSH_PLAN_FILE = "categories.json"


@dataclasses.dataclass(frozen=True)
class CategoryRuns:
    """Where ``kinmo eval --category C`` finds the ANCSH runs of a category (:func:`category_runs`).

    Attributes
    ----------
    runs : Path or None
        Folder holding the category's runs; None when there are none.
    scans : Path or None
        The run's render cache of the category (``kinmo train all``'s ``scans/<Category>/``) to
        reuse for the test scans.
    message : str
        Where the runs were found, or (``runs`` None) one line saying why there are none and
        the command that would train them.
    category : str
        The category as the runs name it (the folder's name), else as given.
    """

    runs: Path | None
    scans: Path | None
    message: str
    category: str = ""


def category_runs(category: str, cwd: Path | None = None) -> CategoryRuns:
    """The ANCSH runs of ``category`` without a path: those of the last ``kinmo train all`` in
    the default run folder (``runs/all/ancsh/<Category>/``), else those of ``kinmo train ancsh``
    (``runs/ancsh/<category>/``).

    Parameters
    ----------
    category : str
        Any spelling (``refrigerator``, ``Refrigerators``, ``storage_furniture``).
    cwd : Path, optional
        Current folder (default ``Path.cwd()``).

    Returns
    -------
    CategoryRuns
    """

    cwd = Path.cwd() if cwd is None else cwd
    key = category_key(category)
    keys = {key, key[:-1] if key.endswith("s") else key}  # plural: refrigerators
    run = cwd / DEFAULT_RUN
    ancsh = run / "ancsh"
    if ancsh.is_dir():
        for d in sorted(p for p in ancsh.iterdir() if p.is_dir()):
            if category_key(d.name) in keys:
                scans = run / "scans" / d.name  # the category's render cache of train all
                return CategoryRuns(d, scans if scans.is_dir() else None,
                                    f"runs of `kinmo train all` in {d}", d.name)
    single = cwd / "runs" / "ancsh"
    if single.is_dir():
        for d in sorted(p for p in single.iterdir() if p.is_dir()):
            if category_key(d.name) in keys:
                return CategoryRuns(d, None, f"runs of `kinmo train ancsh` in {d}", d.name)
    plan_file = ancsh / ANCSH_PLAN_FILE
    if plan_file.is_file():
        try:
            skipped = json.loads(plan_file.read_text()).get("skipped", {})
        except (OSError, ValueError):
            skipped = {}
        for cat, why in skipped.items():
            if category_key(cat) in keys:
                return CategoryRuns(None, None, (
                    f"{cat} was not trained by `kinmo train all` in {run}: {why} (a model needs 2 training "
                    f"and 1 test object of one structure); `kinmo train all --category {cat}` trains it anyway"))
    if run.is_dir():
        return CategoryRuns(None, None, f"no ANCSH run of {category!r} in {run} (its ANCSH stage has not "
                                        f"run yet?): run `kinmo train all`")
    return CategoryRuns(None, None, f"no ANCSH run of {category!r} in ./runs: run `kinmo train all` first "
                                    f"(or `kinmo train ancsh --category {category}`), or give --runs")


