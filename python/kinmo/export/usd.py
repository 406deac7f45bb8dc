"""USD exporter with UsdPhysics joints (``usd-core``): for Isaac Sim / Omniverse and any USD tool.

``mobility.usd`` (binary crate) holds, under the default prim ``/<name>`` (an ``Xform`` with
``PhysicsArticulationRootAPI``):

- ``/<name>/link_<id>``: one rigid body per link (``PhysicsRigidBodyAPI``), an ``Xform``
  translated to the link frame ``a_k`` (the joint axis origin at rest, :mod:`kinmo.urdf`),
  with its merged mesh ``/<name>/link_<id>/mesh`` (``UsdGeom.Mesh``, points in the link
  frame, ``PhysicsCollisionAPI`` + ``PhysicsMeshCollisionAPI`` approximation
  ``convexDecomposition``). Bodies are siblings, not nested (the UsdPhysics convention);
- ``/<name>/joints/joint_<id>``: hinge -> ``PhysicsRevoluteJoint``, slider ->
  ``PhysicsPrismaticJoint``, with ``physics:axis = "X"`` and the joint frame rotated so that
  its X axis is the link's ``axis.direction`` (``localRot0 = localRot1``; ``localPos0 = a_k -
  a_parent``, ``localPos1 = 0``); limits: degrees for revolute (the URDF's turn-shifted range,
  none for unlimited), mesh units for prismatic. A slider that rotates (cylindrical) is a
  generic ``PhysicsJoint`` (D6) whose ``PhysicsLimitAPI`` instances free ``transX`` and
  ``rotX`` within their ranges and lock ``transY``, ``transZ``, ``rotY``, ``rotZ`` (low >
  high). Fixed labels -> ``PhysicsFixedJoint``; the root link has a fixed joint to the world
  (``body0`` empty).

Stage: ``upAxis = "Y"`` and ``metersPerUnit = 1`` (mesh units taken as metres), so the y-up
mesh frame stays as it is.

Cannot express: joint labels ``free``/``heavy``/``static``/``junk`` (all fixed joints), the
annotated turn of hinge limits, mass properties (left to the simulator: no ``MassAPI``).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from kinmo.export import ExportContext, register
from kinmo.io import atomic_path
from kinmo.urdf import link_frame_origins, urdf_joints

__all__ = ["axis_quaternion", "write_usd"]


def axis_quaternion(direction: np.ndarray) -> tuple[float, float, float, float]:
    """Unit quaternion ``(w, x, y, z)`` rotating +X onto the unit ``direction``."""
    d = np.asarray(direction, dtype=np.float64)
    d = d / np.linalg.norm(d)
    x = np.array([1.0, 0.0, 0.0])
    c = float(np.dot(x, d))
    if c < -1 + 1e-12:  # opposite: half turn about +y
        return (0.0, 0.0, 1.0, 0.0)
    v = np.cross(x, d)
    w = 1.0 + c
    n = math.sqrt(w * w + float(v @ v))
    return (w / n, float(v[0]) / n, float(v[1]) / n, float(v[2]) / n)


def write_usd(ctx: ExportContext) -> list[Path]:
    """Write ``mobility.usd`` (module docs) into ``ctx.out_dir``, atomically.

    Returns
    -------
    list of Path
        ``[mobility.usd]``.

    Raises
    ------
    KinmoDataError
        Inconsistent links or unreadable meshes.
    """
    from pxr import Gf, Sdf, Usd, UsdGeom, UsdPhysics, Vt

    joints = urdf_joints(ctx.links, ctx.shape.path)
    frames = link_frame_origins(ctx.links, ctx.shape.path)
    by_id = {l.id: l for l in ctx.links}
    root = Sdf.Path("/" + "".join(c if c.isalnum() or c == "_" else "_" for c in
                                  (ctx.name if ctx.name[:1].isalpha() else f"kinmo_{ctx.name}")))
    path = ctx.out_dir / "mobility.usd"
    with atomic_path(path) as tmp:
        tmp_usd = tmp.with_suffix(".usd")
        stage = Usd.Stage.CreateNew(str(tmp_usd))
        UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
        UsdGeom.SetStageMetersPerUnit(stage, 1.0)
        top = UsdGeom.Xform.Define(stage, root)
        stage.SetDefaultPrim(top.GetPrim())
        UsdPhysics.ArticulationRootAPI.Apply(top.GetPrim())
        UsdGeom.Scope.Define(stage, root.AppendChild("joints"))
        for link in ctx.links:
            lp = root.AppendChild(f"link_{link.id}")
            x = UsdGeom.Xform.Define(stage, lp)
            x.AddTranslateOp().Set(Gf.Vec3d(*frames[link.id].tolist()))
            UsdPhysics.RigidBodyAPI.Apply(x.GetPrim())
            m = ctx.meshes[link.id]
            if len(m.faces):
                mesh = UsdGeom.Mesh.Define(stage, lp.AppendChild("mesh"))
                mesh.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(
                    (m.vertices - frames[link.id]).astype(np.float32)))
                mesh.CreateFaceVertexCountsAttr(Vt.IntArray.FromNumpy(
                    np.full(len(m.faces), 3, dtype=np.int32)))
                mesh.CreateFaceVertexIndicesAttr(Vt.IntArray.FromNumpy(
                    m.faces.astype(np.int32).reshape(-1)))
                mesh.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
                UsdPhysics.CollisionAPI.Apply(mesh.GetPrim())
                UsdPhysics.MeshCollisionAPI.Apply(mesh.GetPrim()).CreateApproximationAttr(
                    UsdPhysics.Tokens.convexDecomposition)
        for j in joints:
            if j.child.endswith("_helper"):
                continue
            link = by_id[j.link_id]
            jp = root.AppendChild("joints").AppendChild(f"joint_{link.id}")
            body1 = root.AppendChild(f"link_{link.id}")
            helper = j.parent.endswith("_helper")
            if not j.is_moving:
                joint = UsdPhysics.FixedJoint.Define(stage, jp)
            elif helper:
                joint = UsdPhysics.Joint.Define(stage, jp)
                slide = next(k for k in joints if k.child == j.parent)
                for dof, lo, hi in (("transX", slide.lower, slide.upper),
                                    ("rotX", None if j.lower is None else math.degrees(j.lower),
                                     None if j.upper is None else math.degrees(j.upper)),
                                    ("transY", 1.0, -1.0), ("transZ", 1.0, -1.0),
                                    ("rotY", 1.0, -1.0), ("rotZ", 1.0, -1.0)):
                    if lo is None:
                        continue
                    lim = UsdPhysics.LimitAPI.Apply(joint.GetPrim(), dof)
                    lim.CreateLowAttr(float(lo))
                    lim.CreateHighAttr(float(hi))
            elif j.type == "prismatic":
                joint = UsdPhysics.PrismaticJoint.Define(stage, jp)
                joint.CreateAxisAttr("X")
                joint.CreateLowerLimitAttr(float(j.lower))
                joint.CreateUpperLimitAttr(float(j.upper))
            else:
                joint = UsdPhysics.RevoluteJoint.Define(stage, jp)
                joint.CreateAxisAttr("X")
                if j.lower is not None:
                    joint.CreateLowerLimitAttr(math.degrees(j.lower))
                    joint.CreateUpperLimitAttr(math.degrees(j.upper))
            if link.parent != -1:
                joint.CreateBody0Rel().SetTargets([root.AppendChild(f"link_{link.parent}")])
                p0 = frames[link.id] - frames[link.parent]
            else:
                p0 = frames[link.id]
            joint.CreateBody1Rel().SetTargets([body1])
            q = (1.0, 0.0, 0.0, 0.0)
            if j.is_moving:
                q = axis_quaternion(j.axis)
            joint.CreateLocalPos0Attr(Gf.Vec3f(*p0.tolist()))
            joint.CreateLocalRot0Attr(Gf.Quatf(*q))
            joint.CreateLocalPos1Attr(Gf.Vec3f(0.0, 0.0, 0.0))
            joint.CreateLocalRot1Attr(Gf.Quatf(*q))
        stage.GetRootLayer().Save()
        tmp_usd.replace(tmp)
    return [path]


@register("usd", "USD with UsdPhysics joints (Isaac Sim, Omniverse): one rigid body per link")
def _usd(ctx: ExportContext) -> list[Path]:
    return write_usd(ctx)
