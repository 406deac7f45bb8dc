"""Find the artefacts of a kinmo run folder (``kinmo report``).

A *run* is any folder written by the kinmo pipeline: one training run, an evaluation folder,
or the root of a whole pipeline holding all of them. :func:`collect_run` finds its artefacts
in one of two ways:

1. **From** ``pipeline_result.json`` (``kinmo train all``, ``kinmo demo``): it names every
   stage's outputs (:class:`kinmo.pipeline.PipelineResult`), so each file's kind is the kind
   of the stage that wrote it (:data:`STAGE_KINDS`): ``table1`` folders give Table 1,
   ``table2`` folders Table 2, ``gnn`` / ``axis`` / ``ancsh`` runs the training curves,
   ``pseudo`` the pseudo-label summary, and the gallery shows the PNGs in those folders.
   Nothing else in the folder is read (the ranker's fold GNNs, the caches, stray files).
   A generated-shapes run inside it is read from the stages named ``synth-extra: <stage>``
   when the last ``kinmo train all`` call made it.
2. **By walking** the folder (loose folders, and runs of older versions): hidden folders and
   earlier reports are skipped, and files are recognised by **name and columns**, never by
   their place in the tree, so any layout works (:mod:`kinmo.report.recognise`,
   :data:`~kinmo.report.recognise.ARTEFACTS`).

A file that looks like an artefact but cannot be read is listed in
:attr:`RunArtefacts.problems` (file and reason); collecting never raises for a partial or
damaged run, only for a run folder that does not exist. The artefact types are in
:mod:`kinmo.report.artefacts` (re-exported here).
"""

from __future__ import annotations

import json
import os
from collections.abc import Sequence
from pathlib import Path

from kinmo.errors import KinmoDataError
import kinmo.report.artefacts as _artefacts
from kinmo.report.artefacts import *  # noqa: F403 (the artefact types, re-exported)
from kinmo.report.artefacts import CsvTable, RunArtefacts, SynthExtra, Table2, combine_table2, read_csv
from kinmo.report.recognise import ARTEFACTS, CONVERTERS, SKIP_DIRS, SKIP_IMAGE_DIRS, _rel, gallery, png_size
from kinmo.runs import RESULT_FILE, SYNTH_EXTRA_FILE, TABLE2_SEED_STAGE

__all__ = [*_artefacts.__all__, "ARTEFACTS", "RESULT_FILE", "STAGE_KINDS", "collect_run", "png_size"]

#: Stage of ``pipeline_result.json`` -> the kind of artefact its folders hold (an attribute of
#: :class:`RunArtefacts`). Other stages (``split``, ``prepare``, ``ranker``) are not shown.
STAGE_KINDS: dict[str, str] = {"table1": "table1", "table2": "table2_files", "gnn": "curves",
                               "axis": "curves", "ancsh": "curves", "pseudo": "pseudo"}

#: Prefix of the stages of the run with generated shapes (``--synth-extra``).
_SYNTH_PREFIX = "synth-extra: "


def _synth_extra_dirs(run: Path) -> list[Path]:
    """Generated-shapes runs one or two levels below ``run``."""
    return sorted({p.parent for pat in ("*/" + SYNTH_EXTRA_FILE, "*/*/" + SYNTH_EXTRA_FILE)
                   for p in run.glob(pat) if not any(q.startswith(".") for q in p.relative_to(run).parts)})


def _read_result(run: Path, problems: list[tuple[str, str]]) -> dict:
    """``run/pipeline_result.json`` as a dict (empty when absent or unreadable)."""
    p = run / RESULT_FILE
    if not p.is_file():
        return {}
    try:
        res = json.loads(p.read_text(encoding="utf-8"))
        if not isinstance(res, dict):
            raise ValueError("not a JSON object")
    except (OSError, ValueError) as e:
        problems.append((RESULT_FILE, f"cannot read: {e}"))
        return {}
    return res


def _timings(result: dict) -> dict[str, dict]:
    """The stage timings of a ``pipeline_result.json``."""
    t = result.get("timings", {})
    return {str(k): v for k, v in t.items() if isinstance(v, dict)} if isinstance(t, dict) else {}


def _stage_folders(result: dict, run: Path, prefix: str = "") -> dict[str, list[Path]] | None:
    """Kind of artefact -> the existing folders of the stages named ``<prefix><stage>`` in a
    ``pipeline_result.json``, or None when it names no such stage (then the run is walked).

    A recorded path is taken relative to the result's ``out`` (the run folder as it was given,
    maybe relative to another working folder) and found below ``run``; other paths as they are.
    """
    stages = result.get("stages")
    if not isinstance(stages, dict):
        return None
    found: dict[str, list[Path]] = {}
    named = False
    for stage, paths in stages.items():
        if not isinstance(stage, str) or not stage.startswith(prefix) or not isinstance(paths, list):
            continue
        name = stage[len(prefix):]
        if prefix == "" and name.startswith(_SYNTH_PREFIX):
            continue
        named = True
        kind = STAGE_KINDS.get(name)
        if kind is None:
            continue
        for s in paths:
            p = _resolve(s, result, run)
            if p.is_dir() and p not in found.setdefault(kind, []):
                found[kind].append(p)
    return found if named else None


def _seed_tables(out: RunArtefacts, result: dict, exclude: Sequence[Path],
                 main_dirs: Sequence[Path] = ()) -> dict[int, Table2]:
    """Table 2 per ANCSH seed from the ``table2 seed <s>`` stages of a ``pipeline_result.json``
    (``kinmo train all --ancsh-seeds K``), by seed, read as :func:`_from_stages` reads the
    ``table2`` stage; the seed whose folders are that stage's (``main_dirs``) is ``out.table2``."""
    stages = result.get("stages")
    found: dict[int, Table2] = {}
    if not isinstance(stages, dict):
        return found
    for stage, paths in stages.items():
        if not (isinstance(stage, str) and stage.startswith(TABLE2_SEED_STAGE) and isinstance(paths, list)):
            continue
        try:
            seed = int(stage[len(TABLE2_SEED_STAGE):])
        except ValueError:
            continue
        dirs = [p for p in (_resolve(s, result, out.run) for s in paths) if p.is_dir()]
        if dirs and dirs == list(main_dirs):
            t2 = out.table2
        else:
            part = RunArtefacts(out.run)
            _from_stages(part, {"table2_files": dirs}, exclude)
            out.problems += part.problems
            t2 = combine_table2(part.table2_files)
        if t2 is not None:
            found[seed] = t2
    return dict(sorted(found.items()))


def _resolve(path: object, result: dict, run: Path) -> Path:
    """A path recorded in a ``pipeline_result.json`` found below ``run``: relative to the
    result's ``out`` (the run folder as it was given, maybe relative to another working
    folder), else as it is (relative ones below ``run``)."""
    p = Path(str(path))
    try:
        p = run / p.relative_to(Path(str(result.get("out", ""))))
    except ValueError:
        p = p if p.is_absolute() else run / p
    return p.resolve()


def _is_report_dir(names: Sequence[str]) -> bool:
    return "index.html" in names and "report.md" in names


def _walk(run: Path, exclude: Sequence[Path]) -> tuple[list[Path], list[Path]]:
    """CSV and PNG files below ``run`` (sorted), skipping hidden folders and reports."""
    excl = {os.path.realpath(p) for p in exclude}
    csvs: list[Path] = []
    pngs: list[Path] = []
    for root, dirs, files in os.walk(run):
        if os.path.realpath(root) in excl or (Path(root) != run and _is_report_dir(files)):
            dirs[:] = []
            continue
        dirs[:] = sorted(d for d in dirs if not d.startswith(".") and d not in SKIP_DIRS)
        for f in files:
            if f.startswith("."):
                continue
            low = f.lower()
            if low.endswith(".csv"):
                csvs.append(Path(root) / f)
            elif low.endswith(".png") and Path(root).name not in SKIP_IMAGE_DIRS:
                pngs.append(Path(root) / f)
    return sorted(csvs), sorted(pngs)


def _read_table(p: Path, run: Path, problems: list[tuple[str, str]]) -> CsvTable | None:
    """A CSV file of the run, or None (a problem noted when it is one of kinmo's tables)."""
    try:
        header, rows = read_csv(p)
    except KinmoDataError as e:
        if p.name in ("metrics.csv", "table1.csv", "table2.csv", "summary.csv"):
            problems.append((_rel(p, run), e.problem))
        return None
    return CsvTable(p, _rel(p, run), header, rows)


def _add(out: RunArtefacts, t: CsvTable, converters) -> None:
    """Add ``t`` as the first kind of ``converters`` it is; a damaged one is a problem."""
    try:
        for kind, conv in converters:
            found = conv(t)
            if found is not None:
                getattr(out, kind).append(found)
                return
    except KinmoDataError as e:
        out.problems.append((t.rel, e.problem))


def _from_stages(out: RunArtefacts, folders: dict[str, list[Path]], exclude: Sequence[Path]) -> list[Path]:
    """Fill ``out`` from the stage folders of a ``pipeline_result.json``; returns their PNGs.

    A stage folder's CSVs are read as its kind only; one that is not (a per-shape table next
    to Table 1) is left out, as is a folder outside the run (the baseline's models that a
    generated-shapes run reuses).
    """
    conv = dict(CONVERTERS)
    pngs: list[Path] = []
    for kind, dirs in folders.items():
        for d in dirs:  # in the order of the stages (Table 1 of the selector first)
            if d != out.run and out.run not in d.parents:
                continue  # a baseline's run reused by a generated-shapes run: shown there
            csvs, images = _walk(d, exclude)
            pngs += images
            for p in csvs:
                t = _read_table(p, out.run, out.problems)
                if t is not None:
                    _add(out, t, [(kind, conv[kind])])
    return sorted(set(pngs))


def collect_run(run: str | Path, exclude: Sequence[str | Path] = (),
                max_images: int = 48, _result: dict | None = None, _prefix: str = "") -> RunArtefacts:
    """Find the artefacts of a run folder (module docstring: from ``pipeline_result.json``
    when the folder has one, else by walking it).

    Parameters
    ----------
    run : str or Path
        The run folder.
    exclude : sequence of str or Path
        Folders not searched (the report's own output folder). Folders holding both
        ``index.html`` and ``report.md`` (earlier reports) are always skipped.
    max_images : int
        Most PNGs kept for the gallery (spread over their folders).

    Returns
    -------
    RunArtefacts
        ``from_result`` says which way it was found.

    Raises
    ------
    KinmoDataError
        ``run`` does not exist or is not a folder.
    """
    run = Path(run)
    if not run.exists():
        raise KinmoDataError(run, "run folder does not exist")
    if not run.is_dir():
        raise KinmoDataError(run, "not a folder (give the run folder)")
    run = run.resolve()
    out = RunArtefacts(run)
    result = _read_result(run, out.problems) if _result is None else _result
    variants = _synth_extra_dirs(run)
    excl = [Path(e) for e in exclude] + variants
    folders = _stage_folders(result, run, _prefix) if result else None
    if folders is not None:
        out.from_result = True
        pngs = _from_stages(out, folders, excl)
    else:
        csvs, pngs = _walk(run, excl)
        for p in csvs:
            t = _read_table(p, run, out.problems)
            if t is not None:
                _add(out, t, CONVERTERS)
    out.table2 = combine_table2(out.table2_files)
    if result and not _prefix:
        out.table2_seeds = _seed_tables(out, result, excl, (folders or {}).get("table2_files", []))
        synth = result.get("ancsh_synth")
        out.ancsh_synth = synth if isinstance(synth, dict) else None
    out.images, out.n_images_found = gallery(pngs, run, max_images, out.problems)
    out.timings = _timings(result) if not _prefix else {}
    for v in variants:
        rel = _rel(v, run)
        try:
            info = json.loads((v / SYNTH_EXTRA_FILE).read_text(encoding="utf-8"))
            if not isinstance(info, dict):
                raise ValueError("not a JSON object")
        except (OSError, ValueError) as e:
            out.problems.append((f"{rel}/{SYNTH_EXTRA_FILE}", f"cannot read: {e}"))
            continue
        # the last call's generated-shapes run is in pipeline_result.json: its stage paths
        # are taken relative to the variant's folder
        last = result.get("synth_extra") if result else None
        sub_result = ({**result, "out": str(Path(str(result.get("out", ""))) / rel)}
                      if last and _resolve(last, result, run) == v.resolve() else {})
        sub = collect_run(v, exclude=exclude, max_images=0, _result=sub_result,
                          _prefix=_SYNTH_PREFIX if sub_result else "")
        out.problems += [(f"{rel}/{r}", p) for r, p in sub.problems]
        out.synth_extra.append(SynthExtra(v, rel, info, sub))
    return out
