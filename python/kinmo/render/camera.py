"""Cameras for rendering partial scans: viewpoints, intrinsics, depth and back-projection.

Partial depth scans of articulated objects are the input of ANCSH (Li et al. CVPR 2020,
Sec. 4), the last stage of Liu et al. 2023 (Sec. 4.3, motion prediction on partial scans).

Conventions
-----------
- **World frame** = the object's mesh frame (y-up, mesh units): the URDF base is fixed at the
  identity (:mod:`kinmo.urdf`).
- **Camera frame: OpenCV** (x right, y down, z forward, into the scene). ``cam_to_world``
  (4x4, float64) maps camera-frame points to the world frame. The OpenGL camera frame
  (x right, y up, z backward) used by PyBullet's view matrix is ``diag(1, -1, -1)`` of it.
- **Pixels**: ``(u, v)`` = (column, row), row 0 at the top of the image, integer coordinates
  at the pixel samples.
- **Intrinsics** ``K = [[f, 0, cx], [0, f, cy], [0, 0, 1]]`` with ``f = H / (2 tan(fov_y / 2))``
  (square pixels) and the principal point of PyBullet's CPU TinyRenderer, **measured**:
  ``cx = W / 2``, ``cy = H / 2 - 1`` (TinyRenderer samples pixel ``(u, v)`` at NDC
  ``x = 2u/W - 1``, ``y = 1 - 2(v + 1)/H``; with this principal point back-projected depth
  pixels lie on the meshes to 1e-7 of the object size, against 2e-3 with the textbook
  ``(W - 1)/2, (H - 1)/2``). These intrinsics hold for ``ER_TINY_RENDERER`` only.
- **Depth**: PyBullet returns the OpenGL depth buffer ``d`` in [0, 1], non-linear in
  distance; the metric depth along the optical axis (the camera-frame z, mesh units) is
  ``z = far * near / (far - (far - near) * d)`` (:func:`metric_depth`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = [
    "Camera",
    "UP",
    "back_project",
    "intrinsics",
    "look_at",
    "metric_depth",
    "sample_camera",
]

#: World up axis (PartNet meshes are y-up).
UP = np.array([0.0, 1.0, 0.0])
_CV_TO_GL = np.diag([1.0, -1.0, -1.0])


def intrinsics(width: int, height: int, fov_y_deg: float) -> np.ndarray:
    """Pinhole intrinsics of PyBullet's TinyRenderer image (OpenCV convention).

    Parameters
    ----------
    width, height : int
        Image size in pixels.
    fov_y_deg : float
        Vertical field of view in degrees (PyBullet's ``computeProjectionMatrixFOV``), in (0, 180).

    Returns
    -------
    K : (3, 3) float64
        ``[[f, 0, W/2], [0, f, H/2 - 1], [0, 0, 1]]`` with ``f = H / (2 tan(fov_y/2))`` pixels
        (see the module docs for the measured principal point).

    Raises
    ------
    ValueError
        Non-positive size or a field of view outside (0, 180).
    """
    if width < 1 or height < 1:
        raise ValueError(f"image size must be positive, got {width}x{height}")
    if not 0.0 < fov_y_deg < 180.0:
        raise ValueError(f"fov_y_deg must be in (0, 180), got {fov_y_deg}")
    f = height / (2.0 * math.tan(math.radians(fov_y_deg) / 2.0))
    return np.array([[f, 0.0, width / 2.0], [0.0, f, height / 2.0 - 1.0], [0.0, 0.0, 1.0]])


def look_at(eye: np.ndarray, target: np.ndarray, up: np.ndarray = UP) -> np.ndarray:
    """OpenCV camera-to-world pose of a camera at ``eye`` looking at ``target``.

    Parameters
    ----------
    eye, target : (3,) float
        World frame (mesh frame), mesh units.
    up : (3,) float
        World up direction; the image's "up" (-y of the camera) is its projection. Default +y.

    Returns
    -------
    cam_to_world : (4, 4) float64
        Columns of the rotation: camera x (right), y (down), z (forward) in the world frame.

    Raises
    ------
    ValueError
        ``eye == target`` or viewing direction parallel to ``up``.
    """
    eye = np.asarray(eye, dtype=np.float64)
    target = np.asarray(target, dtype=np.float64)
    z = target - eye
    n = np.linalg.norm(z)
    if n < 1e-12:
        raise ValueError("eye and target coincide")
    z /= n
    x = np.cross(z, np.asarray(up, dtype=np.float64))
    nx = np.linalg.norm(x)
    if nx < 1e-9:
        raise ValueError("viewing direction is parallel to the up vector")
    x /= nx
    y = np.cross(z, x)
    T = np.eye(4)
    T[:3, 0], T[:3, 1], T[:3, 2], T[:3, 3] = x, y, z, eye
    return T


@dataclass(frozen=True)
class Camera:
    """A pinhole camera for PyBullet's TinyRenderer.

    Attributes
    ----------
    width, height : int
        Image size in pixels.
    fov_y : float
        Vertical field of view, degrees.
    near, far : float
        Clipping planes, mesh units (distances along the optical axis).
    cam_to_world : (4, 4) float64
        OpenCV camera frame -> world (mesh) frame.
    """

    width: int
    height: int
    fov_y: float
    near: float
    far: float
    cam_to_world: np.ndarray

    @property
    def K(self) -> np.ndarray:
        """(3, 3) float64 intrinsics (:func:`intrinsics`)."""
        return intrinsics(self.width, self.height, self.fov_y)

    @property
    def world_to_cam(self) -> np.ndarray:
        """(4, 4) float64 world -> OpenCV camera frame."""
        R, t = self.cam_to_world[:3, :3], self.cam_to_world[:3, 3]
        T = np.eye(4)
        T[:3, :3] = R.T
        T[:3, 3] = -R.T @ t
        return T

    @property
    def view_matrix(self) -> list[float]:
        """PyBullet view matrix: world -> OpenGL camera, 16 floats column-major."""
        V = self.world_to_cam.copy()
        V[:3] = _CV_TO_GL @ V[:3]
        return V.flatten(order="F").tolist()

    @property
    def projection_matrix(self) -> list[float]:
        """PyBullet (OpenGL) projection matrix, 16 floats column-major."""
        f = 1.0 / math.tan(math.radians(self.fov_y) / 2.0)
        a = self.width / self.height
        n, fa = self.near, self.far
        P = np.zeros((4, 4))
        P[0, 0], P[1, 1] = f / a, f
        P[2, 2], P[2, 3] = (fa + n) / (n - fa), 2.0 * fa * n / (n - fa)
        P[3, 2] = -1.0
        return P.flatten(order="F").tolist()


def sample_camera(
    rng: np.random.Generator,
    center: np.ndarray,
    radius: float,
    width: int = 256,
    height: int = 256,
    fov_y: float = 45.0,
    elevation_deg: tuple[float, float] = (10.0, 50.0),
    distance_factor: tuple[float, float] = (1.1, 1.6),
) -> tuple[Camera, dict[str, float]]:
    """A random viewpoint around an object, looking at its centre.

    The azimuth is uniform all around the vertical (+y) axis, measured in the horizontal x-z
    plane from +z towards +x; the elevation above the horizontal plane is uniform in
    ``elevation_deg``; the distance is ``distance_factor`` (uniform) times the distance at
    which the bounding sphere just fits the vertical field of view,
    ``radius / sin(fov_y / 2)``, so the whole object is always in view and its image size does
    not depend on its size. Near and far planes hug the bounding sphere (depth precision).

    Parameters
    ----------
    rng : numpy.random.Generator
        Source of the three random numbers (azimuth, elevation, distance, in that order).
    center : (3,) float
        Centre of the object's bounding sphere, world (mesh) frame.
    radius : float
        Its radius, mesh units, > 0.
    width, height : int
        Image size, pixels.
    fov_y : float
        Vertical field of view, degrees.
    elevation_deg : (float, float)
        Elevation range in degrees, within (-90, 90).
    distance_factor : (float, float)
        Distance range in units of ``radius / sin(fov_y / 2)``; the lower bound must be >= 1.

    Returns
    -------
    camera : Camera
    view : dict
        ``azimuth_deg``, ``elevation_deg``, ``distance`` (mesh units).

    Raises
    ------
    ValueError
        Non-positive radius, bad ranges.
    """
    if not radius > 0:
        raise ValueError(f"radius must be > 0, got {radius}")
    lo, hi = elevation_deg
    if not -90.0 < lo <= hi < 90.0:
        raise ValueError(f"elevation range must be within (-90, 90), got {elevation_deg}")
    dlo, dhi = distance_factor
    if not 1.0 <= dlo <= dhi:
        raise ValueError(f"distance_factor must satisfy 1 <= lo <= hi, got {distance_factor}")
    center = np.asarray(center, dtype=np.float64)
    az = rng.uniform(0.0, 360.0)
    el = rng.uniform(lo, hi)
    fit = radius / math.sin(math.radians(fov_y) / 2.0)
    dist = fit * rng.uniform(dlo, dhi)
    a, e = math.radians(az), math.radians(el)
    eye = center + dist * np.array(
        [math.cos(e) * math.sin(a), math.sin(e), math.cos(e) * math.cos(a)])
    cam = Camera(
        width=width,
        height=height,
        fov_y=fov_y,
        near=max(dist - 1.05 * radius, 1e-3 * dist),
        far=dist + 1.05 * radius,
        cam_to_world=look_at(eye, center, UP),
    )
    return cam, {"azimuth_deg": az, "elevation_deg": el, "distance": dist}


def metric_depth(depth_buffer: np.ndarray, near: float, far: float) -> np.ndarray:
    """Metric depth (camera z, mesh units) from PyBullet's non-linear depth buffer.

    Parameters
    ----------
    depth_buffer : (H, W) float
        OpenGL depth in [0, 1] (1 = far plane / background).
    near, far : float
        The projection's clipping planes.

    Returns
    -------
    (H, W) float64
        ``far * near / (far - (far - near) * d)``; background pixels give ``far``.
    """
    d = np.asarray(depth_buffer, dtype=np.float64)
    return far * near / (far - (far - near) * d)


def back_project(
    depth: np.ndarray, K: np.ndarray, mask: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Back-project a metric depth image to a point cloud in the OpenCV camera frame.

    Parameters
    ----------
    depth : (H, W) float
        Metric depth (camera z), mesh units.
    K : (3, 3) float
        Intrinsics (OpenCV, integer pixel coordinates at the samples).
    mask : (H, W) bool, optional
        Pixels to keep (default: all with finite, positive depth).

    Returns
    -------
    points : (N, 3) float64
        ``((u - cx) z / fx, (v - cy) z / fy, z)``, camera frame, mesh units, in row-major
        pixel order.
    pixels : (N, 2) int64
        ``(v, u)`` = (row, column) of each point.
    """
    depth = np.asarray(depth, dtype=np.float64)
    if mask is None:
        mask = np.isfinite(depth) & (depth > 0)
    v, u = np.nonzero(mask)
    z = depth[v, u]
    x = (u - K[0, 2]) * z / K[0, 0]
    y = (v - K[1, 2]) * z / K[1, 1]
    return np.stack([x, y, z], axis=1), np.stack([v, u], axis=1).astype(np.int64)
