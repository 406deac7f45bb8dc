"""Model bundles: one folder holding everything a prediction needs (issue 22).

Layout of a bundle folder (written by :func:`write_bundle`, e.g. ``runs/all/model/`` by
``kinmo train all``)::

    bundle.json      {"format": "kinmo-model-bundle", "version": 1, "gnn": "gnn",
                      "axis": "axis" | null, "ranker": "ranker.json" | null,
                      "selector": "ranker" | "paper" | "none", "trained_on": [ids...]}
    gnn/             the motion-GNN run (model.pt: weights, config, semantic vocabulary;
                     members/<k>/model.pt: its ensemble members, when it has any)
    axis/            optional: the axis-selection network run (model.pt ...)
    ranker.json      optional: the learned selector, with its semantic direction prior
    ranges.json      optional: the range-of-motion prior (issue 35; key "ranges" in
                     bundle.json, absent in older bundles)
    check/           optional: a second motion-GNN run (``kinmo train all``: the coarse-type
                     GNN) that ``kinmo pseudo-label`` requires to agree on every kept joint
                     (issue 34; key "check", absent in older bundles)

:func:`resolve_bundle` also accepts what users passed before bundles existed: a GNN run
folder (or ``model.pt``) with ``--axis-model`` / ``--ranker``. A ranker is then looked for
in the axis folder (``AXIS/ranker.json``) and beside it (``AXIS/../ranker/ranker.json``, the
layout of ``kinmo train all``), so ``--axis-model runs/all/axis`` gets the learned selector
instead of silently falling back to the paper's.
"""

from __future__ import annotations

import os
import shutil
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

from kinmo.errors import KinmoDataError
from kinmo.io import read_json_document, write_json
from kinmo.refine.axis_io import CATEGORIES_FILE, category_files
from kinmo.runs import MEMBERS_DIR, member_folders

__all__ = ["BUNDLE_FILE", "BUNDLE_FORMAT", "BUNDLE_VERSION", "ModelBundle", "find_ranker",
           "read_bundle", "resolve_bundle", "write_bundle"]

BUNDLE_FILE = "bundle.json"
BUNDLE_FORMAT = "kinmo-model-bundle"
BUNDLE_VERSION = 1


@dataclass(frozen=True)
class ModelBundle:
    """The resolved parts of a model.

    Attributes
    ----------
    gnn : Path
        Motion-GNN run folder (or its ``model.pt``).
    axis : Path or None
        Axis-network run folder, if any.
    ranker : Path or None
        ``ranker.json`` of the learned selector, if any.
    trained_on : tuple of str
        Shape ids the models were trained on (empty when unknown).
    root : Path or None
        The bundle folder (None for a GNN run given alone).
    ranges : Path or None
        ``ranges.json``, the range-of-motion prior (:class:`kinmo.ranges.RangePrior`), if any.
    check : Path or None
        A second motion-GNN run folder that pseudo-labelling requires to agree
        (:func:`kinmo.pseudo_label.pseudo_label_dataset` ``check_run``), if any.
    """

    gnn: Path
    axis: Path | None = None
    ranker: Path | None = None
    trained_on: tuple[str, ...] = field(default=())
    root: Path | None = None
    ranges: Path | None = None
    check: Path | None = None

    @property
    def has_axis_network(self) -> bool:
        """True when an axis network's weights are present (``axis/model.pt``)."""
        if self.axis is None:
            return False
        return (self.axis.is_file() and self.axis.suffix == ".pt") or (self.axis / "model.pt").is_file()


def find_ranker(axis: str | Path | None) -> Path | None:
    """The ranker belonging to an axis folder: ``AXIS/ranker.json``, else
    ``AXIS/../ranker/ranker.json`` (``kinmo train all``'s layout), else None."""
    if axis is None:
        return None
    axis = Path(axis)
    folder = axis if axis.is_dir() else axis.parent
    for cand in (folder / "ranker.json", folder.parent / "ranker" / "ranker.json"):
        if cand.is_file():
            return cand
    return None


def read_bundle(path: str | Path) -> ModelBundle:
    """Read a bundle folder (its ``bundle.json``).

    Raises
    ------
    KinmoDataError
        ``bundle.json`` missing, malformed, of another format or a newer version, or a
        part it names missing (one line naming the file).
    """
    root = Path(path)
    f = root / BUNDLE_FILE
    doc = read_json_document(f, BUNDLE_FORMAT, BUNDLE_VERSION, "model bundle",
                             "not a model bundle (no bundle.json)")

    def part(key: str, required: bool) -> Path | None:
        name = doc.get(key)
        if name is None and not required:
            return None
        if not isinstance(name, str) or not name or "/" in name or "\\" in name or name in (".", ".."):
            raise KinmoDataError(f, f"malformed model bundle: {key!r} must name an entry of the folder")
        p = root / name
        if not p.exists():
            raise KinmoDataError(p, f"missing from the model bundle ({key})")
        return p

    ids = doc.get("trained_on", [])
    if not isinstance(ids, list) or not all(isinstance(i, str) for i in ids):
        raise KinmoDataError(f, "malformed model bundle: 'trained_on' must be a list of ids")
    return ModelBundle(part("gnn", True), part("axis", False), part("ranker", False),  # type: ignore[arg-type]
                       tuple(ids), root, part("ranges", False), part("check", False))


def resolve_bundle(model: str | Path, axis_model: str | Path | None = None,
                   ranker: str | Path | None = None) -> ModelBundle:
    """What ``--model`` (and ``--axis-model`` / ``--ranker``) name, as one bundle.

    Parameters
    ----------
    model : str or Path
        A bundle folder (``bundle.json``), or a GNN run folder / ``model.pt``.
    axis_model : str or Path, optional
        Overrides (or, for a GNN run, adds) the axis network.
    ranker : str or Path, optional
        Overrides the ranker; by default the bundle's, or the one found with the axis
        network (:func:`find_ranker`).

    Returns
    -------
    ModelBundle

    Raises
    ------
    KinmoDataError
        ``model`` does not exist, or a bundle is malformed (:func:`read_bundle`).
    """
    model = Path(model)
    if not model.exists():
        raise KinmoDataError(model, "model not found (a bundle folder or a run of `kinmo train gnn`)")
    if (model / BUNDLE_FILE).is_file():
        b = read_bundle(model)
    else:
        b = ModelBundle(model)
    axis = Path(axis_model) if axis_model is not None else b.axis
    rk = Path(ranker) if ranker is not None else (
        b.ranker if b.ranker is not None and axis_model is None else find_ranker(axis) or b.ranker)
    return replace(b, axis=axis, ranker=rk)


def _copy_gnn_run(pt: Path, dest: Path, names: Sequence[str] = ("config.json",)) -> None:
    """Copy a motion-GNN run into the bundle folder ``dest``: its weights ``pt``, the files
    ``names`` beside them, and its ensemble members (``members/<k>/``,
    :func:`kinmo.runs.member_folders`: weights and ``config.json`` each)."""
    dest.mkdir(parents=True)
    shutil.copy2(pt, dest / "model.pt")
    for name in names:
        if (pt.parent / name).is_file():
            shutil.copy2(pt.parent / name, dest / name)
    for folder in member_folders(pt.parent):
        _copy_gnn_run(folder / "model.pt", dest / MEMBERS_DIR / folder.name)


def write_bundle(out: str | Path, gnn: str | Path, axis: str | Path | None = None,
                 ranker: str | Path | None = None, trained_on: Sequence[str] = (),
                 ranges: str | Path | None = None, check: str | Path | None = None) -> ModelBundle:
    """Write a bundle folder (module docstring) by copying the trained parts into ``out``.

    Parameters
    ----------
    out : str or Path
        The bundle folder; written whole into a temporary sibling, then renamed into place.
    gnn : str or Path
        Run folder of ``kinmo train gnn`` (its ``model.pt`` and ``config.json`` are copied,
        and its ensemble members', ``members/<k>/``).
    axis : str or Path, optional
        Run folder of ``kinmo train axis`` (its ``model.pt`` and ``categories.json``/
        per-category networks when present).
    ranker : str or Path, optional
        ``ranker.json`` of ``kinmo train ranker``.
    trained_on : sequence of str
        Shape ids the models were trained on (the training split).
    ranges : str or Path, optional
        ``ranges.json``, the range-of-motion prior (:meth:`kinmo.ranges.RangePrior.save`).
    check : str or Path, optional
        Run folder of a second ``kinmo train gnn`` (its ``model.pt``, ``config.json`` and
        members are copied into ``check/``): the model pseudo-labelling requires to agree.

    Returns
    -------
    ModelBundle
        As :func:`read_bundle` reads it back.

    Raises
    ------
    KinmoDataError
        A part is missing.
    """
    out = Path(out)
    gnn = Path(gnn)
    gnn_pt = gnn if gnn.is_file() else gnn / "model.pt"
    if not gnn_pt.is_file():
        raise KinmoDataError(gnn_pt, "motion-GNN weights missing (run `kinmo train gnn`)")
    if ranker is not None and not Path(ranker).is_file():
        raise KinmoDataError(Path(ranker), "ranker file missing (run `kinmo train ranker`)")
    if ranges is not None and not Path(ranges).is_file():
        raise KinmoDataError(Path(ranges), "range prior missing (run `kinmo train all`)")
    check_pt = None if check is None else (Path(check) if Path(check).is_file() else Path(check) / "model.pt")
    if check_pt is not None and not check_pt.is_file():
        raise KinmoDataError(check_pt, "second motion-GNN weights missing (run `kinmo train gnn`)")
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.parent / f".{out.name}.{os.getpid()}.tmp"
    shutil.rmtree(tmp, ignore_errors=True)
    try:
        tmp.mkdir()
        # eval reads the split of its run
        _copy_gnn_run(gnn_pt, tmp / "gnn", ("config.json", "split.json") if gnn.is_dir() else ())
        if axis is not None:
            axis = Path(axis)
            if axis.is_file():
                (tmp / "axis").mkdir()
                shutil.copy2(axis, tmp / "axis" / "model.pt")
            elif (axis / "model.pt").is_file():
                # the networks the run uses and nothing else (not its last epoch, logs or
                # the per-category files an earlier run left in the same folder)
                files = ["model.pt", *sorted(category_files(axis).values())]
                files += [n for n in (CATEGORIES_FILE, "config.json") if (axis / n).is_file()]
                for rel in files:
                    if not (axis / rel).is_file():
                        raise KinmoDataError(axis / rel, "per-category axis network missing "
                                             f"(listed in {CATEGORIES_FILE})")
                    (tmp / "axis" / rel).parent.mkdir(parents=True, exist_ok=True)
                    shutil.copy2(axis / rel, tmp / "axis" / rel)
            else:
                axis = None
        if ranker is not None:
            shutil.copy2(ranker, tmp / "ranker.json")
        if ranges is not None:
            shutil.copy2(ranges, tmp / "ranges.json")
        if check_pt is not None:
            _copy_gnn_run(check_pt, tmp / "check")
        selector = "ranker" if ranker is not None else ("paper" if axis is not None else "none")
        write_json(tmp / BUNDLE_FILE, {
            "format": BUNDLE_FORMAT, "version": BUNDLE_VERSION, "gnn": "gnn",
            "axis": "axis" if axis is not None else None,
            "ranker": "ranker.json" if ranker is not None else None,
            "ranges": "ranges.json" if ranges is not None else None,
            "check": "check" if check_pt is not None else None,
            "selector": selector, "trained_on": sorted(str(i) for i in trained_on),
        })
        if out.exists():
            shutil.rmtree(out)
        os.replace(tmp, out)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return read_bundle(out)
