"""The data of ``kinmo train all``: which dataset folders it uses (:func:`find_data`), and
datasets made of several folders or caches (the runs with generated shapes)."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path
from typing import Any

from kinmo.data.cache import load_cache
from kinmo.data.readers import find_shapes
from kinmo.errors import KinmoDataError, KinmoError
from kinmo.synth import CATEGORIES

__all__ = ["FoundData", "find_data", "missing_data_message"]


@dataclasses.dataclass(frozen=True)
class FoundData:
    """The dataset folders ``kinmo train all`` uses (:func:`find_data`).

    Attributes
    ----------
    labeled, unlabeled : Path or None
        PartNet-Mobility (labelled) and PartNet (unlabelled) folders.
    why_labeled, why_unlabeled : str
        How each was found (one line).
    """

    labeled: Path | None
    unlabeled: Path | None
    why_labeled: str
    why_unlabeled: str


def _prepared_sources(cwd: Path) -> list[tuple[Path, Path, bool]]:
    """``(source folder, cache folder, labelled)`` of every ``kinmo prepare`` cache under
    ``cwd/cache`` whose source still exists, newest cache first."""
    found = []
    caches = [m.parent for m in (cwd / "cache").glob("*/manifest.json")] if (cwd / "cache").is_dir() else []
    for cache in sorted(caches, key=lambda c: -(c / "manifest.json").stat().st_mtime):
        try:
            man = json.loads((cache / "manifest.json").read_text())
            root = Path(man["root"])
            sources = [Path(r["source"]) for r in man.get("shapes", [])]
        except (OSError, ValueError, KeyError, TypeError):
            continue
        root = root if root.is_absolute() else cwd / root
        if not root.is_dir():
            continue
        labeled = any((src if src.is_absolute() else cwd / src).joinpath("mobility_v2.json").is_file()
                      for src in sources)
        found.append((root, cache, labeled))
    return found


def find_data(cwd: Path | None = None, env: dict[str, str] | None = None, labeled: Path | None = None,
              unlabeled: Path | None = None) -> FoundData:
    """The data of ``kinmo train all`` without options: one rule, for each of the labelled
    (PartNet-Mobility) and unlabelled (PartNet) folders, the first that exists of

    1. the folder given (``--labeled`` / ``--unlabeled``);
    2. the source folder of a cache that ``kinmo prepare DIR`` wrote under ``./cache/`` (its
       ``manifest.json`` remembers it): labelled when its shapes have ``mobility_v2.json``,
       unlabelled otherwise (the newest cache of each kind);
    3. ``./partnet-mobility`` / ``./partnet`` in the current folder;
    4. ``$KINMO_DATA/partnet-mobility`` / ``$KINMO_DATA/partnet``.

    No unlabelled folder: only the ``supervised`` setting is trained.

    Parameters
    ----------
    cwd : Path, optional
        The current folder (default ``Path.cwd()``).
    env : dict, optional
        Environment (default ``os.environ``).
    labeled, unlabeled : Path, optional
        Folders given on the command line.

    Returns
    -------
    FoundData
        ``labeled`` is None when nothing was found (:func:`missing_data_message`).
    """
    import os

    cwd = Path.cwd() if cwd is None else cwd
    env = dict(os.environ) if env is None else env
    prepared = _prepared_sources(cwd)
    root = env.get("KINMO_DATA")

    def pick(given: Path | None, is_labeled: bool, local: str) -> tuple[Path | None, str]:
        if given is not None:
            return given, "given on the command line"
        for src, cache, lab in prepared:
            if lab == is_labeled:
                return src, f"source of the cache {cache} that `kinmo prepare` wrote"
        if (cwd / local).is_dir():
            return cwd / local, f"./{local} in the current folder"
        if root and (Path(root) / local).is_dir():
            return Path(root) / local, f"$KINMO_DATA/{local}"
        return None, "none found"

    lab, why_l = pick(labeled, True, "partnet-mobility")
    unl, why_u = pick(unlabeled, False, "partnet")
    return FoundData(lab, unl, why_l, why_u)


def missing_data_message() -> str:
    """The one-line error of ``kinmo train all`` when :func:`find_data` finds no labelled data."""
    return ("no labelled PartNet-Mobility data found: run `kinmo prepare partnet-mobility/` (or put it in "
            "./partnet-mobility, set KINMO_DATA to a folder holding partnet-mobility/ and partnet/, or give "
            "--labeled DIR)")


def _synth_categories(cache: Path) -> list[str]:
    """The categories of a labelled cache that :mod:`kinmo.synth` generates (sorted).

    Raises
    ------
    KinmoError
        None of them.
    """

    real = sorted({g.category for g in load_cache(cache)})
    cats = [c for c in real if c in CATEGORIES]
    if not cats:
        raise KinmoError(f"--synth-extra: none of the labelled categories ({', '.join(real)}) can be "
                         f"generated (kinmo synth makes {', '.join(CATEGORIES)})")
    return cats


def _graphs(source: Any) -> Any:
    """A cache folder as is, or the graphs of several caches concatenated."""
    if isinstance(source, (str, Path)):
        return source

    return [g for c in source for g in load_cache(c)]


def _link_folder(folder: Path, sources: list[Path]) -> Path:
    """``folder`` holding a symbolic link to every shape folder of ``sources`` (a dataset made
    of several); links are replaced, nothing else is touched."""

    folder.mkdir(parents=True, exist_ok=True)
    for src in sources:
        for shape in find_shapes(src):
            link = folder / shape.name
            if link.is_symlink():
                if link.resolve() == shape.resolve():
                    continue
                link.unlink()
            elif link.exists():
                raise KinmoDataError(link, "exists and is not a link made by kinmo")
            link.symlink_to(shape.resolve(), target_is_directory=True)
    return folder


