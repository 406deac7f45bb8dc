"""Generated objects as ANCSH training data (issue 38, item 2).

Real labelled objects are few: 2-20 per kinematic structure in PartNet-Mobility. ``kinmo
synth`` draws objects of 13 categories with exact motion; those of one kinematic structure
(:func:`kinmo.ancsh.objects.structure_filter`) can join ANCSH's labelled training scans of
that structure. :func:`generated_samples` generates them (seeded), renders
``frames_per_object`` partial scans of each, like the labelled objects
(:func:`kinmo.ancsh.scans.render_objects`), and reads them into training samples of the
structure. :func:`mix` and :func:`pretrain_epochs` are the two ways
:func:`kinmo.ancsh.train.train_ancsh` uses them (``ANCSHConfig.synth_as``), always at the
same number of steps as a run without them. Test objects stay real.

Layout, under the run's render cache ``SCANS`` (shared by the settings and variants of a
category, so each generated object is made and rendered once):

- ``SCANS/generated/<structure>-seed<s>-n<N>/objects/<id>/``: the objects
  (PartNet-Mobility format, :func:`kinmo.synth.generate_dataset`), with ``generated.json``
  (what made them) written last: a folder without it, or with another one, is made again;
- ``SCANS/generated/<structure>-seed<s>-n<N>/frames/``: their scans.

The generation seed is ``ANCSHConfig.seed + GENERATION_SEED_OFFSET``, so each ANCSH seed
trains on its own generated objects.
"""

from __future__ import annotations

import functools
import json
import math
import shutil
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from kinmo.ancsh.config import ANCSHConfig
from kinmo.ancsh.dataset import FrameSample, load_samples
from kinmo.ancsh.objects import object_parts_of, structure_filter, synth_structure
from kinmo.ancsh.scans import render_objects
from kinmo.ancsh.structure import KinematicStructure, ObjectParts, structure_slug
from kinmo.errors import KinmoDataError
from kinmo.io import write_json
from kinmo.synth import CATEGORIES, SYNTH_VERSION, generate_dataset, generate_object

__all__ = ["GENERATION_SEED_OFFSET", "GeneratedData", "can_generate", "generated_samples", "mix",
           "pretrain_epochs", "synth_structures"]

#: Added to the ANCSH seed to seed the generated objects (``kinmo synth --seed``).
GENERATION_SEED_OFFSET = 500

#: Objects drawn by :func:`synth_structures` to find which structures a category produces.
PROBE_DRAWS = 40


def synth_structures(category: str, draws: int = PROBE_DRAWS, seed: int = 0) -> dict[str, int]:
    """The ANCSH structures ``kinmo synth`` produces for a category, by drawing objects.

    Parameters
    ----------
    category : str
        A PartNet-Mobility category name (``model_cat``).
    draws : int
        Objects drawn (``generate_object(category, seed, k)``, k < draws).
    seed : int

    Returns
    -------
    dict of str to int
        Structure signature -> objects of it among the draws (objects ANCSH cannot express
        are not counted); empty when ``kinmo synth`` does not make the category.
    """
    return dict(_probe(category, draws, seed))


@functools.lru_cache(maxsize=64)
def _probe(category: str, draws: int, seed: int) -> tuple[tuple[str, int], ...]:
    """:func:`synth_structures`, computed once per process (about a second a category: the
    pipeline asks for each (category, structure) pair, then each training again)."""
    if category not in CATEGORIES:
        return ()
    out: dict[str, int] = {}
    for k in range(draws):
        s = synth_structure(generate_object(category, seed, k))
        if s is not None:
            out[s.signature()] = out.get(s.signature(), 0) + 1
    return tuple(out.items())


def can_generate(category: str, structure: KinematicStructure, draws: int = PROBE_DRAWS) -> str | None:
    """Why generated objects of ``structure`` cannot be had for ``category``, or None when they can.

    A structure counts as produced when at least one of ``draws`` probe objects has it
    (:func:`synth_structures`); :func:`kinmo.synth.generate_dataset` then draws up to
    ``100 n + 100`` objects for ``n``.
    """
    if category not in CATEGORIES:
        return f"kinmo synth does not make {category}"
    made = synth_structures(category, draws)
    if structure.signature() not in made:
        return (f"kinmo synth makes no {category} of structure {structure.signature()} "
                f"in {draws} draws (it makes {', '.join(sorted(made)) or 'none ANCSH can express'})")
    return None


@dataclass
class GeneratedData:
    """Generated training scans of one category and structure (:func:`generated_samples`).

    Attributes
    ----------
    samples : list of FrameSample
        ``kind`` ``"generated"``.
    objects : list of str
        The generated object ids.
    skipped : str or None
        Why none were generated (category or structure not made by ``kinmo synth``).
    failed : dict of str to str
        Objects whose rendering failed.
    skipped_scans : list of str
    """

    samples: list[FrameSample]
    objects: list[str]
    skipped: str | None = None
    failed: dict[str, str] = field(default_factory=dict)
    skipped_scans: list[str] = field(default_factory=list)

    def info(self) -> dict[str, Any]:
        """What ``data.json`` records of them."""
        return {"generated_objects": self.objects, "generated_scans": len(self.samples),
                "generated_skipped": self.skipped}


def _objects(folder: Path, category: str, structure: KinematicStructure, n: int, seed: int,
             progress: bool) -> list[Path]:
    """The ``n`` generated objects in ``folder/objects`` (made unless ``generated.json`` matches)."""
    want = {"category": category, "structure": structure.signature(), "n": n, "seed": seed,
            "synth_version": SYNTH_VERSION}
    objects, stamp = folder / "objects", folder / "objects" / "generated.json"
    if stamp.is_file():
        try:
            have = json.loads(stamp.read_text())
        except (OSError, ValueError):
            have = None
        if isinstance(have, dict) and {k: have.get(k) for k in want} == want:
            return [objects / i for i in have["objects"]]
    if objects.exists():
        shutil.rmtree(objects)
    paths = generate_dataset(objects, n, seed, categories=[category], progress=progress,
                             keep=structure_filter(structure.signature()))
    write_json(stamp, {**want, "objects": [p.name for p in paths]})
    return paths


def generated_samples(category: str, structure: KinematicStructure, config: ANCSHConfig, scans: Path,
                      progress: bool = True) -> GeneratedData:
    """Generate, render and read ``config.synth_objects`` objects of ``structure``.

    Parameters
    ----------
    category : str
        PartNet-Mobility category name (as :func:`kinmo.ancsh.objects.scan_category`
        resolves it).
    structure : KinematicStructure
        The trained structure; every generated object has it.
    config : ANCSHConfig
        ``synth_objects``, ``seed``, ``frames_per_object``, ``image_size``, ``theta``,
        ``cache_points``, ``render_workers``.
    scans : Path
        The run's render cache (``SCANS`` of the module docstring).
    progress : bool

    Returns
    -------
    GeneratedData
        Empty with ``skipped`` set when ``kinmo synth`` does not produce the structure.

    Raises
    ------
    KinmoDataError
        A generated object cannot be read back (a bug of ``kinmo synth``).
    """
    n = config.synth_objects
    why = can_generate(category, structure) if n > 0 else "synth_objects is 0"
    if why is not None:
        return GeneratedData([], [], skipped=why)
    seed = config.seed + GENERATION_SEED_OFFSET
    folder = scans / "generated" / f"{structure_slug(structure)}-seed{seed}-n{n}"
    paths = _objects(folder, category, structure, n, seed, progress)
    parts: dict[str, ObjectParts | None] = {}
    for p in paths:
        op = object_parts_of(p)[1]
        if op is None or op.structure != structure:
            raise KinmoDataError(f"{p}: generated object does not have structure {structure.signature()}")
        parts[p.name] = op
    files, failed = render_objects({p.name: p for p in paths}, folder / "links", folder / "frames",
                                   config.frames_per_object, config, progress)
    samples, skipped = load_samples(files, parts, structure, config.theta, config.cache_points, config.seed)
    for s in samples:
        s.kind = "generated"
    return GeneratedData(samples, [p.name for p in paths], failed=failed, skipped_scans=skipped)


def mix(real: Sequence[FrameSample], generated: Sequence[FrameSample], share: float) -> list[FrameSample]:
    """Real and generated scans in one list whose uniform draws hit generated ones about
    ``share`` of the time.

    The real scans are repeated ``r = max(1, round((1 - share) / share * G / R))`` times (R
    real, G generated scans); a batch then holds ``G / (G + r R)`` generated scans on average,
    ``share`` up to the rounding of ``r`` (each repeat draws a fresh point subset,
    :class:`~kinmo.ancsh.dataset.ANCSHFrames`). With more real than ``share`` allows, every
    scan appears once.

    Parameters
    ----------
    real, generated : sequence of FrameSample
    share : float
        In (0, 1).

    Returns
    -------
    list of FrameSample
        ``real * r + generated``.

    Raises
    ------
    ValueError
        ``share`` outside (0, 1).
    """
    if not 0 < share < 1:
        raise ValueError(f"share must be in (0, 1), got {share}")
    if not real or not generated:
        return list(real) + list(generated)
    r = max(1, round((1 - share) / share * len(generated) / len(real)))
    return list(real) * r + list(generated)


def pretrain_epochs(config: ANCSHConfig) -> int:
    """Epochs on generated scans alone before fine-tuning (``synth_as`` ``pretrain``):
    ``round(synth_share * epochs)``, kept within 1 .. epochs - 1 (for ``epochs`` >= 2)."""
    if config.epochs < 2:
        return 0
    return min(config.epochs - 1, max(1, int(math.floor(config.synth_share * config.epochs + 0.5))))
