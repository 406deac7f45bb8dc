"""Partial scans of articulated objects with ANCSH ground truth (PyBullet, CPU TinyRenderer).

Liu et al. 2023 (Sec. 4.3) predict motions on partial depth scans with ANCSH (Li et al. CVPR
2020); this package renders such scans from any PartNet-Mobility-format object (real,
generated, or pseudo-labelled) through its URDF (:mod:`kinmo.urdf`):

- :mod:`kinmo.render.scene`: the object in a PyBullet DIRECT client; joint states, link
  poses, depth and link segmentation.
- :mod:`kinmo.render.camera`: viewpoints (y-up), TinyRenderer intrinsics, metric depth,
  back-projection (OpenCV camera frame).
- :mod:`kinmo.render.ancsh_gt`: NPCS, NAOCS, part poses, joints in camera and NAOCS frames.
- :mod:`kinmo.render.dataset`: the parallel, resumable ``kinmo render`` pipeline writing one
  ``.npz`` per frame and ``manifest.csv``.

Submodules import PyBullet lazily (inside functions), so importing this package is light.
"""

from kinmo.render.camera import (
    Camera,
    back_project,
    intrinsics,
    look_at,
    metric_depth,
    sample_camera,
)

__all__ = ["Camera", "back_project", "intrinsics", "look_at", "metric_depth", "sample_camera"]
