"""Readers of a user's own assets (``kinmo predict FILE``): one module per input format behind
one registry, as :mod:`kinmo.export` is for the formats kinmo writes.

kinmo predicts motion over a *part hierarchy* (Liu et al. 2023, Sec. 3.1); a user's asset
gives the parts, each read here into a :data:`Part` in the asset's own frame and units.
:mod:`kinmo.user_input` stages the parts as a PartNet folder and predicts.

=================  ==========================  ==========================================
reader (module)    input                       parts
=================  ==========================  ==========================================
``mesh``           ``.glb`` / ``.gltf`` scene  one per scene node with a mesh (node
(:mod:`.mesh`)                                 transforms applied)
                   ``.obj`` with ``o`` / ``g`` one per object / group (trimesh's
                                               ``split_objects`` / ``split_groups``)
                   ``.stl`` ``.ply`` ``.off``  one per mesh in the file
``folder``         a folder of mesh files      one per file, each merged into one part
(:mod:`.folder`)
``urdf``           ``.urdf`` (or ``.xml``      one per link with geometry, at the rest
(:mod:`.urdf`)     whose root is ``<robot>``)  pose: meshes (``package://`` resolved) and
                                               box / cylinder / sphere / capsule
``mjcf``           ``.xml`` whose root is      one per body with geometry, at the model's
(:mod:`.mjcf`)     ``<mujoco>`` (MuJoCo)       default pose; the world's own geoms: ``world``
=================  ==========================  ==========================================

Up axes (:func:`asset_up`, :mod:`kinmo.data.frames`): glTF, OBJ and mesh folders are y-up;
URDF (ROS REP 103) and MJCF (MuJoCo's gravity along -z) are z-up; a URDF that kinmo wrote is
y-up. Files named inside an input (meshes, ``package://``, MJCF includes) must stay inside
their root (:mod:`kinmo.assets.refs`, ``docs/security.md``).
"""

from __future__ import annotations

import importlib
import re
import xml.etree.ElementTree as ET
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from kinmo import limits
from kinmo.data.frames import UpAxis
from kinmo.errors import KinmoDataError
from kinmo.io import parse_xml

__all__ = [
    "NEEDS",
    "Part",
    "READERS",
    "ReadOptions",
    "Reader",
    "asset_up",
    "is_user_input",
    "merge",
    "read_parts",
    "read_xml",
    "reader_for",
    "register",
    "xml_root",
]

Part = tuple[str, np.ndarray, np.ndarray]
"""A part: ``(name, vertices (V, 3) float64, faces (F, 3) int64)`` in the asset's frame and
units (every transform of the file applied). ``name`` is literal text from the file."""

#: What kinmo needs, said by every "not enough parts" error.
NEEDS = ("kinmo needs the object split into its parts (at least 2): a GLB/glTF scene with one "
         "node per part, an OBJ with one 'o'/'g' group per part, a folder with one mesh file per "
         "part, a URDF with one link per part, or an MJCF model with one body per part")


@dataclass(frozen=True)
class ReadOptions:
    """What the user says about an asset beyond the file itself.

    Attributes
    ----------
    package_path : tuple of Path
        Folders holding ROS packages by name (``--package-path DIR``): ``package://NAME/...``
        may resolve to ``DIR/NAME`` (:func:`kinmo.assets.refs.package_root`).
    """

    package_path: tuple[Path, ...] = ()


@dataclass(frozen=True)
class Reader:
    """One registered input format.

    Attributes
    ----------
    name : str
        Format name (``"urdf"``).
    description : str
        One line for documentation and errors.
    accepts : callable
        ``accepts(path: Path) -> bool``: whether this reader reads ``path`` (cheap: a suffix,
        a folder listing, the first bytes of an XML file).
    read : callable
        ``read(path: Path, options: ReadOptions) -> list[Part]``; raises
        :class:`~kinmo.errors.KinmoDataError` naming the file, the problem and the fix.
    up : callable
        ``up(path: Path) -> "y" | "z"``: the up axis the format declares.
    """

    name: str
    description: str
    accepts: Callable[[Path], bool] = field(repr=False)
    read: Callable[[Path, ReadOptions], list[Part]] = field(repr=False)
    up: Callable[[Path], UpAxis] = field(repr=False)


#: Format name -> reader: kinmo's formats in :data:`_MODULES`' order, then formats registered
#: later in their registration order (the first that accepts a path reads it). The order does
#: not depend on which format module was imported first.
READERS: dict[str, Reader] = {}

#: The format modules of kinmo, imported (so registered) on first use, in this order.
_MODULES: tuple[str, ...] = ("mesh", "folder", "urdf", "mjcf")


def register(name: str, description: str, accepts: Callable[[Path], bool],
             up: Callable[[Path], UpAxis]) -> Callable:
    """Decorator registering ``read(path, options) -> list[Part]`` as format ``name``."""

    def deco(fn: Callable[[Path, ReadOptions], list[Part]]):
        READERS[name] = Reader(name, description, accepts, fn, up)
        rank = {m: k for k, m in enumerate(_MODULES)}
        ordered = sorted(READERS.items(), key=lambda kv: rank.get(kv[0], len(rank)))  # stable
        READERS.clear()
        READERS.update(ordered)
        return fn

    return deco


def _load_all() -> None:
    for m in _MODULES:  # importing a format module registers it
        importlib.import_module(f"kinmo.assets.{m}")


def reader_for(path: str | Path) -> Reader | None:
    """The reader of ``path`` (the first registered that accepts it), or None."""
    _load_all()
    path = Path(path)
    return next((r for r in READERS.values() if r.accepts(path)), None)


def is_user_input(path: str | Path) -> bool:
    """True for a file or folder some reader accepts: a mesh, URDF or MJCF file, or a folder of
    mesh files that holds no PartNet shape folder."""
    return reader_for(path) is not None


#: Bytes of an XML file read to find its root element (:func:`xml_root`).
XML_HEAD_BYTES = 65536


def xml_root(path: Path) -> str | None:
    """The tag of the root element of the XML file ``path`` (``"mujoco"``, ``"robot"``), from
    its first :data:`XML_HEAD_BYTES` bytes without parsing; None when not found there or not
    readable (the reader that parses the file names any problem)."""
    try:
        with open(path, "rb") as fh:
            head = fh.read(XML_HEAD_BYTES).decode("utf-8", "replace")
    except OSError:
        return None
    head = re.sub(r"<\?.*?\?>|<!--.*?-->", "", head, flags=re.S)
    m = re.search(r"<\s*([A-Za-z_][\w.-]*)", head)
    return m.group(1) if m else None


def read_xml(path: Path, tag: str, kind: str) -> ET.Element:
    """The root element of the XML file ``path``, which must be ``<tag>`` (parsed by
    :func:`kinmo.io.parse_xml`: bounded, no document type, no entities).

    Raises
    ------
    KinmoDataError
        ``"not a readable <kind>: <why>"`` or ``"not a <kind>: its root element is <x>, not <tag>"``.
    """
    try:
        root = parse_xml(path).getroot()
    except KinmoDataError as e:
        raise KinmoDataError(path, f"not a readable {kind}: {e.problem}") from None
    if root.tag != tag:
        raise KinmoDataError(path, f"not a {kind}: its root element is <{root.tag}>, not <{tag}>")
    return root


def merge(parts: Sequence[Part], name: str) -> Part:
    """``parts`` as one part named ``name`` (vertices stacked, face indices shifted)."""
    vs, fs, n = [], [], 0
    for _, v, f in parts:
        vs.append(v)
        fs.append(f + n)
        n += len(v)
    return name, np.concatenate(vs), np.concatenate(fs)


def read_parts(path: str | Path, options: ReadOptions | None = None) -> list[Part]:
    """The parts of a user's asset (module table: which input gives which parts).

    Parameters
    ----------
    path : str or Path
        ``.glb``/``.gltf``, ``.obj``, ``.stl``/``.ply``/``.off``, ``.urdf``, an MJCF ``.xml``
        or a folder of mesh files.
    options : ReadOptions, optional
        ``--package-path`` folders for URDF ``package://`` names.

    Returns
    -------
    list of Part
        In input order (scene nodes, sorted file names, URDF link order, MJCF body order);
        vertices ``(V, 3) float64`` in the asset's frame and units, faces ``(F, 3) int64``.

    Raises
    ------
    KinmoDataError
        Unknown kind, unreadable file, a file reference refused or missing, more parts than
        the ``parts`` limit, or fewer than two parts (the message says what kinmo needs).
    """
    path = Path(path)
    reader = reader_for(path)
    if reader is None:
        if not path.exists():
            raise KinmoDataError(path, "no such file or folder")
        kind = "folder without mesh files" if path.is_dir() else repr(path.suffix.lower() or "(none)")
        raise KinmoDataError(path, f"unknown input kind {kind} (an .xml file must be MJCF, root "
                                   f"<mujoco>, or URDF, root <robot>); {NEEDS}")
    parts = reader.read(path, options or ReadOptions())
    limits.check("parts", len(parts), path)
    if len(parts) < 2:
        raise KinmoDataError(path, f"found {len(parts)} part(s): an unsegmented mesh; {NEEDS}")
    return parts


def asset_up(path: str | Path) -> UpAxis:
    """The up axis ``path`` declares by its format (module docs): ``"y"`` for glTF, OBJ, mesh
    folders and URDFs kinmo wrote, ``"z"`` for URDF (ROS REP 103) and MJCF; ``"y"`` for what
    no reader accepts (:func:`read_parts` names the problem)."""
    reader = reader_for(path)
    return "y" if reader is None else reader.up(Path(path))
