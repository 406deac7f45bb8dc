"""Prediction on a user's own part-segmented asset (``kinmo predict FILE``).

kinmo predicts motion over a *part hierarchy* (Liu et al. 2023, Sec. 3.1: the GNN runs on the
parts of a PartNet shape). The asset's parts are read by :mod:`kinmo.assets` (one reader per
format: GLB / glTF scenes, OBJ with groups, folders of part meshes, URDF, MJCF); here they
become a PartNet folder (``result.json``, ``meta.json``, ``objs/part_<k>.obj``) that the
unchanged prediction path (:func:`kinmo.predict.predict_dataset`: part graph, motion GNN,
optional axis refinement) reads like any PartNet shape.

**Hierarchy rule.** A root node named after the file (its stem), with one leaf per part in
input order (scene nodes, sorted file names, URDF link order, MJCF body order), named after
the node / group / file / link / body (``part_<k>`` when nameless; names sanitised to
``[A-Za-z0-9_]``). PartNet's own hierarchies are deeper; a flat one is what a user's
segmentation tells, and the GNN's sibling edges then relate every pair of parts.

**Names the model does not know** (issue 36). Part names are the motion GNN's semantic input,
learned from PartNet's names in PartNet's frame. A robot-learning asset's link names are
mostly its own (``cabinet5_drawer_top``, ``handle_cab5_m``), and one that happens to match
(its body ``cabinet5`` read as PartNet's ``cabinet``) made the whole object count as named:
it was then read in PartNet's facing, without the quarter turns that unnamed objects get
(:mod:`kinmo.inference.gnn`). So when fewer than :data:`KNOWN_NAME_SHARE` of the parts' names
are known to the model's vocabulary (:func:`names_known`), the object is staged as if
unnamed: root ``unknown``, leaves ``part_<k>``, exactly as a GLB with generic names. The
outputs (``result.json``, ``mobility_v2.json``, the exports) keep the user's names.

Frames and units (issue 22; :mod:`kinmo.data.frames`): the asset's up axis is ``--up``, by
default its format's (:func:`kinmo.assets.asset_up`: glTF and OBJ y-up, URDF and MJCF z-up,
a URDF kinmo wrote y-up); a warning is logged when its support faces suggest the other axis.
The parts are staged in kinmo's frame (y-up, centred, bounding-box diagonal 2, whatever the
units), and every output is mapped back: ``textured_objs/`` holds the meshes as given,
``mobility_v2.json`` and the exports carry the joints in the asset's frame and units, and
``frame.json`` records the map (``edges.json`` stays in kinmo's frame).

Output (:func:`predict_user_input`): ``OUT/<stem>/`` becomes a complete PartNet-Mobility
folder: ``result.json``, ``meta.json``, ``textured_objs/part_<k>.obj``, ``mobility_v2.json``,
``edges.json``, ``frame.json``, ``view.html`` (:func:`kinmo.view.view_folder`) and the chosen
export formats (:mod:`kinmo.export`), the staged PartNet folder
(``OUT/.staging/<stem>``) is removed afterwards. An unsegmented input (fewer than two parts)
raises :class:`~kinmo.errors.KinmoDataError` saying what kinmo needs.
"""

from __future__ import annotations

import dataclasses
import logging
import re
import shutil
from collections.abc import Sequence
from pathlib import Path

from kinmo.assets import Part, ReadOptions, asset_up, read_parts
from kinmo.data.frames import AssetFrame, guess_up
from kinmo.data.readers import read_shape
from kinmo.data.writers import write_mobility_v2
from kinmo.export import DEFAULT_FORMATS, export
from kinmo.export.collision import DEFAULT_COLLISION
from kinmo.export.kinematics import write_obj
from kinmo.features import SemanticVocab
from kinmo.inference.predictor import Predictor
from kinmo.io import check_outputs_apart, staged_folder, write_json, write_text
from kinmo.mobility_tree import TreeOptions
from kinmo.predict import predict_dataset
from kinmo.progress import plain
from kinmo.view import view_folder

__all__ = ["KNOWN_NAME_SHARE", "asset_frame", "names_known", "predict_user_input", "stage_partnet"]

logger = logging.getLogger(__name__)


#: A user's part names reach the motion GNN only when at least this share of them is known to
#: its vocabulary (module docs, "Names the model does not know"; issue 36). Any share from 0.3
#: to 0.7 gives the same foreign-asset figures (``docs/results/foreign_assets.md``).
KNOWN_NAME_SHARE = 0.5


def _clean(name: str, k: int) -> str:
    s = re.sub(r"[^A-Za-z0-9_]+", "_", name).strip("_")
    return s or f"part_{k}"


def names_known(names: Sequence[str], vocab: SemanticVocab) -> bool:
    """Whether a user's part names are given to the motion GNN (module docs).

    Parameters
    ----------
    names : sequence of str
        The parts' names as read (:func:`kinmo.assets.read_parts`), before sanitising.
    vocab : SemanticVocab
        The motion GNN's vocabulary (:attr:`kinmo.train.gnn.Run.vocab`).

    Returns
    -------
    bool
        True when at least :data:`KNOWN_NAME_SHARE` of ``names`` (sanitised as staged) are
        known to ``vocab``; False for no names.
    """
    if not names:
        return False
    known = sum(vocab.index(_clean(n, k)) != 0 for k, n in enumerate(names))
    return known >= KNOWN_NAME_SHARE * len(names)


def _hierarchy(path: Path, parts: Sequence[Part], named: bool) -> list[dict]:
    """``result.json`` of a staged asset: a root and one leaf per part (module docs); with
    ``named`` False the root is ``unknown`` and the leaves ``part_<k>``, their ``text`` the
    user's names either way."""
    leaves = [{"id": k + 1, "name": _clean(name, k) if named else f"part_{k}",
               "text": name or _clean(name, k), "objs": [f"part_{k}"]}
              for k, (name, _, _) in enumerate(parts)]
    return [{"id": 0, "name": _clean(path.stem, 0) if named else "unknown", "text": path.name,
             "children": leaves}]


def stage_partnet(path: str | Path, folder: str | Path, category: str = "unknown",
                  parts: Sequence[Part] | None = None, frame: AssetFrame | None = None,
                  vocab: SemanticVocab | None = None) -> Path:
    """Write the parts of ``path`` as a PartNet shape folder (module docs: hierarchy rule).

    Parameters
    ----------
    path : str or Path
        The user's asset (:func:`kinmo.assets.read_parts`).
    folder : str or Path
        The shape folder to create (replaced if present).
    category : str
        ``model_cat`` written to ``meta.json`` (used only as the GNN's semantic context).
    parts : sequence of Part, optional
        The parts when the caller has read them (else :func:`read_parts` of ``path``).
    frame : AssetFrame, optional
        Map the parts into kinmo's frame (y-up, diagonal 2) before writing them
        (:meth:`kinmo.data.frames.AssetFrame.to_kinmo`); default: written as given.
    vocab : SemanticVocab, optional
        The motion GNN's vocabulary: when the parts' names are not :func:`names_known` to it,
        they are staged as ``part_<k>`` under a root ``unknown`` (module docs); default: the
        names as given.

    Returns
    -------
    Path
        ``folder``, readable by :func:`kinmo.data.readers.read_shape`.

    Raises
    ------
    KinmoDataError
        As :func:`kinmo.assets.read_parts`.
    """

    path, folder = Path(path), Path(folder)
    parts = read_parts(path) if parts is None else parts
    if folder.exists():
        shutil.rmtree(folder)
    (folder / "objs").mkdir(parents=True)
    for k, (_, v, f) in enumerate(parts):
        write_obj(folder / "objs" / f"part_{k}.obj", v if frame is None else frame.to_kinmo(v), f)
    named = vocab is None or names_known([n for n, _, _ in parts], vocab)
    write_json(folder / "result.json", _hierarchy(path, parts, named))
    stem = _clean(path.stem, 0)
    write_json(folder / "meta.json", {"model_cat": category, "anno_id": stem,
                                      "source": str(path)})
    return folder


def asset_frame(path: str | Path, parts: Sequence[Part], up: str | None = None) -> AssetFrame:
    """How ``kinmo predict FILE`` reads an asset's frame: the one rule (module docs, "Frames").

    Parameters
    ----------
    path : str or Path
        The asset (its format gives the default up axis, :func:`kinmo.assets.asset_up`).
    parts : sequence of Part
        Its parts, asset frame and units (:func:`kinmo.assets.read_parts`).
    up : {"y", "z"}, optional
        The up axis the user gave (``--up``); ``None``: the format's, with a warning when the
        support faces suggest the other one (:func:`kinmo.data.frames.guess_up`).

    Returns
    -------
    AssetFrame
        The map into kinmo's frame (y-up, centred, diagonal 2).
    """
    up = up if up is not None else asset_up(path)
    suggested = guess_up([(v, f) for _, v, f in parts], up)
    if suggested is not None:
        logger.warning("%s: read as %s-up, but it stands on faces that say %s-up (give --up %s if so)",
                       plain(path), up, suggested, suggested)
    return AssetFrame.fit([v for _, v, _ in parts], up)


def predict_user_input(path: str | Path, run, out: str | Path, formats: Sequence[str] | None = None,
                       category: str = "unknown", up: str | None = None,
                       package_path: Sequence[str | Path] = (), **predict_kw):
    """Predict the motion of a user's asset; write ``OUT/<stem>/`` (module docs).

    Parameters
    ----------
    path : str or Path
        ``.glb``/``.gltf``, ``.obj`` with groups, ``.urdf``, an MJCF ``.xml`` or a folder
        of part meshes (:func:`kinmo.assets.read_parts`).
    run : str, Path or Run
        Motion GNN run folder (``kinmo train gnn``).
    out : str or Path
        Output folder.
    formats : sequence of str, optional
        Export formats (default :data:`kinmo.export.DEFAULT_FORMATS`); ``mobility_v2`` is
        always written.
    category : str
        Category name given to the GNN.
    up : {"y", "z"}, optional
        The asset's up axis (default :func:`kinmo.assets.asset_up`: by its format). A warning is logged
        when the geometry suggests the other one (:func:`kinmo.data.frames.guess_up`).
    package_path : sequence of str or Path
        Folders holding ROS packages by name, for URDF ``package://NAME/...`` meshes
        (``--package-path``; :mod:`kinmo.assets.urdf`).
    **predict_kw
        Passed to :func:`kinmo.predict.predict_dataset` (``axis_model``, ``options``,
        ``device``, ``progress`` ...).

    Returns
    -------
    list of PredictRow
        One row (the asset), ``outputs`` naming every file written.

    Raises
    ------
    KinmoDataError
        As :func:`kinmo.assets.read_parts`, or the run cannot be loaded.
    KinmoUsageError
        ``out`` would overwrite ``path`` (:func:`kinmo.io.check_outputs_apart`).
    """

    path, out = Path(path), Path(out)
    stem = _clean(path.stem, 0)
    check_outputs_apart(out, [path], written=[stem, ".staging", "predictions.csv"])
    staging = out / ".staging"
    parts = read_parts(path, ReadOptions(tuple(Path(p) for p in package_path)))
    frame = asset_frame(path, parts, up)
    shutil.rmtree(staging, ignore_errors=True)  # a killed run's leftovers
    predictor = run if isinstance(run, Predictor) else Predictor.from_parts(
        run, predict_kw.pop("axis_model", None), predict_kw.pop("refine_config", None),
        predict_kw.get("options") or TreeOptions(), predict_kw.get("device", "auto"))
    vocab = predictor.run.vocab
    named = names_known([n for n, _, _ in parts], vocab)
    shape_dir = stage_partnet(path, staging / "shapes" / stem, category, parts=parts, frame=frame,
                              vocab=vocab)
    fmts = list(dict.fromkeys(["mobility_v2", *(DEFAULT_FORMATS if formats is None else formats)]))
    try:
        pred_out = staging / "pred"
        rows = predict_dataset(staging / "shapes", predictor, pred_out, formats=["mobility_v2"],
                               **predict_kw)
        for row in rows:
            if row.status != "ok":
                continue
            # OUT/<stem> is built in a temporary sibling and renamed into place whole (issue
            # 21, finding 12), in the asset's own frame and units: its meshes as given, the
            # predicted joints mapped back (edges.json stays in kinmo's frame)
            with staged_folder(out / stem) as final:
                for entry in (pred_out / stem).iterdir():
                    shutil.move(str(entry), str(final / entry.name))
                tex = final / "textured_objs"  # kinmo-frame copies of the staged meshes: replaced
                shutil.rmtree(tex, ignore_errors=True)
                tex.mkdir()
                for k, (_, v, f) in enumerate(parts):
                    write_obj(tex / f"part_{k}.obj", v, f)
                shutil.copyfile(shape_dir / "meta.json", final / "meta.json")
                write_json(final / "result.json", _hierarchy(path, parts, True))  # the user's names
                predicted = read_shape(final)
                if predicted.links is not None and not (frame.is_identity and named):
                    links = frame.links_to_asset(predicted.links)
                    if not named:  # links named after a staged part_<k>: the user's name
                        users = {f"part_{k}": _clean(n, k) for k, (n, _, _) in enumerate(parts)}
                        links = [dataclasses.replace(link, name=users.get(link.name, link.name))
                                 for link in links]
                    write_mobility_v2(links, final / "mobility_v2.json", predicted.hierarchy)
                write_json(final / "frame.json", frame.to_json())
                files = export(read_shape(final), final, fmts, name=stem,
                               progress=predict_kw.get("progress", True),
                               collision=predict_kw.get("collision", DEFAULT_COLLISION))
                written = {f: w[0] for f, w in files.items()}
                written["view"] = view_folder(final)  # view.html: a slider per joint
                written.update({k: v for k, v in row.outputs.items() if k not in written})
            row.outputs = {k: out / stem / Path(v).name for k, v in written.items()}
        write_text(out / "predictions.csv", (pred_out / "predictions.csv").read_text())
    finally:
        shutil.rmtree(staging, ignore_errors=True)
    return rows
