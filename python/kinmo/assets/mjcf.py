"""MJCF input (a MuJoCo model, ``.xml`` whose root is ``<mujoco>``), read through ``mujoco``.

**Parts.** One part per body with geometry, in MuJoCo's body order, named after the body
(``body_<id>`` when nameless); the world body's own geoms form a part named ``world``. A
body welded to its parent (no joint) is still its own part, as a URDF's fixed link is. Joints
are ignored (kinmo predicts them): the geometry is placed at the model's default pose
(``qpos0``; ``mj_kinematics`` gives every geom's world position ``geom_xpos`` and rotation
``geom_xmat``).

**Geometry.** A body's visual geoms (``contype = conaffinity = 0``, as robosuite and the
MuJoCo Menagerie mark them) when it has any, else all its geoms. Meshes use MuJoCo's compiled
vertices (``mesh_vert``: scaled, recentred and turned into the mesh's inertial frame, which
``geom_xpos`` / ``geom_xmat`` account for); boxes, cylinders, capsules, spheres and ellipsoids
are meshed with trimesh from ``geom_size`` (:mod:`kinmo.assets.primitives`). Planes, height
fields and SDFs are skipped (floors and terrain, not parts).

**Files.** Every file the model names is checked before MuJoCo opens any
(:func:`check_references`): the XML is parsed by :func:`kinmo.io.parse_xml` (bounded, no
entities), ``<include file>`` followed (at most :data:`MAX_FILES` files), and every
``file*`` attribute (mesh, height field, skin, include, model) and the ``<compiler>``
folders ``meshdir`` / ``texturedir`` / ``assetdir`` must be relative and stay inside the
model's folder (:mod:`kinmo.assets.refs`: ``..`` may go up within it, as Meta-World's
``../objects/meshes/...`` from ``objects/``), each file under the ``file_bytes`` limit.
Textures and materials are deleted from the parsed model (``mujoco.MjSpec``) before it is
compiled: they carry no geometry, so texture files are never opened and need not exist
(robosuite's objects name ``../textures/*.png`` beside their folder), and a material used
but defined elsewhere (robosuite's ``cabinet.xml`` expects the arena's) is no error.

The up axis is z (MuJoCo's gravity is along -z by default); units are the model's (metres by
convention).
"""

from __future__ import annotations

import os
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from kinmo import limits
from kinmo.assets import Part, ReadOptions, merge, read_xml, register, xml_root
from kinmo.assets.primitives import primitive
from kinmo.assets.refs import file_inside, reference_problem
from kinmo.errors import KinmoDataError

__all__ = ["BOUND_INERTIA", "BOUND_MASS", "MAX_FILES", "allow_massless", "check_references", "compile_mjcf", "read_mjcf"]

#: Most XML files one model may name through ``<include>`` (a cycle is refused before).
MAX_FILES = 256

_FIX = "MJCF file references are relative paths inside the model's folder"
#: The ``<compiler>`` folder each asset element's files are looked up in (``assetdir`` sets both).
_DIRS = {"mesh": "meshdir", "hfield": "meshdir", "skin": "meshdir", "texture": "texturedir"}


def _accepts(path: Path) -> bool:
    return path.is_file() and path.suffix.lower() in (".xml", ".mjcf") and xml_root(path) == "mujoco"


def _model_files(model: Path) -> list[tuple[Path, ET.Element]]:
    """The model file and every file it includes (depth first), each parsed once."""
    files: list[tuple[Path, ET.Element]] = []
    todo, seen = [model], set()
    while todo:
        path = todo.pop()
        key = path.resolve()
        if key in seen:
            raise KinmoDataError(path, "included twice (an <include> cycle?): include each file once")
        seen.add(key)
        if len(seen) > MAX_FILES:
            raise KinmoDataError(model, f"includes more than {MAX_FILES} files")
        root = read_xml(path, "mujoco", "MJCF file")
        files.append((path, root))
        todo += [_checked(model, path, "", inc.get("file", ""), "<include file>")
                 for inc in root.iter("include")]
    return files


def _checked(model: Path, source: Path, sub: str, ref: str, tag: str) -> Path:
    """``ref`` of element ``tag`` (in ``sub``, a checked ``<compiler>`` folder) under the rule,
    looked up as MuJoCo does: from the model's folder, else from the folder of the file naming
    it; both must stay inside the model's folder. Returns the first that exists (else the
    first), its size under ``file_bytes``."""
    what = f"{tag} {ref!r}" + (f" (in {sub!r})" if sub else "")
    rel = f"{sub.rstrip('/')}/{ref}" if sub and reference_problem(ref) is None else ref
    paths: list[Path] = []
    refused: KinmoDataError | None = None
    for base in dict.fromkeys([model.parent, source.parent]):  # an included file's folder too
        try:
            paths.append(file_inside(model.parent, rel, source, what, _FIX, base=base))
        except KinmoDataError as e:  # refused from here: MuJoCo may look it up from the other
            refused = refused or e
    if not paths:
        assert refused is not None
        raise refused
    path = next((p for p in paths if p.is_file()), paths[0])
    limits.check_file(path)
    return path


def check_references(model: Path) -> None:
    """Check every file ``model`` names (module docs) before MuJoCo opens any.

    Raises
    ------
    KinmoDataError
        A file or folder reference refused (absolute, ``..``, a link leaving the folder, a
        control character ...), an XML file refused or not ``<mujoco>``, a file over the
        ``file_bytes`` limit, an include cycle: names the file holding the reference.
    """
    model = Path(os.path.abspath(model))
    files = _model_files(model)
    dirs = {"meshdir": "", "texturedir": "", "assetdir": ""}
    for source, root in files:
        for compiler in root.iter("compiler"):
            for attr in dirs:
                if d := compiler.get(attr):  # empty: none
                    file_inside(model.parent, d, source, f"<compiler {attr}> {d!r}", _FIX)
                    dirs[attr] = d
    for source, root in files:
        for el in root.iter():
            sub = (dirs[_DIRS[el.tag]] or dirs["assetdir"]) if el.tag in _DIRS else ""
            for attr, ref in el.attrib.items():
                if attr.startswith("file") and el.tag not in ("include", "texture"):
                    _checked(model, source, sub, ref, f"<{el.tag} {attr}>")


def _geom_mesh(m, d, g: int) -> tuple[np.ndarray, np.ndarray] | None:
    """Geom ``g`` as a mesh in the world frame, or None for a type that is not a part."""
    import mujoco

    kind = int(m.geom_type[g])
    if kind == mujoco.mjtGeom.mjGEOM_MESH:
        k = int(m.geom_dataid[g])
        v0, nv, f0, nf = (int(x) for x in (m.mesh_vertadr[k], m.mesh_vertnum[k],
                                           m.mesh_faceadr[k], m.mesh_facenum[k]))
        v = np.asarray(m.mesh_vert[v0:v0 + nv], dtype=np.float64)
        f = np.asarray(m.mesh_face[f0:f0 + nf], dtype=np.int64)
    else:
        s = m.geom_size[g]
        sizes = {mujoco.mjtGeom.mjGEOM_BOX: ("box", 2 * s), mujoco.mjtGeom.mjGEOM_SPHERE: ("sphere", s[:1]),
                 mujoco.mjtGeom.mjGEOM_CYLINDER: ("cylinder", [s[0], 2 * s[1]]),
                 mujoco.mjtGeom.mjGEOM_CAPSULE: ("capsule", [s[0], 2 * s[1]]),
                 mujoco.mjtGeom.mjGEOM_ELLIPSOID: ("ellipsoid", s)}.get(kind)
        if sizes is None:  # plane, height field, SDF
            return None
        v, f = primitive(*sizes)
    return v @ d.geom_xmat[g].reshape(3, 3).T + d.geom_xpos[g], f


#: Least mass and inertia of a body in the compiled model (``compiler/boundmass``,
#: ``boundinertia``): object files written to be completed by their framework (LIBERO's
#: ``microwave.xml``, ``window.xml``: robosuite adds the inertials) give moving bodies no
#: mass, which MuJoCo refuses. kinmo never simulates the model, and kinematics do not depend
#: on mass.
BOUND_MASS, BOUND_INERTIA = 1e-6, 1e-9


def allow_massless(spec) -> None:
    """Let ``spec`` (a parsed ``mujoco.MjSpec``) compile with moving bodies that have no mass:
    its ``compiler/boundmass`` and ``boundinertia`` raised to :data:`BOUND_MASS` and
    :data:`BOUND_INERTIA` (larger bounds the file sets are kept). For kinmo's reader and for
    the staging of foreign assets (``bench/foreign_assets.py``) alike."""
    spec.compiler.boundmass = max(float(spec.compiler.boundmass), BOUND_MASS)
    spec.compiler.boundinertia = max(float(spec.compiler.boundinertia), BOUND_INERTIA)


def _compiled_geometry(spec):
    """``spec`` (a parsed ``mujoco.MjSpec``, no asset file opened yet) compiled without its
    looks: textures and materials deleted, and every element's ``material`` emptied. They
    carry no geometry, so texture files are neither checked nor opened (robosuite's objects
    name ``../textures/*.png`` beside their folder), and a material the file uses but does
    not define (robosuite's ``cabinet.xml`` and ``button.xml`` expect the arena's) is no
    error. A moving body without mass is no error either (:func:`allow_massless`). Returns
    the ``mujoco.MjModel``."""
    for texture in list(spec.textures):
        spec.delete(texture)
    for material in list(spec.materials):
        spec.delete(material)
    for kind in ("geoms", "sites", "skins", "tendons", "flexes"):
        for el in getattr(spec, kind, ()):
            el.material = ""
    allow_massless(spec)
    return spec.compile()


def compile_mjcf(path: str | Path):
    """The MJCF model at ``path`` compiled as kinmo reads it: every file it names checked first
    (:func:`check_references`), then parsed with ``mujoco.MjSpec`` and compiled without its
    looks (textures and materials deleted: module docs, "Files"). The one way kinmo opens an
    MJCF file: :func:`read_mjcf` and the foreign-asset evaluation's true joints
    (:func:`kinmo.evaluate.foreign.mjcf_true_joints`) both go through it.

    Returns
    -------
    mujoco.MjModel

    Raises
    ------
    KinmoDataError
        As :func:`check_references`; MuJoCo cannot compile the model (its message in one line).
    """
    import mujoco

    path = Path(path)
    check_references(path)
    try:
        return _compiled_geometry(mujoco.MjSpec.from_file(str(path)))
    except Exception as e:  # mujoco raises ValueError with a multi-line message
        raise KinmoDataError(path, f"MuJoCo cannot load the model: {' '.join(str(e).split())}") from None


def _body_name(m, b: int) -> str:
    return "world" if b == 0 else (m.body(b).name or f"body_{b}")


@register("mjcf", "an MJCF model (a body per part)", _accepts, lambda p: "z")
def read_mjcf(path: Path, options: ReadOptions) -> list[Part]:
    """One part per body with geometry (module docs); ``options`` are unused.

    Parameters
    ----------
    path : Path
        The MJCF model (root ``<mujoco>``).

    Returns
    -------
    list of Part
        Named after the bodies; vertices ``(V, 3) float64`` in the model's world frame and
        units at ``qpos0``.

    Raises
    ------
    KinmoDataError
        As :func:`check_references`; MuJoCo cannot compile the model (its message in one
        line); more bodies or triangles than the limits.
    """
    import mujoco

    m = compile_mjcf(path)
    limits.check("parts", int(m.nbody), path)
    for k in range(int(m.nmesh)):
        limits.check("triangles", int(m.mesh_facenum[k]), path)
    d = mujoco.MjData(m)
    mujoco.mj_kinematics(m, d)
    visual = (m.geom_contype == 0) & (m.geom_conaffinity == 0)
    parts: list[Part] = []
    for b in range(int(m.nbody)):
        geoms = np.flatnonzero(m.geom_bodyid == b)
        if visual[geoms].any():
            geoms = geoms[visual[geoms]]
        name = _body_name(m, b)
        pieces = [(name, *vf) for g in geoms if (vf := _geom_mesh(m, d, int(g))) is not None]
        if pieces:
            parts.append(merge(pieces, name))
    return parts
