"""glTF 2.0 exporter (binary ``.glb``, pygltflib): a node per link, one animation per joint.

``mobility.glb`` opens in any glTF viewer (Blender, three.js, model-viewer, Windows 3D
Viewer) and plays each joint's motion as a named animation.

- Node ``<name>`` (the object) holds the link nodes as the mobility tree: node ``link_<id>``
  is translated to its frame ``a_k - a_parent`` (the joint axis origin at rest,
  :mod:`kinmo.urdf`) and carries the link's merged mesh (points relative to ``a_k``, so a
  node rotation turns the part about its axis).
- Animation ``joint_<id>`` per moving link: a ``LINEAR`` sampler over 1 s with
  :data:`KEYFRAMES` keys sweeping the joint through its range (the URDF range of
  :func:`kinmo.urdf.urdf_joints`; unlimited hinges a full turn): ``rotation`` channel for a
  hinge (quaternion about ``axis.direction``), ``translation`` for a slider (rest translation
  + ``value * direction``), both for a cylindrical joint. The joint values of the keys are in
  the animation's ``extras`` (``{"joint": ..., "values": [[translation, rotation], ...]}``,
  mesh units and radians).

glTF is y-up with metres, like kinmo's mesh frame (mesh units are written as metres).
Cannot express: joints as such (only their sampled motion; interpolating quaternions between
keys is exact for a rotation about one axis as long as keys are < 180 degrees apart, which
:data:`KEYFRAMES` ensures), limits beyond the sampled range, joint labels of fixed links.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from kinmo.export import ExportContext, register
from kinmo.io import atomic_path
from kinmo.urdf import link_frame_origins, urdf_joints

__all__ = ["KEYFRAMES", "joint_samples", "write_gltf"]

#: Keys per animation (9 keys: a full turn is sampled every 45 degrees).
KEYFRAMES = 9


def joint_samples(ctx: ExportContext) -> dict[int, np.ndarray]:
    """Joint values of every moving link's animation keys.

    Returns
    -------
    dict of int to (KEYFRAMES, 2) float64
        Link id -> ``(translation, rotation)`` per key (mesh units, radians), sweeping the
        URDF range of each degree of freedom from lower to upper.
    """

    out: dict[int, np.ndarray] = {}
    t = np.linspace(0.0, 1.0, KEYFRAMES)
    for j in urdf_joints(ctx.links, ctx.shape.path):
        if not j.is_moving:
            continue
        lo, hi = (j.lower, j.upper) if j.lower is not None else (0.0, 2 * math.pi)
        vals = out.setdefault(j.link_id, np.zeros((KEYFRAMES, 2)))
        vals[:, 0 if j.type == "prismatic" else 1] = lo + (hi - lo) * t
    return out


def _quat_xyzw(direction: np.ndarray, angle: float) -> list[float]:
    d = np.asarray(direction, dtype=np.float64)
    d = d / np.linalg.norm(d)
    s = math.sin(angle / 2)
    return [float(d[0] * s), float(d[1] * s), float(d[2] * s), math.cos(angle / 2)]


def write_gltf(ctx: ExportContext) -> list[Path]:
    """Write ``mobility.glb`` (module docs) into ``ctx.out_dir``, atomically.

    Returns
    -------
    list of Path
        ``[mobility.glb]``.

    Raises
    ------
    KinmoDataError
        Inconsistent links or unreadable meshes.
    """
    import pygltflib as g

    frames = link_frame_origins(ctx.links, ctx.shape.path)
    by_id = {l.id: l for l in ctx.links}
    blob = bytearray()
    gl = g.GLTF2(scene=0, asset=g.Asset(generator="kinmo"))

    def add(arr: np.ndarray, ctype: int, atype: str, target: int | None = None,
            minmax: bool = False) -> int:
        data = np.ascontiguousarray(arr).tobytes()
        while len(blob) % 4:
            blob.append(0)
        gl.bufferViews.append(g.BufferView(buffer=0, byteOffset=len(blob), byteLength=len(data),
                                           target=target))
        blob.extend(data)
        acc = g.Accessor(bufferView=len(gl.bufferViews) - 1, componentType=ctype,
                         count=len(arr), type=atype)
        if minmax:
            acc.min = np.asarray(arr).min(axis=0).reshape(-1).tolist()
            acc.max = np.asarray(arr).max(axis=0).reshape(-1).tolist()
        gl.accessors.append(acc)
        return len(gl.accessors) - 1

    node_of: dict[int, int] = {}
    gl.nodes.append(g.Node(name=ctx.name, children=[]))
    for link in sorted(ctx.links, key=lambda l: l.id):
        m = ctx.meshes[link.id]
        node = g.Node(name=f"link_{link.id}", children=[])
        if len(m.faces):
            pos = add((m.vertices - frames[link.id]).astype(np.float32), g.FLOAT, g.VEC3,
                      g.ARRAY_BUFFER, minmax=True)
            idx = add(m.faces.astype(np.uint32).reshape(-1), g.UNSIGNED_INT, g.SCALAR,
                      g.ELEMENT_ARRAY_BUFFER)
            gl.meshes.append(g.Mesh(name=f"link_{link.id}", primitives=[
                g.Primitive(attributes=g.Attributes(POSITION=pos), indices=idx)]))
            node.mesh = len(gl.meshes) - 1
        gl.nodes.append(node)
        node_of[link.id] = len(gl.nodes) - 1
    for link in ctx.links:
        parent_frame = frames[link.parent] if link.parent != -1 else np.zeros(3)
        node = gl.nodes[node_of[link.id]]
        node.translation = (frames[link.id] - parent_frame).tolist()
        parent_node = node_of[link.parent] if link.parent != -1 else 0
        gl.nodes[parent_node].children.append(node_of[link.id])
    times = np.linspace(0.0, 1.0, KEYFRAMES).astype(np.float32)
    for lid, vals in sorted(joint_samples(ctx).items()):
        link = by_id[lid]
        d = np.asarray(link.joint.direction, dtype=np.float64)
        d = d / np.linalg.norm(d)
        base = np.asarray(gl.nodes[node_of[lid]].translation)
        t_acc = add(times, g.FLOAT, g.SCALAR, minmax=True)
        samplers, channels = [], []
        if link.joint.type.value == "slider":
            tr = (base + vals[:, :1] * d).astype(np.float32)
            samplers.append(g.AnimationSampler(input=t_acc, output=add(tr, g.FLOAT, g.VEC3)))
            channels.append(g.AnimationChannel(sampler=len(samplers) - 1, target=g.AnimationChannelTarget(
                node=node_of[lid], path="translation")))
        if link.joint.type.value == "hinge" or link.joint.rotates:
            q = np.array([_quat_xyzw(d, a) for a in vals[:, 1]], dtype=np.float32)
            samplers.append(g.AnimationSampler(input=t_acc, output=add(q, g.FLOAT, g.VEC4)))
            channels.append(g.AnimationChannel(sampler=len(samplers) - 1, target=g.AnimationChannelTarget(
                node=node_of[lid], path="rotation")))
        gl.animations.append(g.Animation(
            name=f"joint_{lid}", samplers=samplers, channels=channels,
            extras={"joint": f"joint_{lid}", "values": vals.round(9).tolist()}))
    gl.scenes.append(g.Scene(nodes=[0]))
    gl.buffers.append(g.Buffer(byteLength=len(blob)))
    gl.set_binary_blob(bytes(blob))
    path = ctx.out_dir / "mobility.glb"
    with atomic_path(path) as tmp:
        gl.save_binary(str(tmp))
    return [path]


@register("gltf", "glTF 2.0 binary (.glb): a node per link, one animation per joint")
def _gltf(ctx: ExportContext) -> list[Path]:
    return write_gltf(ctx)
