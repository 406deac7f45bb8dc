"""An articulated object loaded in PyBullet (DIRECT, CPU TinyRenderer) from its URDF.

:class:`Scene` writes the object's URDF (:func:`kinmo.urdf.urdf_string`, from real, generated
or predicted ``mobility_v2.json`` links), loads it with a fixed base in its own PyBullet
``DIRECT`` client, sets joint states, reports link poses and renders depth and link
segmentation with the CPU TinyRenderer (no GPU, no display).

Frames: the world frame is the object's mesh frame (y-up, mesh units). A joint state maps
each moving link id to ``(translation, angle)``: mesh units along ``+direction`` and radians
about ``+direction`` (right-hand rule), 0 being the rest pose (meshes as stored); a hinge
uses the angle, a slider the translation, a cylindrical joint both.
"""

from __future__ import annotations

import math
import os
import sys
import tempfile
import threading
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from kinmo.data.model import Link, Shape
from kinmo.errors import KinmoDataError
from kinmo.render.camera import Camera, metric_depth
from kinmo.urdf import UrdfJoint, link_frame_origins, urdf_joints, urdf_string

__all__ = ["JointState", "MovingJoint", "Scene", "pybullet_module", "sample_joint_state"]

_IMPORT_LOCK = threading.Lock()


def pybullet_module():
    """The ``pybullet`` module, imported without its banner.

    PyBullet's C module writes ``pybullet build time: ...`` to the process's standard error
    (file descriptor 2) when it is first imported: one line per process, so a log of
    ``kinmo train all`` or ``kinmo demo`` got two for every rendering or Table 2 stage (its
    worker processes). The first import here sends file descriptor 2 to ``os.devnull`` for
    the import's duration; later calls return the module. Where descriptor 2 cannot be
    duplicated, the import is a plain one.

    Returns
    -------
    module
        ``pybullet``.

    Raises
    ------
    ImportError
        PyBullet is not installed.
    """
    if "pybullet" in sys.modules:
        return sys.modules["pybullet"]
    with _IMPORT_LOCK:
        try:
            sys.stderr.flush()
            saved = os.dup(2)
        except (OSError, ValueError, AttributeError):  # no descriptor 2 (a detached process)
            import pybullet

            return pybullet
        try:
            null = os.open(os.devnull, os.O_WRONLY)
            try:
                os.dup2(null, 2)
                import pybullet
            finally:
                os.close(null)
        finally:
            os.dup2(saved, 2)
            os.close(saved)
    return pybullet

#: ``link id -> (translation, angle)`` (mesh units, radians).
JointState = dict[int, tuple[float, float]]


@dataclass(frozen=True)
class MovingJoint:
    """The degrees of freedom of one moving link, as loaded in PyBullet.

    Attributes
    ----------
    link_id : int
        The kinmo link it moves.
    kind : str
        ``"revolute"``, ``"prismatic"`` or ``"cylindrical"``.
    origin, direction : (3,) float64
        Axis in the mesh frame at the rest pose (``direction`` unit length).
    translation_limits, angle_limits : (float, float) or None
        Sampling ranges: mesh units / radians, ``None`` when the joint has no such DOF.
        Unlimited rotations give ``(-pi, pi)``.
    prismatic_index, revolute_index : int or None
        PyBullet joint indices of the two DOFs.
    parent_id : int
        Parent link id (the axis moves with it).
    """

    link_id: int
    kind: str
    origin: np.ndarray
    direction: np.ndarray
    translation_limits: tuple[float, float] | None
    angle_limits: tuple[float, float] | None
    prismatic_index: int | None
    revolute_index: int | None
    parent_id: int


def _limits(j: UrdfJoint) -> tuple[float, float]:
    if j.type == "continuous":
        return (-math.pi, math.pi)
    return (float(j.lower), float(j.upper))  # type: ignore[arg-type]


class Scene:
    """One articulated object in a private PyBullet DIRECT client.

    Parameters
    ----------
    shape : Shape
        The object (hierarchy and meshes).
    links : sequence of Link, optional
        Its kinematic links; default ``shape.links`` (``mobility_v2.json``).

    Attributes
    ----------
    links : list of Link
    link_index : dict of int to int
        kinmo link id -> PyBullet link index (segmentation and ``getLinkState``).
    joints : list of MovingJoint
        The moving links in ascending id.
    frame_origins : dict of int to (3,) float64
        Rest-pose position of each link frame (:func:`kinmo.urdf.link_frame_origins`).

    Raises
    ------
    KinmoDataError
        No links, inconsistent links, or PyBullet cannot load the URDF (e.g. unreadable mesh).

    Notes
    -----
    Use as a context manager, or call :meth:`close`, to free the PyBullet client.
    """

    def __init__(self, shape: Shape, links: Sequence[Link] | None = None) -> None:
        p = pybullet_module()
        self._p = p
        self.shape = shape
        links = list(shape.links if links is None else links)
        if not links:
            raise KinmoDataError(shape.path, "no kinematic links to render (a PartNet shape "
                                             "needs links, e.g. predicted motions)")
        self.links = sorted(links, key=lambda l: l.id)
        self.parent = {l.id: l.parent for l in self.links}
        self.urdf_joints = urdf_joints(self.links, shape.path)
        self.frame_origins = link_frame_origins(self.links, shape.path)
        text = urdf_string(shape, self.links, mesh_root=Path(shape.mesh_dir).resolve())
        self.client = p.connect(p.DIRECT)
        try:
            with tempfile.TemporaryDirectory(prefix="kinmo-urdf-") as tmp:
                path = Path(tmp) / f"{shape.id}.urdf"
                path.write_text(text, encoding="utf-8")
                try:
                    self.body = p.loadURDF(str(path), useFixedBase=True,
                                           physicsClientId=self.client)
                except p.error as e:
                    raise KinmoDataError(
                        shape.path, f"PyBullet cannot load the URDF: {e}") from None
            self._index_joints()
        except BaseException:
            p.disconnect(self.client)
            raise

    def _index_joints(self) -> None:
        p, c = self._p, self.client
        by_name: dict[str, int] = {}
        self.link_index = {}
        for i in range(p.getNumJoints(self.body, physicsClientId=c)):
            info = p.getJointInfo(self.body, i, physicsClientId=c)
            by_name[info[1].decode()] = i
            child = info[12].decode()
            if child.startswith("link_") and not child.endswith("_helper"):
                self.link_index[int(child[5:])] = i
        # segmentation slot (PyBullet link index + 1) -> kinmo link id, -1 for the base / helpers
        n = p.getNumJoints(self.body, physicsClientId=c)
        self._seg_lut = np.full(n + 1, -1, dtype=np.int32)
        for lid, idx in self.link_index.items():
            self._seg_lut[idx + 1] = lid
        self.joints: list[MovingJoint] = []
        specs = [j for j in self.urdf_joints if j.is_moving]
        for lid in sorted({j.link_id for j in specs}):
            js = [j for j in specs if j.link_id == lid]
            pri = next((j for j in js if j.type == "prismatic"), None)
            rev = next((j for j in js if j.type in ("revolute", "continuous")), None)
            kind = "cylindrical" if pri and rev else ("prismatic" if pri else "revolute")
            link = next(l for l in self.links if l.id == lid)
            self.joints.append(MovingJoint(
                link_id=lid,
                kind=kind,
                origin=np.asarray(link.joint.origin, dtype=np.float64),
                direction=(pri or rev).axis,  # type: ignore[union-attr]
                translation_limits=_limits(pri) if pri else None,
                angle_limits=_limits(rev) if rev else None,
                prismatic_index=by_name[pri.name] if pri else None,
                revolute_index=by_name[rev.name] if rev else None,
                parent_id=link.parent,
            ))

    # ------------------------------------------------------------------------- state

    def set_state(self, state: Mapping[int, tuple[float, float]]) -> None:
        """Set joint values; moving links absent from ``state`` go to the rest pose (0).

        Parameters
        ----------
        state : mapping of int to (float, float)
            Link id -> (translation in mesh units, angle in radians). Values outside the
            limits are applied as given.

        Raises
        ------
        KeyError
            A link id in ``state`` is not a moving link.
        """
        p, c = self._p, self.client
        moving = {j.link_id for j in self.joints}
        bad = set(state) - moving
        if bad:
            raise KeyError(f"not moving links: {sorted(bad)}")
        for j in self.joints:
            t, a = state.get(j.link_id, (0.0, 0.0))
            if j.prismatic_index is not None:
                p.resetJointState(self.body, j.prismatic_index, float(t), physicsClientId=c)
            if j.revolute_index is not None:
                p.resetJointState(self.body, j.revolute_index, float(a), physicsClientId=c)

    def link_poses(self) -> dict[int, np.ndarray]:
        """Rigid motion of every link from its rest pose to the current state.

        Returns
        -------
        dict of int to (4, 4) float64
            Link id -> ``T`` with ``x_now = T @ x_rest`` for points of the link in the world
            (mesh) frame; the identity at the rest pose. Read from PyBullet's forward
            kinematics (``getLinkState``, URDF link frame) composed with the link frame's rest
            offset.
        """
        p, c = self._p, self.client
        out: dict[int, np.ndarray] = {}
        for lid, idx in self.link_index.items():
            st = p.getLinkState(self.body, idx, computeForwardKinematics=True, physicsClientId=c)
            T = np.eye(4)
            T[:3, :3] = np.asarray(p.getMatrixFromQuaternion(st[5]), dtype=np.float64).reshape(3, 3)
            T[:3, 3] = st[4]
            T[:3, 3] -= T[:3, :3] @ self.frame_origins[lid]
            out[lid] = T
        return out

    # ------------------------------------------------------------------------ render

    def render(
        self, camera: Camera, segmentation: bool = True
    ) -> tuple[np.ndarray, np.ndarray | None]:
        """Render metric depth and the link segmentation with the CPU TinyRenderer.

        Parameters
        ----------
        camera : Camera
        segmentation : bool
            Also compute the segmentation pass (``ER_SEGMENTATION_MASK_OBJECT_AND_LINKINDEX``);
            False skips it (``ER_NO_SEGMENTATION_MASK``, faster).

        Returns
        -------
        depth : (H, W) float64
            Metric depth along the optical axis (OpenCV camera z), mesh units; ``inf`` where
            nothing is hit.
        labels : (H, W) int32 or None
            kinmo link id per pixel, -1 for the background (None without segmentation).
        """
        p, c = self._p, self.client
        flags = (p.ER_SEGMENTATION_MASK_OBJECT_AND_LINKINDEX if segmentation
                 else p.ER_NO_SEGMENTATION_MASK)
        _, _, _, depth_buf, seg = p.getCameraImage(
            camera.width, camera.height, camera.view_matrix, camera.projection_matrix,
            renderer=p.ER_TINY_RENDERER, flags=flags, physicsClientId=c,
        )
        buf = np.asarray(depth_buf, dtype=np.float64).reshape(camera.height, camera.width)
        depth = metric_depth(buf, camera.near, camera.far)
        if not segmentation:
            depth[buf >= 1.0] = np.inf
            return depth, None
        seg = np.asarray(seg, dtype=np.int64).reshape(camera.height, camera.width)
        # value = body + ((link index + 1) << 24), -1 for the background
        hit = (seg >= 0) & ((seg & ((1 << 24) - 1)) == self.body)
        slot = np.where(hit, seg >> 24, 0)  # link index + 1; 0: base / background
        labels = self._seg_lut[np.clip(slot, 0, len(self._seg_lut) - 1)]
        labels[~hit] = -1
        depth[labels < 0] = np.inf
        return depth, labels

    # ---------------------------------------------------------------------- lifetime

    def close(self) -> None:
        """Disconnect the PyBullet client (idempotent)."""
        if getattr(self, "client", None) is not None:
            try:
                self._p.disconnect(self.client)
            except self._p.error:
                pass
            self.client = None  # type: ignore[assignment]

    def __enter__(self) -> Scene:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __del__(self) -> None:  # pragma: no cover - best effort
        try:
            self.close()
        except Exception:
            pass


def sample_joint_state(joints: Sequence[MovingJoint], rng: np.random.Generator,
                       turn_cylindrical: bool = True) -> JointState:
    """A random joint state, uniform within each joint's limits.

    Parameters
    ----------
    joints : sequence of MovingJoint
        In the order the random numbers are drawn (translation then angle per joint).
    rng : numpy.random.Generator
    turn_cylindrical : bool
        False holds every cylindrical joint at its rest angle (0) and draws only its
        translation, the prismatic view of it that ANCSH takes
        (:func:`kinmo.ancsh.structure.object_parts`). The angle is still drawn and dropped,
        so the random stream, and every other joint's state, are the same either way.

    Returns
    -------
    JointState
        Link id -> (translation in mesh units, angle in radians); 0 for a DOF the joint does
        not have. Unlimited rotations are drawn in [-pi, pi).
    """
    out: JointState = {}
    for j in joints:
        t = float(rng.uniform(*j.translation_limits)) if j.translation_limits else 0.0
        a = float(rng.uniform(*j.angle_limits)) if j.angle_limits else 0.0
        if j.kind == "cylindrical" and not turn_cylindrical:
            a = 0.0
        out[j.link_id] = (t, a)
    return out
