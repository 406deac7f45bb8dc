"""The frame file of ``kinmo render``: one partial scan with its ANCSH ground truth.

A frame file ``<out>/<key>/<frame:05d>.npz`` (:func:`frame_path`) is a deflate-compressed
``.npz`` (``np.load`` reads it), written atomically (:func:`save_frame`, :mod:`kinmo.io`) by
:mod:`kinmo.render.dataset` and read by ANCSH training and evaluation (:func:`load_frame`).
Arrays, for N points, K rigid parts, J moving joints and L links; camera frame = OpenCV,
lengths in mesh units (details in :mod:`kinmo.render.ancsh_gt`):

- ``points`` (N, 3) float32: camera frame; ``pixels`` (N, 2) uint16: (row, column);
- ``link``, ``part`` (N,) int16: link id and rigid part id of each point;
- ``npcs``, ``naocs`` (N, 3) float16: values in [0, 1], quantisation <= 2.5e-4;
- ``K`` (3, 3) float64: intrinsics; ``cam_to_world`` (4, 4) float64: camera -> mesh frame
  (y-up); ``image_size`` (2,) int32: (H, W);
- ``part_ids`` (K,) int16; ``part_rotation`` (K, 3, 3), ``part_translation`` (K, 3),
  ``part_scale`` (K,) float32: NPCS -> camera, ``p = s R npcs + t``; ``part_bounds``
  (K, 2, 3) float32: the part's box in NPCS;
- ``naocs_rotation`` (3, 3), ``naocs_translation`` (3,), ``naocs_scale`` () float32:
  NAOCS -> camera;
- ``joint_ids`` (J,) int16: the moving links; ``joint_parent`` (J,) int16: rigid part id of
  the parent; ``joint_type`` (J,) int8: index in ``("revolute", "prismatic",
  "cylindrical")``; ``joint_origin``, ``joint_direction`` (J, 3) float32: camera frame,
  rendered state; ``joint_origin_naocs``, ``joint_direction_naocs`` (J, 3) float32: NAOCS,
  canonical (rest) state; ``joint_translation``, ``joint_angle`` (J,) float32: the state,
  mesh units / radians; ``joint_translation_limits``, ``joint_angle_limits`` (J, 2)
  float32, NaN where the joint has no such DOF;
- ``link_ids`` (L,) int16, ``link_pose`` (L, 4, 4) float32: rest -> current, mesh frame;
- ``meta_json`` (str): JSON with ids, category, config, view (azimuth, elevation,
  distance, near, far, joint state), counts, source fingerprint.

A change of this layout bumps :data:`FRAME_VERSION` (recorded in every frame's meta), which
makes ``kinmo render`` re-render the frames of older layouts.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from kinmo.errors import KinmoDataError
from kinmo.io import atomic_write

__all__ = ["FRAME_VERSION", "frame_images", "frame_path", "load_frame", "read_frame_meta",
           "save_frame"]

#: Version of the frame file layout (stored in every frame; a change re-renders).
FRAME_VERSION = 1


def frame_path(out_dir: str | Path, key: str, frame: int) -> Path:
    """``out_dir/<key>/<frame:05d>.npz``."""
    return Path(out_dir) / key / f"{frame:05d}.npz"


def _write_npz(f: Any, arrays: dict[str, np.ndarray]) -> None:
    """``np.savez_compressed`` with zlib level 1 instead of 6: files 1-2 % larger, written
    about twice as fast (the write is a third of a frame's cost at level 6)."""
    import zipfile

    with zipfile.ZipFile(f, "w", compression=zipfile.ZIP_DEFLATED, compresslevel=1) as z:
        for k, v in arrays.items():
            with z.open(f"{k}.npy", "w", force_zip64=True) as fh:
                np.lib.format.write_array(fh, np.asanyarray(v), allow_pickle=False)


def save_frame(path: Path, arrays: dict[str, np.ndarray], meta: dict[str, Any]) -> None:
    """Write a frame file atomically: ``arrays`` plus ``meta`` as ``meta_json``.

    Parameters
    ----------
    path : Path
    arrays : dict of str to ndarray
        The arrays of the module docstring, with their dtypes.
    meta : dict
        JSON-ready metadata.
    """

    payload = dict(arrays, meta_json=np.array(json.dumps(meta)))
    atomic_write(path, lambda f: _write_npz(f, payload), mode="wb")


def read_frame_meta(path: Path) -> dict[str, Any] | None:
    """The parsed ``meta_json`` of a frame file, or None when it is missing or unreadable."""
    if not path.is_file():
        return None
    try:
        with np.load(path, allow_pickle=False) as z:
            return dict(json.loads(str(z["meta_json"])))
    except Exception:
        return None


def load_frame(path: str | Path) -> dict[str, Any]:
    """Read a frame file: its arrays plus ``meta`` (the parsed ``meta_json``).

    Raises
    ------
    KinmoDataError
        Missing, unreadable or not a kinmo frame file.
    """
    path = Path(path)
    try:
        with np.load(path, allow_pickle=False) as z:
            out: dict[str, Any] = {k: z[k] for k in z.files}
    except FileNotFoundError:
        raise KinmoDataError(path, "file is missing") from None
    except Exception as e:
        raise KinmoDataError(path, f"unreadable frame file: {type(e).__name__}: {e}") from None
    if "meta_json" not in out:
        raise KinmoDataError(path, "not a kinmo frame file (no meta_json)")
    out["meta"] = json.loads(str(out.pop("meta_json")))
    return out


def frame_images(frame: dict[str, Any]) -> tuple[np.ndarray, np.ndarray]:
    """The depth and link-label images of a loaded frame (:func:`load_frame`).

    Returns
    -------
    depth : (H, W) float32
        Metric depth (OpenCV camera z, mesh units), ``inf`` off the object.
    labels : (H, W) int16
        kinmo link id per pixel, -1 off the object.
    """
    H, W = (int(v) for v in frame["image_size"])
    depth = np.full((H, W), np.inf, dtype=np.float32)
    labels = np.full((H, W), -1, dtype=np.int16)
    r, c = frame["pixels"][:, 0].astype(np.intp), frame["pixels"][:, 1].astype(np.intp)
    depth[r, c] = frame["points"][:, 2]
    labels[r, c] = frame["link"]
    return depth, labels
