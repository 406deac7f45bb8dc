"""ANCSH training samples from rendered partial scans (``kinmo render`` frames).

ANCSH (Li et al. CVPR 2020) is category-level: every object of a category must share one
kinematic structure (:mod:`kinmo.ancsh.structure`). This module

- uses a category's objects mapped onto the category's ANCSH parts
  (:mod:`kinmo.ancsh.objects`: :func:`scan_category`, :func:`object_parts_of`, re-exported
  here with :func:`category_key`, :func:`resolve_category`, :func:`link_centroids`);
- turns one rendered frame into per-point targets (:func:`frame_sample`): ANCSH part label
  (from the per-point link id), NPCS of the point in its part, NAOCS, and the joint targets
  of :func:`kinmo.ancsh.targets.joint_targets` from the frame's NAOCS joint axes (ordered as
  the structure's joints);
- serves fixed-size, normalised training samples (:class:`ANCSHFrames`, a torch
  ``Dataset``).

**Normalisation.** The network sees the ``n_points`` sampled camera-frame points centred on
their mean and divided by their largest distance to it (unit ball,
:func:`normalize_points`); the centre and scale come with every sample so predictions can be
mapped back (``points = xyz * scale + center``). NPCS and NAOCS targets are canonical and do
not depend on it.

Frames: points in the OpenCV camera frame (mesh units); NPCS / NAOCS in [0, 1]
(:mod:`kinmo.render.ancsh_gt`).
"""

from __future__ import annotations

import zlib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch.utils.data import Dataset

from kinmo.ancsh.objects import (
    CategoryObjects,
    category_key,
    link_centroids,
    object_parts_of,
    resolve_category,
    scan_category,
)
from kinmo.ancsh.structure import NOT_EXPRESSIBLE, KinematicStructure, ObjectParts
from kinmo.ancsh.targets import joint_targets
from kinmo.errors import KinmoDataError
from kinmo.render.dataset import load_frame

__all__ = [
    "ANCSHFrames",
    "CategoryObjects",
    "FrameSample",
    "category_key",
    "frame_sample",
    "link_centroids",
    "load_samples",
    "normalize_points",
    "object_parts_of",
    "resolve_category",
    "scan_category",
    "subsample_indices",
]

#: Per-point target arrays of a :class:`FrameSample` (besides ``points``).
TARGET_KEYS: tuple[str, ...] = (
    "seg", "npcs", "naocs", "heatmap", "unitvec", "axis", "joint", "position_mask",
)
#: Frames with fewer visible points are not usable for training.
MIN_POINTS = 32


# ------------------------------------------------------------------------------ samples


@dataclass
class FrameSample:
    """Per-point inputs and targets of one scan, at most ``cache_points`` points.

    Attributes
    ----------
    key : str
        Object key (the render sub-folder).
    frame : int
    kind : str
        ``"labeled"`` (rendered ground truth) or ``"pseudo"`` (targets from a model's
        predictions, ``semi``).
    points : (M, 3) float32
        Camera frame, mesh units.
    seg : (M,) int64
        ANCSH part index.
    npcs, naocs : (M, 3) float32
    heatmap : (M,) float32
    unitvec, axis : (M, 3) float32
    joint : (M,) int64
        0: no joint, j + 1: joint j.
    position_mask : (M,) bool
    """

    key: str
    frame: int
    kind: str
    points: np.ndarray
    seg: np.ndarray
    npcs: np.ndarray
    naocs: np.ndarray
    heatmap: np.ndarray
    unitvec: np.ndarray
    axis: np.ndarray
    joint: np.ndarray
    position_mask: np.ndarray

    def __len__(self) -> int:
        return len(self.points)


def frame_rng(seed: int, key: str, frame: int) -> np.random.Generator:
    """The generator of one frame's point subset: ``default_rng([seed, crc32(key), frame])``."""
    return np.random.default_rng([int(seed) & 0xFFFFFFFF, zlib.crc32(key.encode()), int(frame)])


def subsample_indices(n_total: int, n: int, rng: np.random.Generator) -> np.ndarray:
    """``n`` indices into ``n_total`` points: a random subset, padded by random repeats when
    ``n_total < n``.

    Returns
    -------
    (n,) int64

    Raises
    ------
    ValueError
        ``n_total == 0``.
    """
    if n_total <= 0:
        raise ValueError("cannot sample points from an empty scan")
    if n_total >= n:
        return rng.choice(n_total, size=n, replace=False).astype(np.int64)
    extra = rng.choice(n_total, size=n - n_total, replace=True)
    return np.concatenate([rng.permutation(n_total), extra]).astype(np.int64)


def normalize_points(points: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """Centre points on their mean and scale them into the unit ball.

    Parameters
    ----------
    points : (N, 3) float

    Returns
    -------
    xyz : (N, 3) float32
        ``(points - center) / scale``.
    center : (3,) float64
    scale : float
        Largest distance to the centre (1 for a single point).
    """
    p = np.asarray(points, dtype=np.float64)
    center = p.mean(0)
    scale = float(np.linalg.norm(p - center, axis=1).max()) if len(p) else 1.0
    scale = scale if scale > 0 else 1.0
    return ((p - center) / scale).astype(np.float32), center, scale


def _check_parts(path: Path, key: str, parts: ObjectParts | None, structure: KinematicStructure) -> ObjectParts:
    if parts is None:
        raise KinmoDataError(
            path, f"object {key} {NOT_EXPRESSIBLE}: it does not fit the category structure {structure.signature()}")
    if parts.structure != structure:
        raise KinmoDataError(
            path, f"object {key} has the kinematic structure {parts.structure.signature()}, not "
                  f"the category's {structure.signature()}: it cannot be trained on or evaluated "
                  "with this ANCSH model")
    return parts


def frame_sample(
    frame: Mapping[str, Any],
    parts: ObjectParts | None,
    structure: KinematicStructure,
    theta: float = 0.2,
    cache_points: int | None = 4096,
    seed: int = 0,
    path: str | Path = "<frame>",
) -> FrameSample:
    """Per-point ANCSH targets of one rendered frame.

    Parameters
    ----------
    frame : mapping
        A frame as read by :func:`kinmo.render.dataset.load_frame`.
    parts : ObjectParts or None
        The object's mapping onto ANCSH parts (:func:`object_parts_of`).
    structure : KinematicStructure
        The category's structure; the object must have exactly this one.
    theta : float
        Joint association distance, NAOCS units.
    cache_points : int or None
        Keep a random subset of at most this many points (seeded by ``seed``, the frame's key
        and index); None keeps all.
    seed : int
    path : str or Path
        The frame file, for messages.

    Returns
    -------
    FrameSample

    Raises
    ------
    KinmoDataError
        The object does not fit ``structure`` (the message names both structures), the frame
        has fewer than :data:`MIN_POINTS` points, a point's link is not part of the object,
        or a joint of the structure is missing from the frame.
    """
    path = Path(path)
    meta = frame.get("meta", {})
    key = str(meta.get("key", path.parent.name))
    index = int(meta.get("frame", 0))
    parts = _check_parts(path, key, parts, structure)
    n = len(frame["points"])
    if n < MIN_POINTS:
        raise KinmoDataError(path, f"only {n} visible points (< {MIN_POINTS}): the object is "
                                   "barely in view")
    idx = np.arange(n)
    if cache_points is not None and n > cache_points:
        idx = np.sort(frame_rng(seed, key, index).choice(n, size=cache_points, replace=False))
    links = np.asarray(frame["link"])[idx].astype(np.int64)
    lut = dict(parts.link_part)
    ulinks, inv = np.unique(links, return_inverse=True)
    missing = [int(u) for u in ulinks if int(u) not in lut]
    if missing:
        raise KinmoDataError(path, f"points of links {missing} that are not links of object {key}")
    seg = np.array([lut[int(u)] for u in ulinks], dtype=np.int64)[inv.reshape(-1)]
    # reconcile with the renderer's rigid parts: a rigid part maps onto one ANCSH part
    rparts = np.asarray(frame["part"])[idx].astype(np.int64)
    bad = [int(r) for r in np.unique(rparts) if int(r) not in lut or np.any(seg[rparts == r] != lut[int(r)])]
    if bad:
        raise KinmoDataError(path, f"rigid parts {bad} of the frame disagree with the ANCSH part "
                                   "mapping (rendered with other links?)")
    jids = [int(j) for j in np.asarray(frame["joint_ids"])]
    rows = []
    for j, lid in enumerate(parts.joint_links):
        if lid not in jids:
            raise KinmoDataError(path, f"joint {j} (moving link {lid}) of object {key} is not in the frame")
        rows.append(jids.index(lid))
    origins = np.asarray(frame["joint_origin_naocs"], dtype=np.float64)[rows]
    directions = np.asarray(frame["joint_direction_naocs"], dtype=np.float64)[rows]
    naocs = np.asarray(frame["naocs"], dtype=np.float32)[idx]
    tg = joint_targets(naocs, seg, structure, origins, directions, theta)
    return FrameSample(
        key=key, frame=index, kind="labeled",
        points=np.asarray(frame["points"], dtype=np.float32)[idx],
        seg=seg,
        npcs=np.asarray(frame["npcs"], dtype=np.float32)[idx],
        naocs=naocs,
        heatmap=tg["heatmap"].astype(np.float32),
        unitvec=tg["unitvec"].astype(np.float32),
        axis=tg["axis"].astype(np.float32),
        joint=tg["joint"].astype(np.int64),
        position_mask=tg["position_mask"].astype(bool),
    )


def load_samples(
    files: Sequence[str | Path],
    parts: Mapping[str, ObjectParts | None],
    structure: KinematicStructure,
    theta: float = 0.2,
    cache_points: int | None = 4096,
    seed: int = 0,
    skip_small: bool = True,
) -> tuple[list[FrameSample], list[str]]:
    """Read rendered frames into samples.

    Parameters
    ----------
    files : sequence of path
        Frame files (``<out>/<key>/<frame>.npz``).
    parts : mapping of str to ObjectParts or None
        Object key (the frame's ``meta["key"]``) -> its parts.
    structure, theta, cache_points, seed
        See :func:`frame_sample`.
    skip_small : bool
        Skip frames with fewer than :data:`MIN_POINTS` points (reported) instead of raising.

    Returns
    -------
    samples : list of FrameSample
    skipped : list of str
        One line per skipped frame.

    Raises
    ------
    KinmoDataError
        Unreadable frame, unknown object key, or an object not fitting ``structure``.
    """

    out: list[FrameSample] = []
    skipped: list[str] = []
    for f in files:
        fr = load_frame(f)
        key = str(fr["meta"].get("key", Path(f).parent.name))
        if key not in parts:
            raise KinmoDataError(f, f"frame of object {key}, which is not among the objects given")
        if skip_small and len(fr["points"]) < MIN_POINTS:
            skipped.append(f"{f}: only {len(fr['points'])} visible points")
            continue
        out.append(frame_sample(fr, parts[key], structure, theta, cache_points, seed, f))
    return out, skipped


class ANCSHFrames(Dataset):
    """Fixed-size, normalised ANCSH training samples drawn from :class:`FrameSample` s.

    Each item draws ``n_points`` of a scan's cached points (a fresh random subset per epoch
    and item, :meth:`set_epoch`; seeded), normalises them (:func:`normalize_points`) and
    optionally jitters them.

    Parameters
    ----------
    samples : sequence of FrameSample
    n_points : int
    seed : int
    jitter : float
        Standard deviation of Gaussian noise on the normalised points (0: none).

    Shapes:
        item ``i`` -> dict of tensors: ``xyz`` (N, 3) float32 (normalised input),
        ``points`` (N, 3) float32 (camera frame), ``center`` (3,) float32, ``scale`` ()
        float32, ``seg`` (N,) int64, ``npcs`` (N, 3), ``naocs`` (N, 3), ``heatmap`` (N,),
        ``unitvec`` (N, 3), ``axis`` (N, 3) float32, ``joint`` (N,) int64,
        ``position_mask`` (N,) bool, ``index`` () int64. Batches of the default collate add a
        leading B, the layout :func:`kinmo.ancsh.model.ancsh_loss` expects.
    """

    def __init__(self, samples: Sequence[FrameSample], n_points: int, seed: int = 0, jitter: float = 0.0) -> None:
        if not samples:
            raise ValueError("no training scans")
        self.samples = list(samples)
        self.n_points = int(n_points)
        self.seed = int(seed)
        self.jitter = float(jitter)
        self.epoch = 0

    def __len__(self) -> int:
        return len(self.samples)

    def set_epoch(self, epoch: int) -> None:
        """Draw new point subsets (seeded by ``(seed, epoch, index)``)."""
        self.epoch = int(epoch)

    def __getitem__(self, i: int) -> dict[str, torch.Tensor]:
        return self.sample(i, np.random.default_rng([self.seed, self.epoch, int(i)]))

    def sample(self, i: int, rng: np.random.Generator) -> dict[str, torch.Tensor]:
        """Item ``i`` with the points drawn by ``rng`` (see the class docstring)."""
        s = self.samples[i]
        idx = subsample_indices(len(s), self.n_points, rng)
        pts = s.points[idx]
        xyz, center, scale = normalize_points(pts)
        if self.jitter > 0:
            xyz = xyz + rng.normal(0.0, self.jitter, size=xyz.shape).astype(np.float32)
        out = {
            "xyz": torch.from_numpy(np.ascontiguousarray(xyz)),
            "points": torch.from_numpy(np.ascontiguousarray(pts)),
            "center": torch.tensor(center, dtype=torch.float32),
            "scale": torch.tensor(scale, dtype=torch.float32),
            "index": torch.tensor(int(i)),
        }
        for k in TARGET_KEYS:
            out[k] = torch.from_numpy(np.ascontiguousarray(getattr(s, k)[idx]))
        return out
