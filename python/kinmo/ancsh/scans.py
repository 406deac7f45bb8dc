"""Rendering ANCSH's partial scans of a set of objects, and finding a category's shape folders.

Shared by training (:mod:`kinmo.ancsh.train`, :mod:`kinmo.ancsh.semi`) and evaluation
(:mod:`kinmo.ancsh.evaluate`): :func:`render_objects` links the objects under one render root
and renders (or resumes) their frames with :func:`kinmo.render.dataset.render_dataset`;
:func:`all_categories` and :func:`category_folders` list the objects of a dataset folder
(PartNet-Mobility or PartNet format) by category.
"""

from __future__ import annotations

from pathlib import Path

from kinmo.ancsh.config import ANCSHConfig
from kinmo.ancsh.objects import category_key
from kinmo.data.readers import find_shapes, read_meta
from kinmo.errors import KinmoDataError
from kinmo.render.dataset import RenderConfig, render_dataset

__all__ = ["SCAN_RULES", "all_categories", "category_folders", "render_objects"]

#: How ANCSH's scans are rendered beyond :class:`~kinmo.ancsh.config.ANCSHConfig` (image
#: size, seed): fields of :class:`~kinmo.render.dataset.RenderConfig`. A cylindrical joint is
#: a prismatic one to ANCSH (:func:`kinmo.ancsh.structure.object_parts`), so its scans hold it
#: at its rest angle. Part of ``kinmo train all``'s ANCSH stage keys: a run folder of other
#: rules trains and evaluates again.
SCAN_RULES: dict[str, bool] = {"turn_cylindrical": False}


def _link_objects(folders: dict[str, Path], objects_dir: Path) -> None:
    """``objects_dir/<key>`` -> folder symbolic links, exactly ``folders``."""
    objects_dir.mkdir(parents=True, exist_ok=True)
    for p in objects_dir.iterdir():
        if p.is_symlink() and p.name not in folders:
            p.unlink()
    for key, f in folders.items():
        link = objects_dir / key
        target = Path(f).resolve()
        if link.is_symlink():
            if link.resolve() == target:
                continue
            link.unlink()
        elif link.exists():
            continue  # a real folder (e.g. a wrapper written there): render it as is
        link.symlink_to(target, target_is_directory=True)


def render_objects(
    folders: dict[str, Path],
    objects_dir: str | Path,
    scans_dir: str | Path,
    frames: int,
    config: ANCSHConfig,
    progress: bool = True,
    seed_offset: int = 0,
) -> tuple[list[Path], dict[str, str]]:
    """Render ``frames`` partial scans of each object (resuming up-to-date frames).

    Parameters
    ----------
    folders : dict of str to Path
        Object key -> PartNet-Mobility-format folder.
    objects_dir : str or Path
        Folder of symbolic links to the objects (the render root).
    scans_dir : str or Path
        Output of :func:`kinmo.render.dataset.render_dataset` (``<key>/<frame>.npz``).
    frames : int
    config : ANCSHConfig
        ``image_size``, ``seed``, ``render_workers``; the rest is :data:`SCAN_RULES`.
    progress : bool
    seed_offset : int
        Added to ``config.seed`` for the render seed.

    Returns
    -------
    files : list of Path
        The frames rendered or up to date, sorted.
    failed : dict of str to str
        Object key -> reason for objects that failed.
    """

    objects_dir, scans_dir = Path(objects_dir), Path(scans_dir)
    if not folders:
        return [], {}
    _link_objects(folders, objects_dir)
    rc = RenderConfig(width=config.image_size, height=config.image_size, seed=config.seed + seed_offset,
                      **SCAN_RULES)
    res = render_dataset(objects_dir, scans_dir, frames, rc, workers=config.render_workers,
                         progress=progress)
    files: list[Path] = []
    failed: dict[str, str] = {}
    for r in res.rows:
        if r.id not in folders:
            continue
        if r.status in ("ok", "skipped"):
            files.append(scans_dir / r.file)
        else:
            failed.setdefault(r.id, r.error)
    return sorted(files), failed


def all_categories(root: Path) -> tuple[list[str], list[str]]:
    """Ids and categories of every PartNet-Mobility object under ``root``."""

    ids, cats = [], []
    for f in find_shapes(root):
        if not (f / "mobility_v2.json").is_file():
            continue
        try:
            cats.append(read_meta(f)[0])
        except KinmoDataError:
            cats.append("unknown")
        ids.append(f.name)
    return ids, cats


def category_folders(root: Path, category: str) -> dict[str, Path]:
    """Shape folders of ``category`` under ``root`` (either format), by folder name."""

    out: dict[str, Path] = {}
    for f in find_shapes(root):
        try:
            cat = read_meta(f)[0]
        except KinmoDataError:
            continue
        if category_key(cat) == category_key(category):
            out[f.name] = f
    return out
