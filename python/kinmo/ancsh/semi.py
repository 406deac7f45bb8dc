"""The semi-supervised baseline of Liu et al. CVPR 2023 (Table 2, "semi"): self-training ANCSH.

A model trained on the labelled scans predicts on scans of the *unlabelled* PartNet shapes
of the category; its confident predictions become pseudo-targets and training continues on
both. PartNet shapes carry no motion, so they can only be seen in the pose they were modelled
in: :func:`unlabeled_object` wraps a PartNet shape as a PartNet-Mobility-format object with a
single root link (no joint) — the renderer then draws it at rest from random viewpoints, using
nothing but its geometry. Nothing of the motion GNN or of the pseudo-labels of
``kinmo pseudo-label`` is used here (that is the ``semi-weakly`` setting).

Pseudo-targets of one scan (:func:`pseudo_sample`), from the network output and its
post-processing (:func:`kinmo.ancsh.postprocess.estimate`):

- ``seg``: the predicted part of each point (arg max);
- ``npcs``: each point mapped through the inverse of its part's fitted pose (the fitted
  similarity makes the targets of a part rigidly consistent), clipped to the unit cube;
- ``naocs``: the predicted NAOCS;
- joint targets (:func:`kinmo.ancsh.targets.joint_targets`) from the estimated joints mapped
  to NAOCS by the inverse of the fitted NAOCS -> camera similarity.

A scan is a candidate (:func:`scan_confidence`) when the mean per-point segmentation
probability is at least ``min_seg_confidence``, every part with at least 4 points has a RANSAC
inlier ratio of at least ``min_inlier_ratio`` (the share of its points within the estimator's
inlier threshold, 5 % of the scan's radius, of its fitted pose), at least two parts are seen
and at least :data:`MIN_IN_CUBE` of the points map into the NPCS cube through their part's
pose (a degenerate pose, e.g. a tiny scale, sends them far outside); the ``pseudo_keep_fraction`` of the candidates with the highest inlier ratio are kept
(:func:`semi_pseudo_targets`, called by :func:`kinmo.ancsh.train.train_ancsh`).
"""

from __future__ import annotations

import json
import os
import shutil
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from kinmo.ancsh.dataset import FrameSample
from kinmo.ancsh.inference import predict_scans, quiet_estimate
from kinmo.ancsh.postprocess import ANCSHEstimate
from kinmo.ancsh.scans import category_folders, render_objects
from kinmo.ancsh.structure import KinematicStructure
from kinmo.ancsh.targets import joint_targets
from kinmo.data.readers import read_hierarchy
from kinmo.errors import KinmoDataError
from kinmo.render.dataset import load_frame
from kinmo.train.loop import rows_csv

__all__ = ["CUBE_MARGIN", "MIN_IN_CUBE", "RECORD_COLUMNS", "pose_npcs", "pseudo_sample", "records_csv",
           "scan_confidence", "semi_pseudo_targets", "softmax", "unlabeled_object"]

#: Margin of the unit cube within which pose-mapped NPCS count as valid.
CUBE_MARGIN = 0.05
#: A pseudo-targeted scan needs at least this share of valid pose-mapped NPCS.
MIN_IN_CUBE = 0.95


def _hard_link(src: Path, dst: Path) -> None:
    """``dst`` the same file as ``src``: a hard link, or an atomic copy across file systems;
    left alone when already up to date."""
    if not src.is_file():
        return  # read_shape names the missing mesh
    if dst.is_file() and not dst.is_symlink():
        a, b = src.stat(), dst.stat()
        if (a.st_ino, a.st_dev) == (b.st_ino, b.st_dev) or (a.st_size == b.st_size
                                                           and b.st_mtime_ns >= a.st_mtime_ns):
            return
    tmp = dst.with_name(f".{dst.name}.tmp")
    tmp.unlink(missing_ok=True)
    try:
        os.link(src, tmp)
    except OSError:
        shutil.copy2(src, tmp)
    os.replace(tmp, dst)


def unlabeled_object(source: str | Path, dest: str | Path) -> Path:
    """Wrap a PartNet shape as a motionless PartNet-Mobility-format object.

    ``dest`` gets symbolic links to the source's ``result.json`` and ``meta.json``, its meshes
    hard-linked (copied across file systems) into ``textured_objs/`` (kinmo's readers refuse
    meshes that resolve outside an object folder), and a ``mobility_v2.json`` with one root
    link holding the whole hierarchy (joint ``free``: no degree of freedom is rendered). Files
    already up to date are left untouched (so renders of it stay cached).

    Parameters
    ----------
    source : str or Path
        A PartNet shape folder (``result.json`` + ``objs/``).
    dest : str or Path
        The folder to write.

    Returns
    -------
    Path
        ``dest``.

    Raises
    ------
    KinmoDataError
        ``source`` is not a readable PartNet shape.
    """

    src, dst = Path(source).resolve(), Path(dest)
    if not (src / "objs").is_dir():
        raise KinmoDataError(src / "objs", "folder is missing (not a PartNet shape)")
    hier = read_hierarchy(src / "result.json")  # validates the mesh names
    dst.mkdir(parents=True, exist_ok=True)
    for name, target in (("result.json", src / "result.json"), ("meta.json", src / "meta.json")):
        link = dst / name
        if not target.exists():
            continue
        if link.is_symlink() and Path(link.readlink()) == target:
            continue
        if link.is_symlink() or link.exists():
            link.unlink()
        link.symlink_to(target)
    tex = dst / "textured_objs"
    if tex.is_symlink():  # written by an earlier kinmo as a link to objs/
        tex.unlink()
    tex.mkdir(exist_ok=True)
    for nid in hier.order:
        for mesh in hier.nodes[nid].objs:
            _hard_link(src / "objs" / f"{mesh}.obj", tex / f"{mesh}.obj")
    text = json.dumps([{"id": 0, "parent": -1, "joint": "free", "name": "base",
                        "parts": [{"id": hier.root}], "jointData": {}}])
    mob = dst / "mobility_v2.json"
    if not mob.is_file() or mob.read_text() != text:
        from kinmo.io import write_text

        write_text(mob, text)
    return dst


def softmax(logits: np.ndarray) -> np.ndarray:
    """Row-wise softmax of ``(N, C)`` logits."""
    z = np.asarray(logits, dtype=np.float64)
    z = z - z.max(-1, keepdims=True)
    e = np.exp(z)
    return e / e.sum(-1, keepdims=True)


def scan_confidence(points: np.ndarray, pred: Mapping[str, np.ndarray], est: ANCSHEstimate) -> dict[str, Any]:
    """How much to trust ANCSH's output on one scan.

    Parameters
    ----------
    points : (N, 3) float
        The scan points the network saw, camera frame.
    pred : mapping
        Network output of the scan (:func:`kinmo.ancsh.inference.predict_scans`).
    est : ANCSHEstimate
        Its post-processing.

    Returns
    -------
    dict
        ``seg_confidence`` (mean max softmax probability), ``inlier_ratio`` (the smallest over
        parts with >= 4 points, 0 when none), ``part_inlier_ratio`` (list, NaN for parts with
        < 4 points), ``parts_seen`` (parts with >= 4 points), ``in_cube`` (share of the points
        whose NPCS through their part's fitted pose lies in the unit cube, margin
        :data:`CUBE_MARGIN`: a pose that maps its points outside NPCS is wrong).
    """
    pts = np.asarray(points, dtype=np.float64)
    prob = softmax(pred["seg_logits"])
    seg = est.segmentation
    radius = float(np.linalg.norm(pts - pts.mean(0), axis=1).max()) or 1.0
    thr = 0.05 * radius
    ratios = []
    for k, part in enumerate(est.parts):
        idx = np.flatnonzero(seg == k)
        if len(idx) < 4:
            ratios.append(float("nan"))
            continue
        npcs = np.asarray(pred["npcs"][idx, k], dtype=np.float64)
        fit = part.scale * npcs @ part.rotation.T + part.translation
        ratios.append(float((np.linalg.norm(fit - pts[idx], axis=1) < thr).mean()))
    seen = [r for r in ratios if not np.isnan(r)]
    npcs = pose_npcs(pts, est)
    in_cube = np.all((npcs >= -CUBE_MARGIN) & (npcs <= 1 + CUBE_MARGIN), axis=1)
    return {
        "seg_confidence": float(prob.max(-1).mean()),
        "inlier_ratio": float(min(seen)) if seen else 0.0,
        "part_inlier_ratio": ratios,
        "parts_seen": len(seen),
        "in_cube": float(in_cube.mean()) if len(in_cube) else 0.0,
    }


def pose_npcs(points: np.ndarray, est: ANCSHEstimate) -> np.ndarray:
    """NPCS of every point through the inverse fitted pose of its predicted part.

    Returns
    -------
    (N, 3) float64
        ``R_k^T (p - t_k) / s_k`` for the part ``k`` of each point (0 for an empty estimate).
    """
    pts = np.asarray(points, dtype=np.float64)
    seg = np.asarray(est.segmentation, dtype=np.int64)
    out = np.zeros_like(pts)
    for k, part in enumerate(est.parts):
        m = seg == k
        if m.any():
            out[m] = (pts[m] - part.translation) @ part.rotation / max(part.scale, 1e-12)
    return out


def pseudo_sample(
    key: str,
    frame: int,
    points: np.ndarray,
    pred: Mapping[str, np.ndarray],
    est: ANCSHEstimate,
    structure: KinematicStructure,
    theta: float = 0.2,
) -> FrameSample:
    """Pseudo-targets of one scan from ANCSH's own output (module docstring).

    Parameters
    ----------
    key : str
        Object key of the scan.
    frame : int
    points : (N, 3) float
        The points the network saw, camera frame.
    pred : mapping
        Network output for these points.
    est : ANCSHEstimate
        Post-processing of ``pred``.
    structure : KinematicStructure
    theta : float
        Joint association distance, NAOCS units.

    Returns
    -------
    FrameSample
        ``kind="pseudo"``, one entry per point.
    """
    pts = np.asarray(points, dtype=np.float64)
    seg = np.asarray(est.segmentation, dtype=np.int64)
    npcs = np.clip(pose_npcs(pts, est), 0.0, 1.0)
    naocs = np.asarray(pred["naocs"], dtype=np.float64)
    g = est.naocs_to_camera
    origins = np.array([g.rotation.T @ (j.origin - g.translation) / g.scale for j in est.joints])
    directions = np.array([g.rotation.T @ j.direction for j in est.joints])
    tg = joint_targets(naocs, seg, structure, origins, directions, theta)
    return FrameSample(
        key=key, frame=int(frame), kind="pseudo",
        points=pts.astype(np.float32), seg=seg, npcs=npcs.astype(np.float32),
        naocs=naocs.astype(np.float32), heatmap=tg["heatmap"].astype(np.float32),
        unitvec=tg["unitvec"].astype(np.float32), axis=tg["axis"].astype(np.float32),
        joint=tg["joint"].astype(np.int64), position_mask=tg["position_mask"].astype(bool),
    )


#: Columns of ``pseudo_targets.csv``: one row per unlabelled scan.
RECORD_COLUMNS = ("id", "frame", "n_points", "seg_confidence", "inlier_ratio", "parts_seen", "in_cube", "kept")


def records_csv(records: list[dict[str, Any]]) -> str:
    """``pseudo_targets.csv`` text (:data:`RECORD_COLUMNS`) of :func:`semi_pseudo_targets`'s records."""

    return rows_csv(records, RECORD_COLUMNS, digits=None, nan="nan")


def semi_pseudo_targets(
    model: Any, cat: Any, structure: KinematicStructure, partnet: Path, test_ids: set[str],
    out: Path, scans_dir: Path, cfg: Any, device: Any, progress: bool,
) -> tuple[list[FrameSample], list[dict[str, Any]]]:
    """Render the category's PartNet shapes at rest, label them with ``model``, keep the
    confident scans (module docstring).

    Parameters
    ----------
    model : ANCSH
        The supervised stage's network (on ``device``).
    cat : CategoryObjects
    structure : KinematicStructure
    partnet : Path
        PartNet dataset folder (the unlabelled shapes).
    test_ids : set of str
        Shapes never used (test objects of the split).
    out : Path
        Run folder (``objects/unlabeled`` gets the wrappers of :func:`unlabeled_object`).
    scans_dir : Path
        Render cache (``unlabeled/``).
    cfg : ANCSHConfig
        Frames per shape, thresholds, ``pseudo_keep_fraction``, seeds.
    device : torch.device
    progress : bool

    Returns
    -------
    kept : list of FrameSample
        The pseudo-targeted scans.
    records : list of dict
        One per scan (:data:`RECORD_COLUMNS`), ``kept`` telling which were.
    """
    import math

    shapes = {k: f for k, f in category_folders(partnet, cat.category).items()
              if (f / "objs").is_dir() and k not in test_ids}
    wrappers: dict[str, Path] = {}
    for k, f in sorted(shapes.items()):
        try:
            wrappers[k] = unlabeled_object(f, out / "objects" / "unlabeled" / k)
        except KinmoDataError:
            continue
    files, _ = render_objects(wrappers, out / "objects" / "unlabeled", scans_dir / "unlabeled",
                              cfg.unlabeled_frames_per_object, cfg, progress)
    frames = [load_frame(f) for f in files]
    frames = [fr for fr in frames if len(fr["points"]) >= 32]
    seeds = [int(fr["meta"]["frame"]) + 1000 * i for i, fr in enumerate(frames)]
    preds = predict_scans(model, [fr["points"] for fr in frames], cfg.n_points, device, seeds)
    kept: list[FrameSample] = []
    records: list[dict[str, Any]] = []
    candidates: list[tuple[float, int, np.ndarray, dict[str, np.ndarray], Any]] = []
    for fr, (pts, pred) in zip(frames, preds):
        key, index = str(fr["meta"]["key"]), int(fr["meta"]["frame"])
        rec: dict[str, Any] = {"id": key, "frame": index, "n_points": len(fr["points"])}
        try:
            est = quiet_estimate(pts, pred, structure, theta=cfg.theta, seed=cfg.seed)
        except (ValueError, np.linalg.LinAlgError):
            rec.update(seg_confidence="", inlier_ratio="", parts_seen=0, kept=False)
            records.append(rec)
            continue
        conf = scan_confidence(pts, pred, est)
        ok = (conf["seg_confidence"] >= cfg.min_seg_confidence and conf["inlier_ratio"] >= cfg.min_inlier_ratio
              and conf["parts_seen"] >= 2 and conf["in_cube"] >= MIN_IN_CUBE)
        rec.update(seg_confidence=round(conf["seg_confidence"], 4), inlier_ratio=round(conf["inlier_ratio"], 4),
                   parts_seen=conf["parts_seen"], in_cube=round(conf["in_cube"], 4), kept=False)
        records.append(rec)
        if ok:
            candidates.append((conf["inlier_ratio"], len(records) - 1, pts, pred, est))
    # the most consistent share of the confident scans (ties: scan order)
    candidates.sort(key=lambda c: (-c[0], c[1]))
    n_keep = int(math.ceil(cfg.pseudo_keep_fraction * len(candidates)))
    for _, i, pts, pred, est in sorted(candidates[:n_keep], key=lambda c: c[1]):
        records[i]["kept"] = True
        kept.append(pseudo_sample(str(records[i]["id"]), int(records[i]["frame"]), pts, pred, est, structure,
                                  cfg.theta))
    return kept, records
