"""Camera conventions: PyBullet matrices, metric depth, back-projection, viewpoints."""

from __future__ import annotations

import numpy as np
import pybullet as p
import pytest

from kinmo.render.camera import Camera, back_project, intrinsics, look_at, metric_depth, sample_camera


def _camera(rng: np.random.Generator, w: int = 320, h: int = 240) -> Camera:
    cam, _ = sample_camera(rng, rng.normal(size=3), 0.7, w, h, fov_y=50.0)
    return cam


def test_matrices_match_pybullet() -> None:
    rng = np.random.default_rng(0)
    for _ in range(5):
        cam = _camera(rng)
        eye = cam.cam_to_world[:3, 3]
        target = eye + cam.cam_to_world[:3, 2]
        V = p.computeViewMatrix(eye.tolist(), target.tolist(), [0, 1, 0])
        P = p.computeProjectionMatrixFOV(cam.fov_y, cam.width / cam.height, cam.near, cam.far)
        assert np.allclose(cam.view_matrix, V, atol=1e-5)  # PyBullet computes in float32
        assert np.allclose(cam.projection_matrix, P, rtol=1e-5, atol=1e-6)


def test_metric_depth_inverts_the_projection() -> None:
    cam = _camera(np.random.default_rng(1))
    P = np.asarray(cam.projection_matrix).reshape(4, 4, order="F")
    z = np.linspace(cam.near, cam.far, 50)
    clip = P @ np.stack([np.zeros_like(z), np.zeros_like(z), -z, np.ones_like(z)])  # OpenGL: -z ahead
    d = (clip[2] / clip[3] + 1.0) / 2.0  # window depth in [0, 1]
    assert d.min() == pytest.approx(0.0, abs=1e-9) and d.max() == pytest.approx(1.0, abs=1e-9)
    assert np.allclose(metric_depth(d, cam.near, cam.far), z, rtol=1e-9)


def test_back_project_inverts_projection() -> None:
    rng = np.random.default_rng(2)
    K = intrinsics(64, 48, 60.0)
    assert (K[0, 2], K[1, 2]) == (32.0, 23.0)  # TinyRenderer's principal point (measured)
    depth = rng.uniform(1.0, 3.0, size=(48, 64))
    mask = rng.random((48, 64)) > 0.3
    pts, pix = back_project(depth, K, mask)
    assert len(pts) == mask.sum()
    uvw = pts @ K.T
    assert np.allclose(uvw[:, :2] / uvw[:, 2:], pix[:, ::-1])  # (u, v) = (col, row)
    assert np.allclose(pts[:, 2], depth[mask])


def test_look_at_is_opencv() -> None:
    T = look_at(np.array([0.0, 0.0, 5.0]), np.zeros(3))
    assert np.allclose(T[:3, :3] @ T[:3, :3].T, np.eye(3)) and np.linalg.det(T[:3, :3]) > 0
    assert np.allclose(T[:3, 2], [0, 0, -1])  # z forward, towards the target
    assert np.allclose(T[:3, 1], [0, -1, 0])  # y down: image up is world +y
    with pytest.raises(ValueError):
        look_at(np.array([0.0, 3.0, 0.0]), np.zeros(3))  # looking straight down the up axis


def test_sampled_views_keep_the_object_in_view() -> None:
    rng = np.random.default_rng(3)
    center, radius = np.array([0.2, -0.1, 0.3]), 0.8
    az = []
    for _ in range(200):
        cam, view = sample_camera(rng, center, radius, 128, 96, 45.0, (10.0, 50.0), (1.0, 1.6))
        offset = cam.cam_to_world[:3, 3] - center
        el = np.degrees(np.arcsin(offset[1] / np.linalg.norm(offset)))
        assert 10.0 <= el <= 50.0 and el == pytest.approx(view["elevation_deg"])
        assert np.linalg.norm(offset) == pytest.approx(view["distance"])
        az.append(view["azimuth_deg"])
        # the bounding sphere (sampled on its surface) projects inside the image, between planes
        s = rng.normal(size=(500, 3))
        s = center + radius * s / np.linalg.norm(s, axis=1, keepdims=True)
        pc = s @ cam.world_to_cam[:3, :3].T + cam.world_to_cam[:3, 3]
        assert (pc[:, 2] > cam.near).all() and (pc[:, 2] < cam.far).all()
        uv = (pc @ cam.K.T)[:, :2] / pc[:, 2:]
        assert (uv >= -1).all() and (uv[:, 0] <= 128).all() and (uv[:, 1] <= 96).all()
        assert cam.cam_to_world[1, 1] < 0  # image up (-y camera) points up in the world
    assert np.histogram(az, bins=4, range=(0, 360))[0].min() > 30  # all around
