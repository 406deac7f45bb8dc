"""ANCSH ground truth of a rendered partial scan: NPCS, NAOCS, part poses, joints.

ANCSH (Li et al. CVPR 2020, Sec. 3) represents an articulated object seen in a depth scan by

- **NPCS** (normalized part coordinate space, Sec. 3.1): every rigid part at its rest pose,
  translated and scaled so that its tight axis-aligned bounding box is centred at
  ``(0.5, 0.5, 0.5)`` with a diagonal of length 1 (so it lies in the unit cube);
- **NAOCS** (normalized articulated object coordinate space, Sec. 3.2): the whole object at
  its *canonical joint state*, normalised the same way (box centred at 0.5, unit diagonal);
- per part, the similarity NPCS -> camera, ``p_cam = scale * R @ npcs + t``; the NAOCS ->
  camera similarity; the joints' axes and states.

**Canonical joint state.** The ANCSH paper fixes one canonical state per category (e.g.
eyeglasses with their temples unfolded at 90 degrees); the reference implementation
(3dlg-hcvc/ANCSH-pytorch, ``proc_stage1`` / ``proc_stage2``) uses the URDF rest state, all
joint values 0. kinmo follows the reference implementation: the canonical state is the rest
pose, i.e. the meshes exactly as stored in the PartNet-Mobility object (doors closed, drawers
in), the state in which the part boxes are measured. It is defined for every object, also for
generated and predicted motions, and makes NAOCS a normalisation of the mesh frame (y-up).

**Rigid parts** are ANCSH's parts: links joined by ``static``, ``heavy`` or ``junk`` joints
move together and form one part (:func:`kinmo.data.labels.rigid_groups`, the convention of
:mod:`kinmo.ancsh.structure`); a part is named by the id of the link heading its group (the
root or a moving link). Boxes are measured on the mesh vertices.

Frames: rest-pose coordinates are in the mesh frame (y-up, mesh units); camera quantities in
the OpenCV camera frame (:mod:`kinmo.render.camera`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from kinmo.data.build import load_shape_meshes
from kinmo.data.labels import rigid_groups
from kinmo.data.model import Link, Shape
from kinmo.render.camera import Camera
from kinmo.render.scene import MovingJoint

__all__ = [
    "JOINT_KINDS",
    "RestGeometry",
    "frame_ground_truth",
    "link_meshes",
    "normalize_box",
    "rest_geometry",
]

#: Codes of ``joint_type`` in the frame files.
JOINT_KINDS: tuple[str, ...] = ("revolute", "prismatic", "cylindrical")

Mesh = tuple[np.ndarray, np.ndarray]


def link_meshes(shape: Shape, links: Sequence[Link] | None = None) -> dict[int, list[Mesh]]:
    """The rest-pose meshes of every link (its PartNet leaves' OBJ files).

    Parameters
    ----------
    shape : Shape
    links : sequence of Link, optional
        Default ``shape.links``.

    Returns
    -------
    dict of int to list of (vertices (V, 3) float64, faces (F, 3) int64)
        Link id -> meshes, mesh frame (y-up), mesh units.

    Raises
    ------
    KinmoDataError
        A mesh file is missing or malformed (named).
    """

    links = list(shape.links if links is None else links)
    names = {l.id: [m for pid in l.parts for m in shape.hierarchy.mesh_names(pid)] for l in links}
    flat = [shape.mesh_path(m) for l in links for m in names[l.id]]
    loaded = load_shape_meshes(flat) if flat else []
    out: dict[int, list[Mesh]] = {}
    k = 0
    for l in links:
        n = len(names[l.id])
        out[l.id] = list(loaded[k:k + n])
        k += n
    return out


def normalize_box(lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, float]:
    """Centre and scale of ANCSH's normalisation of the box ``[lo, hi]``.

    Returns
    -------
    center : (3,) float64
        Box centre.
    scale : float
        Box diagonal; ``normalized = (x - center) / scale + 0.5``. A degenerate (point) box
        gets scale 1.
    """
    lo, hi = np.asarray(lo, dtype=np.float64), np.asarray(hi, dtype=np.float64)
    scale = float(np.linalg.norm(hi - lo))
    return (lo + hi) / 2.0, scale if scale > 0 else 1.0


@dataclass(frozen=True)
class RestGeometry:
    """Rest-pose boxes of an object's rigid parts and of the whole object (mesh frame).

    Attributes
    ----------
    part_of_link : dict of int to int
        Link id -> rigid part id (the link heading its group).
    part_ids : (K,) int64
        Rigid part ids, ascending.
    part_bounds : (K, 2, 3) float64
        Min / max corner of each part's vertices at rest (a part without geometry: its frame
        origin, a point box).
    object_bounds : (2, 3) float64
        Min / max corner of all vertices at rest (the NAOCS box).
    """

    part_of_link: dict[int, int]
    part_ids: np.ndarray
    part_bounds: np.ndarray
    object_bounds: np.ndarray

    @property
    def part_center(self) -> np.ndarray:
        """(K, 3) float64 box centres."""
        return self.part_bounds.mean(axis=1)

    @property
    def part_scale(self) -> np.ndarray:
        """(K,) float64 box diagonals (1 for point boxes)."""
        return np.array([normalize_box(*b)[1] for b in self.part_bounds])

    @property
    def object_center(self) -> np.ndarray:
        """(3,) float64 centre of the NAOCS box."""
        return self.object_bounds.mean(axis=0)

    @property
    def object_scale(self) -> float:
        """Diagonal of the NAOCS box."""
        return normalize_box(*self.object_bounds)[1]

    def part_index(self, part_id: int) -> int:
        """Row of ``part_id`` in the per-part arrays."""
        return int(np.searchsorted(self.part_ids, part_id))


def rest_geometry(
    links: Sequence[Link],
    meshes: Mapping[int, Sequence[Mesh]],
    frame_origins: Mapping[int, np.ndarray] | None = None,
) -> RestGeometry:
    """Rest-pose part and object boxes from the links' meshes.

    Parameters
    ----------
    links : sequence of Link
    meshes : mapping of int to sequence of (vertices, faces)
        Link id -> rest-pose meshes (:func:`link_meshes`), mesh frame.
    frame_origins : mapping of int to (3,) float, optional
        Where to put the point box of a part without geometry (default: the origin).

    Returns
    -------
    RestGeometry

    Raises
    ------
    ValueError
        No link has any vertex.
    """
    groups = rigid_groups(list(links))
    part_ids = np.array(sorted(set(groups.values())), dtype=np.int64)
    bounds = np.empty((len(part_ids), 2, 3))
    all_lo, all_hi = np.full(3, np.inf), np.full(3, -np.inf)
    for k, pid in enumerate(part_ids):
        verts = [np.asarray(v, dtype=np.float64) for lid, g in groups.items() if g == pid
                 for v, _ in meshes.get(lid, ()) if len(v)]
        if verts:
            allv = np.concatenate(verts)
            bounds[k, 0], bounds[k, 1] = allv.min(0), allv.max(0)
            all_lo, all_hi = np.minimum(all_lo, bounds[k, 0]), np.maximum(all_hi, bounds[k, 1])
        else:
            o = np.zeros(3) if frame_origins is None else np.asarray(frame_origins[int(pid)])
            bounds[k, 0] = bounds[k, 1] = o
    if not np.isfinite(all_lo).all():
        raise ValueError("no link has any vertex")
    return RestGeometry(groups, part_ids, bounds, np.stack([all_lo, all_hi]))


def _apply(T: np.ndarray, x: np.ndarray) -> np.ndarray:
    """``x @ T[:3, :3].T + T[:3, 3]`` element-wise: no BLAS call, whose thread pool is slow
    for (N, 3) x (3, 3) products on busy machines."""
    return x[:, :1] * T[:3, 0] + x[:, 1:2] * T[:3, 1] + x[:, 2:3] * T[:3, 2] + T[:3, 3]


def frame_ground_truth(
    points: np.ndarray,
    point_links: np.ndarray,
    camera: Camera,
    link_poses: Mapping[int, np.ndarray],
    geometry: RestGeometry,
    joints: Sequence[MovingJoint],
    state: Mapping[int, tuple[float, float]],
) -> dict[str, np.ndarray]:
    """ANCSH ground truth of one rendered frame.

    Parameters
    ----------
    points : (N, 3) float
        Back-projected points, OpenCV camera frame, mesh units.
    point_links : (N,) int
        kinmo link id of each point.
    camera : Camera
        The camera that saw them (``cam_to_world``: camera -> mesh frame).
    link_poses : mapping of int to (4, 4) float
        Link id -> rest-to-current rigid motion in the mesh frame (:meth:`Scene.link_poses`).
    geometry : RestGeometry
        Rest-pose boxes.
    joints : sequence of MovingJoint
        The moving joints (rest axes in the mesh frame).
    state : mapping of int to (float, float)
        The joint state rendered: link id -> (translation, angle).

    Returns
    -------
    dict of str to ndarray
        Per point: ``part`` (N,) int64 rigid part id; ``npcs`` (N, 3) and ``naocs`` (N, 3)
        float64. Per rigid part (rows of ``part_ids`` (K,) int64): ``part_rotation``
        (K, 3, 3), ``part_translation`` (K, 3), ``part_scale`` (K,) with
        ``p_cam = scale * R @ npcs + t``; ``part_bounds`` (K, 2, 3) the part's box in NPCS.
        Object: ``naocs_rotation`` (3, 3), ``naocs_translation`` (3,), ``naocs_scale`` ()
        with ``p_cam = scale * R @ naocs + t``. Per moving joint (rows of ``joint_ids`` (J,)
        int64, the moving link): ``joint_type`` (J,) int64 (index in :data:`JOINT_KINDS`),
        ``joint_parent`` (J,) int64 (rigid part id of the parent), ``joint_origin`` /
        ``joint_direction`` (J, 3) in the camera frame at the rendered state,
        ``joint_origin_naocs`` / ``joint_direction_naocs`` (J, 3) in NAOCS (canonical state),
        ``joint_translation`` (J,) mesh units and ``joint_angle`` (J,) radians (the state),
        ``joint_translation_limits`` / ``joint_angle_limits`` (J, 2) (NaN where the joint has
        no such DOF). Links: ``link_ids`` (L,) int64 and ``link_pose`` (L, 4, 4) rest ->
        current (mesh frame).
    """
    points = np.asarray(points, dtype=np.float64)
    point_links = np.asarray(point_links)
    c2w, w2c = camera.cam_to_world, camera.world_to_cam
    centers, scales = geometry.part_center, geometry.part_scale
    oc, os_ = geometry.object_center, geometry.object_scale
    world = _apply(c2w, points)

    lids, inv = np.unique(point_links, return_inverse=True)
    inv = inv.reshape(-1)
    rest = np.empty_like(world)  # rest-pose (mesh frame) position of every point
    order = np.argsort(inv, kind="stable")
    counts = np.bincount(inv, minlength=len(lids))
    ends = np.cumsum(counts)
    for u, lid in enumerate(lids):
        idx = order[ends[u] - counts[u]:ends[u]]
        rest[idx] = _apply(np.linalg.inv(link_poses[int(lid)]), world[idx])
    part_of = np.array([geometry.part_of_link[int(l)] for l in lids], dtype=np.int64)
    part = part_of[inv] if len(lids) else np.empty(0, dtype=np.int64)
    k = np.searchsorted(geometry.part_ids, part)
    npcs = (rest - centers[k]) / scales[k][:, None] + 0.5
    naocs = (rest - oc) / os_ + 0.5

    K = len(geometry.part_ids)
    rot = np.empty((K, 3, 3))
    trans = np.empty((K, 3))
    for k, pid in enumerate(geometry.part_ids):
        M = w2c @ link_poses[int(pid)]
        rot[k] = M[:3, :3]
        trans[k] = M[:3, :3] @ (centers[k] - 0.5 * scales[k]) + M[:3, 3]
    pb = (geometry.part_bounds - centers[:, None, :]) / scales[:, None, None] + 0.5

    J = len(joints)
    jt = np.empty(J, dtype=np.int64)
    jp = np.empty(J, dtype=np.int64)
    jo, jd = np.empty((J, 3)), np.empty((J, 3))
    jon, jdn = np.empty((J, 3)), np.empty((J, 3))
    jtr, jan = np.empty(J), np.empty(J)
    jtl, jal = np.full((J, 2), np.nan), np.full((J, 2), np.nan)
    for i, j in enumerate(joints):
        jt[i] = JOINT_KINDS.index(j.kind)
        jp[i] = geometry.part_of_link[j.parent_id]
        M = w2c @ link_poses[j.parent_id]
        jo[i] = M[:3, :3] @ j.origin + M[:3, 3]
        jd[i] = M[:3, :3] @ j.direction
        jon[i] = (j.origin - oc) / os_ + 0.5
        jdn[i] = j.direction
        jtr[i], jan[i] = state.get(j.link_id, (0.0, 0.0))
        if j.translation_limits is not None:
            jtl[i] = j.translation_limits
        if j.angle_limits is not None:
            jal[i] = j.angle_limits
    lids = np.array(sorted(link_poses), dtype=np.int64)
    return {
        "part": part,
        "npcs": npcs,
        "naocs": naocs,
        "part_ids": geometry.part_ids.copy(),
        "part_rotation": rot,
        "part_translation": trans,
        "part_scale": scales.copy(),
        "part_bounds": pb,
        "naocs_rotation": w2c[:3, :3].copy(),
        "naocs_translation": w2c[:3, :3] @ (oc - 0.5 * os_) + w2c[:3, 3],
        "naocs_scale": np.float64(os_),
        "joint_ids": np.array([j.link_id for j in joints], dtype=np.int64),
        "joint_type": jt,
        "joint_parent": jp,
        "joint_origin": jo,
        "joint_direction": jd,
        "joint_origin_naocs": jon,
        "joint_direction_naocs": jdn,
        "joint_translation": jtr,
        "joint_angle": jan,
        "joint_translation_limits": jtl,
        "joint_angle_limits": jal,
        "link_ids": lids,
        "link_pose": (np.stack([link_poses[int(l)] for l in lids]) if len(lids)
                      else np.empty((0, 4, 4))),
    }
