"""``kinmo render``: a parallel, resumable renderer of partial scans with ANCSH ground truth.

For every PartNet-Mobility-format object under a dataset root (real objects, generated ones,
or PartNet shapes pseudo-labelled with a ``mobility_v2.json``), :func:`render_dataset`
renders ``frames_per_object`` single-view depth scans in PyBullet (DIRECT, CPU TinyRenderer,
:class:`~kinmo.render.scene.Scene`), each with a random joint state and a random viewpoint,
back-projects them to labelled point clouds and computes the ground truth ANCSH needs (Li et
al. CVPR 2020; Liu et al. CVPR 2023 Sec. 4.3 evaluate on such scans).

Per frame (:func:`render_frame`), drawn from a generator seeded by ``(seed, crc32(key),
frame)`` (reproducible whatever the worker count, order or resumption):

1. the joint state, uniform within the URDF limits (:func:`~kinmo.render.scene.sample_joint_state`;
   a cylindrical joint's angle held at rest when ``RenderConfig.turn_cylindrical`` is false);
2. the viewpoint: azimuth all around the vertical +y axis, elevation in ``elevation_deg``
   above the horizontal plane, distance ``distance_factor`` times the distance at which the
   posed object's bounding sphere fits the field of view
   (:func:`~kinmo.render.camera.sample_camera`);
3. depth + link segmentation (``ER_SEGMENTATION_MASK_OBJECT_AND_LINKINDEX``), metric depth,
   back-projection to the OpenCV camera frame, ANCSH ground truth
   (:func:`~kinmo.render.ancsh_gt.frame_ground_truth`).

Outputs in ``out``:

- ``<key>/<frame:05d>.npz``: one frame file each (atomic, deflate-compressed; ``np.load``
  reads it; arrays and dtypes in :mod:`kinmo.render.frames`), ``key`` as in ``kinmo prepare``
  (:func:`kinmo.stages.cache_key`);
- ``manifest.csv`` / ``manifest.json``: one row per (object, frame) (:data:`MANIFEST_COLUMNS`),
  status ``ok``, ``skipped`` (up to date) or ``failed`` (one-line reason naming the file),
  written incomplete (``complete: false``) before the first object, rewritten atomically as
  objects complete and at the end (:mod:`kinmo.stages`).

Resume: a frame is skipped when its file exists and records the same :data:`FRAME_VERSION`,
:class:`RenderConfig` and source fingerprint (:func:`kinmo.stages.source_fingerprint`), so
an interrupted run resumes where it stopped and a larger ``frames_per_object`` only renders
the new frames. One run at a time per output folder (``.lock``).

Parallelism: :func:`render_one` is a pure function of picklable arguments (one object, all
its frames: the URDF and meshes are loaded once) returning manifest rows and never raising
for bad input; :func:`render_dataset` runs it over the objects with the stage machinery of
:mod:`kinmo.stages` on the chosen executor (:mod:`kinmo.executor`: a ``spawn`` process pool,
or Ray). ``load_frame``, ``frame_images``, ``frame_path`` and ``FRAME_VERSION`` of
:mod:`kinmo.render.frames` are importable from here too.

Length: over 500 lines, about 30 % of them docstrings: one topic, the ``kinmo render`` stage
(the render of one frame, the resume of an object's frames from their metadata, the manifest
and the run); scene, camera, ground truth and frame format are their own modules, and what the
per-shape stages share is :mod:`kinmo.stages`.
"""

from __future__ import annotations

import time
import zlib
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from functools import partial
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from kinmo import __version__, stages
from kinmo.data.readers import read_shape
from kinmo.errors import KinmoDataError
from kinmo.io import check_outputs_apart
from kinmo.render.ancsh_gt import frame_ground_truth, link_meshes, rest_geometry
from kinmo.render.camera import back_project, sample_camera
from kinmo.render.frames import (
    FRAME_VERSION,
    frame_images,
    frame_path,
    load_frame,
    read_frame_meta,
    save_frame,
)
from kinmo.render.scene import Scene, sample_joint_state
from kinmo.stages import ShapeStage, StageRow, matches, one_line, source_fingerprint

__all__ = [
    "FRAME_VERSION",
    "MANIFEST_COLUMNS",
    "FrameRow",
    "RenderConfig",
    "RenderResult",
    "frame_images",
    "frame_path",
    "frame_rng",
    "load_frame",
    "read_manifest",
    "render_dataset",
    "render_frame",
    "render_one",
]

MANIFEST_COLUMNS: tuple[str, ...] = (
    "id", "frame", "file", "category", "status", "error", "n_points", "n_parts",
    "n_moving_joints", "azimuth_deg", "elevation_deg", "distance", "seconds", "source",
)
#: Objects a render worker process renders before it is replaced by a fresh one: PyBullet's
#: process-wide state grows with every object loaded (89 -> 297 MB after 100 -> 3,000 objects
#: in one process, ``docs/results/scaling.md``), so workers are recycled to keep memory flat.
RECYCLE_WORKERS_AFTER = 200


@dataclass(frozen=True)
class RenderConfig:
    """Everything that changes the content of a rendered frame.

    Attributes
    ----------
    width, height : int
        Image size in pixels (each <= 65535).
    fov_y : float
        Vertical field of view, degrees.
    elevation_deg : (float, float)
        Camera elevation range above the horizontal plane, degrees.
    distance_factor : (float, float)
        Camera distance range in units of the fitting distance (>= 1: whole object in view).
    seed : int
        Base seed.
    turn_cylindrical : bool
        Draw a cylindrical joint's angle as well as its translation (True), or hold it at its
        rest angle (False: the prismatic view ANCSH takes of such a joint, a bottle's screw
        cap; :func:`kinmo.render.scene.sample_joint_state`).
    """

    width: int = 256
    height: int = 256
    fov_y: float = 45.0
    elevation_deg: tuple[float, float] = (10.0, 50.0)
    distance_factor: tuple[float, float] = (1.1, 1.6)
    seed: int = 0
    turn_cylindrical: bool = True

    def __post_init__(self) -> None:
        if not (1 <= self.width <= 65535 and 1 <= self.height <= 65535):
            raise ValueError(f"image size must be in 1..65535, got {self.width}x{self.height}")
        if not 0 < self.fov_y < 180:
            raise ValueError(f"fov_y must be in (0, 180), got {self.fov_y}")
        lo, hi = self.elevation_deg
        if not -90 < lo <= hi < 90:
            raise ValueError(f"elevation_deg must be within (-90, 90), got {self.elevation_deg}")
        dlo, dhi = self.distance_factor
        if not 1 <= dlo <= dhi:
            raise ValueError(f"distance_factor needs 1 <= lo <= hi, got {self.distance_factor}")
        object.__setattr__(self, "elevation_deg", (float(lo), float(hi)))
        object.__setattr__(self, "distance_factor", (float(dlo), float(dhi)))

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready dict (stored in every frame's ``meta_json``)."""
        d = asdict(self)
        d["elevation_deg"] = list(self.elevation_deg)
        d["distance_factor"] = list(self.distance_factor)
        return d


@dataclass
class FrameRow(StageRow):
    """One frame's line in the manifest (:data:`MANIFEST_COLUMNS`)."""

    id: str
    frame: int
    source: str
    status: str
    file: str = ""
    category: str = ""
    error: str = ""
    n_points: int | None = None
    n_parts: int | None = None
    n_moving_joints: int | None = None
    azimuth_deg: float | None = None
    elevation_deg: float | None = None
    distance: float | None = None
    seconds: float = 0.0

    columns: ClassVar[tuple[str, ...]] = MANIFEST_COLUMNS


@dataclass
class RenderResult:
    """Outcome of :func:`render_dataset`: ``rows`` sorted by (id, frame)."""

    out: Path
    rows: list[FrameRow]
    n_objects: int
    seconds: float
    failed_objects: list[str] = field(default_factory=list)

    def count(self, status: str) -> int:
        """Number of frame rows with this status."""
        return sum(r.status == status for r in self.rows)


def frame_rng(seed: int, key: str, frame: int) -> np.random.Generator:
    """The generator of one frame: ``default_rng([seed, crc32(key), frame])``."""
    return np.random.default_rng([int(seed) & 0xFFFFFFFF, zlib.crc32(key.encode()), int(frame)])


# ------------------------------------------------------------------------------ one frame


def _posed_sphere(
    scene: Any, geometry: Any, poses: dict[int, np.ndarray]
) -> tuple[np.ndarray, float]:
    """Bounding sphere of the posed object: the box of its posed part-box corners."""
    corners = []
    for k, pid in enumerate(geometry.part_ids):
        lo, hi = geometry.part_bounds[k]
        c = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1])
                      for z in (lo[2], hi[2])])
        T = poses[int(pid)]
        corners.append(c @ T[:3, :3].T + T[:3, 3])
    allc = np.concatenate(corners)
    lo, hi = allc.min(0), allc.max(0)
    return (lo + hi) / 2.0, max(float(np.linalg.norm(hi - lo)) / 2.0, 1e-6)


def render_frame(
    scene: Any, geometry: Any, config: RenderConfig, rng: np.random.Generator
) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
    """Render one frame of a loaded object.

    Parameters
    ----------
    scene : kinmo.render.scene.Scene
        The loaded object (its state is changed).
    geometry : kinmo.render.ancsh_gt.RestGeometry
        Its rest-pose boxes.
    config : RenderConfig
    rng : numpy.random.Generator
        Draws the joint state, then azimuth, elevation and distance.

    Returns
    -------
    arrays : dict of str to ndarray
        The frame file's arrays (dtypes as stored, :mod:`kinmo.render.frames`), without ``meta_json``.
    view : dict
        ``azimuth_deg``, ``elevation_deg``, ``distance``, ``near``, ``far``,
        ``state`` (link id -> [translation, angle]).
    """

    state = sample_joint_state(scene.joints, rng, config.turn_cylindrical)
    scene.set_state(state)
    poses = scene.link_poses()
    center, radius = _posed_sphere(scene, geometry, poses)
    cam, view = sample_camera(
        rng, center, radius, config.width, config.height, config.fov_y,
        config.elevation_deg, config.distance_factor,
    )
    depth, labels = scene.render(cam, segmentation=True)
    mask = labels >= 0
    points, pixels = back_project(depth, cam.K, mask)
    links = labels[mask]
    gt = frame_ground_truth(points, links, cam, poses, geometry, scene.joints, state)
    f32 = np.float32
    arrays: dict[str, np.ndarray] = {
        "points": points.astype(f32),
        "pixels": pixels.astype(np.uint16),
        "link": links.astype(np.int16),
        "part": gt["part"].astype(np.int16),
        "npcs": gt["npcs"].astype(np.float16),
        "naocs": gt["naocs"].astype(np.float16),
        "K": cam.K,
        "cam_to_world": cam.cam_to_world,
        "image_size": np.array([cam.height, cam.width], dtype=np.int32),
    }
    for k in ("part_ids", "joint_ids", "joint_parent", "link_ids"):
        arrays[k] = gt[k].astype(np.int16)
    arrays["joint_type"] = gt["joint_type"].astype(np.int8)
    for k in ("part_rotation", "part_translation", "part_scale", "part_bounds", "naocs_rotation",
              "naocs_translation", "naocs_scale", "joint_origin", "joint_direction",
              "joint_origin_naocs", "joint_direction_naocs", "joint_translation", "joint_angle",
              "joint_translation_limits", "joint_angle_limits", "link_pose"):
        arrays[k] = np.asarray(gt[k], dtype=f32)
    view = dict(view, near=cam.near, far=cam.far,
                state={str(k): [float(t), float(a)] for k, (t, a) in state.items()})
    return arrays, view


def _cached_meta(path: Path, config: RenderConfig, fingerprint: str) -> dict[str, Any] | None:
    meta = read_frame_meta(path)
    if meta is None or not matches(meta, {"frame_version": FRAME_VERSION, "config": config.as_dict(),
                          "fingerprint": fingerprint}):
        return None
    return meta


def _row_from_meta(meta: dict[str, Any], status: str, source: str, file: str) -> FrameRow:
    v = meta.get("view", {})
    c = meta.get("counts", {})
    return FrameRow(
        id=meta["key"], frame=int(meta["frame"]), source=source, status=status, file=file,
        category=meta.get("category", ""), n_points=c.get("n_points"), n_parts=c.get("n_parts"),
        n_moving_joints=c.get("n_moving_joints"), azimuth_deg=_r(v.get("azimuth_deg")),
        elevation_deg=_r(v.get("elevation_deg")), distance=_r(v.get("distance")),
    )


def _r(x: float | None) -> float | None:
    return None if x is None else round(float(x), 6)


# ------------------------------------------------------------------------------ one object


def render_one(
    path: str | Path,
    out_dir: str | Path,
    config: RenderConfig,
    frames: int,
    key: str | None = None,
    force: bool = False,
) -> list[FrameRow]:
    """Render frames ``0 .. frames-1`` of one object; never raises for bad input.

    A pure function of its (picklable) arguments: safe in any worker process, or wrapped by
    ``ray.remote`` on machines sharing the file system.

    Parameters
    ----------
    path : str or Path
        The object folder (PartNet-Mobility format: ``mobility_v2.json`` + ``textured_objs``).
    out_dir : str or Path
        Output root; frames go to ``out_dir/<key>/<frame:05d>.npz`` (atomic writes).
    config : RenderConfig
    frames : int
        Number of frames of the object.
    key : str, optional
        Output sub-folder; the folder name by default.
    force : bool
        Re-render frames that are up to date.

    Returns
    -------
    list of FrameRow
        One per frame, by frame index: ``ok`` (rendered now), ``skipped`` (up to date) or
        ``failed`` with a one-line error naming the file (a
        :class:`~kinmo.errors.KinmoDataError` message, or ``"<folder>: internal error ..."``).
    """
    t0 = time.perf_counter()
    folder = Path(path)
    out_dir = Path(out_dir)
    key = key or folder.name
    rows: dict[int, FrameRow] = {}
    try:
        fp = source_fingerprint(folder)
        todo = []
        for f in range(frames):
            fpath = frame_path(out_dir, key, f)
            meta = None if force else _cached_meta(fpath, config, fp)
            if meta is not None:
                rows[f] = _row_from_meta(meta, "skipped", str(folder), f"{key}/{fpath.name}")
            else:
                todo.append(f)
        if todo:
            _render_frames(folder, out_dir, config, key, todo, fp, rows)
    except KinmoDataError as e:
        err = one_line(str(e))
    except Exception as e:  # a bug or an environment problem: still rows, the run goes on
        err = one_line(f"{folder}: internal error {type(e).__name__}: {e}")
    else:
        err = ""
    if err:
        for f in range(frames):
            if f not in rows:
                rows[f] = FrameRow(id=key, frame=f, source=str(folder), status="failed", error=err)
    if err:
        try:  # best effort: name the category of a failed object
            from kinmo.data.readers import _read_meta

            category = _read_meta(folder)[0]
        except Exception:
            category = ""
        share = round((time.perf_counter() - t0) / max(1, frames), 4)
        for r in rows.values():
            if r.status == "failed":
                r.category, r.seconds = category, share
    return [rows[f] for f in range(frames)]


def _render_frames(
    folder: Path, out_dir: Path, config: RenderConfig, key: str, todo: list[int], fp: str,
    rows: dict[int, FrameRow],
) -> None:
    shape = read_shape(folder)
    if not shape.links:
        raise KinmoDataError(folder / "mobility_v2.json",
                             "no kinematic links (render needs a PartNet-Mobility object)")
    with Scene(shape) as scene:
        geometry = rest_geometry(scene.links, link_meshes(shape, scene.links), scene.frame_origins)
        for f in todo:
            t0 = time.perf_counter()
            arrays, view = render_frame(scene, geometry, config, frame_rng(config.seed, key, f))
            counts = {"n_points": int(len(arrays["points"])),
                      "n_parts": int(len(arrays["part_ids"])),
                      "n_moving_joints": int(len(arrays["joint_ids"]))}
            meta = {
                "frame_version": FRAME_VERSION, "kinmo_version": __version__, "key": key,
                "id": shape.id, "category": shape.category, "frame": f, "config": config.as_dict(),
                "fingerprint": fp, "view": view, "counts": counts,
                "camera": "opencv", "world": "mesh frame (y-up)",
                "joint_kinds": ["revolute", "prismatic", "cylindrical"],
            }
            fpath = frame_path(out_dir, key, f)
            save_frame(fpath, arrays, meta)
            row = _row_from_meta(meta, "ok", str(folder), f"{key}/{fpath.name}")
            row.seconds = round(time.perf_counter() - t0, 4)
            rows[f] = row


# ------------------------------------------------------------------------------- manifest


def read_manifest(path: str | Path) -> list[FrameRow]:
    """Read a render ``manifest.csv`` (or the output folder holding one) back into rows.

    Raises
    ------
    KinmoDataError
        Missing or malformed manifest.
    """
    return stages.read_manifest(path, FrameRow)


# ----------------------------------------------------------------------------- the run


def _render_job(job: tuple[Path, str], out: Path, config: RenderConfig, frames: int,
                force: bool) -> list[FrameRow]:
    f, key = job
    return render_one(f, out, config, frames, key, force)


def _worker_failed(job: tuple[Path, str], e: Exception, frames: int) -> list[FrameRow]:
    # the worker raised or died (e.g. killed for memory): every frame of the object failed
    f, key = job
    msg = stages.worker_error(f, e)
    return [FrameRow(id=key, frame=i, source=str(f), status="failed", error=msg)
            for i in range(frames)]


def render_dataset(
    root: str | Path,
    out: str | Path,
    frames_per_object: int,
    config: RenderConfig | None = None,
    workers: int = 0,
    force: bool = False,
    progress: bool = True,
    on_rows: Callable[[list[FrameRow]], None] | None = None,
    executor: str = "local",
) -> RenderResult:
    """Render ``frames_per_object`` partial scans of every object under ``root``.

    Parameters
    ----------
    root : str or Path
        Dataset folder (possibly nested) or one object folder; folders without
        ``mobility_v2.json`` (PartNet shapes without motion) fail with a reason.
    out : str or Path
        Output folder (created).
    frames_per_object : int
        Frames per object, >= 1.
    config : RenderConfig, optional
    workers : int
        Worker processes; 0 = one per available CPU; 1 = in this process.
    force : bool
        Re-render up-to-date frames.
    progress : bool
        Show a rich progress bar (stderr) counting frames.
    on_rows : callable, optional
        Called in this process with each object's rows as it completes.
    executor : str
        ``local``, ``ray``, ``ray:auto`` or ``ray:ADDRESS`` (:mod:`kinmo.executor`).

    Returns
    -------
    RenderResult
        Failures are reported in it and in the manifest, never raised.

    Raises
    ------
    KinmoDataError
        ``root`` is not a folder.
    KinmoError
        Another run holds the output folder's lock.
    KinmoUsageError
        ``out`` is, lies inside or holds ``root`` (outputs never overwrite inputs).
    ValueError
        ``frames_per_object < 1``.
    """
    if frames_per_object < 1:
        raise ValueError(f"frames_per_object must be >= 1, got {frames_per_object}")
    t0 = time.perf_counter()
    config = config or RenderConfig()
    root, out = Path(root), Path(out)
    jobs = stages.shape_jobs(root, required=False)
    check_outputs_apart(out, [root])
    out.mkdir(parents=True, exist_ok=True)

    def save(results: list[list[FrameRow]], complete: bool) -> None:
        rows = sorted((r for rs in results for r in rs), key=lambda r: (r.id, r.frame))
        stages.write_manifest(
            out, rows, MANIFEST_COLUMNS,
            {"frame_version": FRAME_VERSION, "root": str(root), "config": config.as_dict(),
             "frames_per_object": frames_per_object, "n_objects": len(jobs)},
            "frames", complete)

    stage: ShapeStage[list[FrameRow]] = ShapeStage(
        out, "kinmo render", len(jobs), save=save, bar_total=len(jobs) * frames_per_object,
        title="render", description=root.name, progress=progress, on_result=on_rows,
        scratch=(".*.tmp", "*/.*.tmp"))
    with stage:
        stage.map(
            partial(_render_job, out=out, config=config, frames=frames_per_object, force=force),
            jobs, workers, partial(_worker_failed, frames=frames_per_object),
            max_tasks_per_child=RECYCLE_WORKERS_AFTER, executor=executor,
        )
    rows = [r for rs in stage.results for r in rs]
    failed = [rs[0].id for rs in stage.results if rs and all(r.status == "failed" for r in rs)]
    return RenderResult(out=out, rows=sorted(rows, key=lambda r: (r.id, r.frame)),
                        n_objects=len(jobs), seconds=time.perf_counter() - t0,
                        failed_objects=sorted(failed))
