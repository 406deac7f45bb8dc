"""Exporters of articulated objects: one module per format behind one registry.

Every exporter takes an object in kinmo's model (a :class:`~kinmo.data.model.Shape`: part
hierarchy and meshes, plus its :class:`~kinmo.data.model.Link` list: real, generated or
predicted motion, Liu et al. 2023 Sec. 3) and writes one format into an output folder.
``kinmo predict``, ``kinmo pseudo-label`` (``--format``, repeatable) and ``kinmo export``
all go through :func:`export`, so a format added here is available to all three.

========================  ==================  ============================================
format                    files               loaded back by (tests)
========================  ==================  ============================================
``mobility_v2``           mobility_v2.json    :func:`kinmo.data.readers.read_links`
``semantics``             semantics.txt       (text)
``urdf``                  mobility.urdf,      PyBullet; :func:`kinmo.export.urdf.read_urdf`
                          collision/          gives the links back losslessly
                          link_<id>_<k>.obj
``mjcf``                  mobility.xml,       MuJoCo (``mujoco.MjModel.from_xml_path``)
                          meshes/*.stl
``usd``                   mobility.usd        ``pxr`` (UsdPhysics joints)
``gltf``                  mobility.glb        pygltflib / trimesh (one animation per joint)
========================  ==================  ============================================

What each format cannot express is documented in its module (:mod:`kinmo.export.urdf`,
:mod:`kinmo.export.mjcf`, :mod:`kinmo.export.usd`, :mod:`kinmo.export.gltf`).

Frames: every exporter keeps kinmo's mesh frame (y-up, mesh units) as its world frame; link
frames sit on their joint axes at the rest pose (all joint values 0), as in
:mod:`kinmo.urdf`.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Any

from kinmo.data.model import Link, Shape
from kinmo.data.names import inside
from kinmo.data.readers import read_links, read_shape
from kinmo.errors import KinmoDataError
from kinmo.export.collision import DEFAULT_COLLISION, check_collision_method
from kinmo.export.kinematics import link_meshes
from kinmo.io import check_outputs_apart, link_or_copy, output_dir, staged_folder

__all__ = [
    "DEFAULT_FORMATS",
    "ExportContext",
    "Exporter",
    "EXPORTERS",
    "export",
    "export_folder",
    "formats",
    "register",
]


@dataclass
class ExportContext:
    """What an exporter gets: the object, its links, where to write, shared lazy data.

    Attributes
    ----------
    shape : Shape
        Hierarchy and meshes (``shape.mesh_dir``).
    links : list of Link
        The motion to export (axes in the mesh frame, hinge limits in degrees).
    out_dir : Path
        Output folder (created).
    name : str
        Object / robot name written into the files.
    progress : bool
        Exporters may show a progress bar (convex decomposition of objects of many links);
        False under ``-q``.
    collision : str
        How collision geometry is made: a method of :mod:`kinmo.export.collision`.
    named_meshes : mapping of str to (vertices, faces), or a callable returning one, optional
        The shape's meshes by name when the caller reads them (:class:`kinmo.data.build.MeshesOnce`:
        called on first use only); otherwise read here, once, on first use.
    """

    shape: Shape
    links: list[Link]
    out_dir: Path
    name: str
    progress: bool = True
    collision: str = DEFAULT_COLLISION
    named_meshes: Mapping[str, tuple[Any, Any]] | Callable[[], Mapping[str, tuple[Any, Any]]] | None = None

    @cached_property
    def meshes(self):
        """Per-link merged meshes (:func:`kinmo.export.kinematics.link_meshes`), loaded once."""

        named = self.named_meshes() if callable(self.named_meshes) else self.named_meshes
        return link_meshes(self.shape, self.links, named)


@dataclass(frozen=True)
class Exporter:
    """One registered format.

    Attributes
    ----------
    name : str
        Format name used on the command line (``--format NAME``).
    description : str
        One line for ``--help``.
    write : callable
        ``write(ctx: ExportContext) -> list[Path]``: writes the files, returns their paths.
    """

    name: str
    description: str
    write: Callable[[ExportContext], list[Path]] = field(repr=False)


#: Format name -> exporter, in registration order.
EXPORTERS: dict[str, Exporter] = {}
#: What ``kinmo predict`` and ``kinmo pseudo-label`` write without ``--format``.
DEFAULT_FORMATS: tuple[str, ...] = ("mobility_v2", "semantics", "urdf")


def register(name: str, description: str) -> Callable:
    """Decorator registering ``write(ctx) -> list[Path]`` as format ``name``."""

    def deco(fn: Callable[[ExportContext], list[Path]]):
        EXPORTERS[name] = Exporter(name, description, fn)
        return fn

    return deco


#: The format modules of kinmo, imported (so registered) on first use, in this order.
_MODULES: tuple[str, ...] = ("partnet", "urdf", "mjcf", "usd", "gltf")


def _load_all() -> None:
    import importlib

    for m in _MODULES:  # importing a format module registers it
        importlib.import_module(f"kinmo.export.{m}")


def formats() -> list[str]:
    """Names of all registered formats: kinmo's own in a fixed order, then any added later."""
    _load_all()
    own = ["mobility_v2", "semantics", "urdf", "mjcf", "usd", "gltf"]
    return [f for f in own if f in EXPORTERS] + [f for f in EXPORTERS if f not in own]


def export(shape: Shape, out_dir: str | Path, fmts: Iterable[str] = DEFAULT_FORMATS,
           links: Sequence[Link] | None = None, name: str | None = None,
           progress: bool = True, collision: str = DEFAULT_COLLISION,
           meshes: Mapping[str, tuple[Any, Any]] | Callable[[], Mapping[str, tuple[Any, Any]]] | None = None,
           ) -> dict[str, list[Path]]:
    """Write ``shape`` moving as ``links`` in each of ``fmts`` into ``out_dir``.

    Parameters
    ----------
    shape : Shape
    out_dir : str or Path
        Created if needed.
    fmts : iterable of str
        Registered format names (:func:`formats`), written in the order given (duplicates
        once).
    links : sequence of Link, optional
        Default ``shape.links``.
    name : str, optional
        Object name in the files; default the shape id.
    progress : bool
        Show the exporters' progress bars (:attr:`ExportContext.progress`).
    collision : str
        Collision geometry of URDF and MJCF: a method of :mod:`kinmo.export.collision`
        (``hull``, ``vhacd``, ``coacd``).
    meshes : mapping of str to (vertices (V, 3) float64, faces (F, 3) int64), optional
        ``shape``'s meshes by name when the caller reads them (one read per shape and
        command), or a callable returning them (called only when a format needs geometry);
        read from ``shape.mesh_dir`` when not given.

    Returns
    -------
    dict of str to list of Path
        Format -> files written.

    Raises
    ------
    KinmoDataError
        An unknown format, no links, ``out_dir`` is a file, or a problem of the object
        (message names the folder).
    """
    _load_all()
    check_collision_method(collision)
    fmts = list(dict.fromkeys(fmts))
    bad = [f for f in fmts if f not in EXPORTERS]
    if bad:
        raise KinmoDataError(out_dir, f"unknown export format(s) {', '.join(bad)}; known: "
                                      f"{', '.join(EXPORTERS)}")
    links = list(shape.links or [] if links is None else links)
    if not links:
        raise KinmoDataError(shape.path, "no kinematic links to export (mobility_v2.json or "
                                         "predicted motion needed)")

    out_dir = output_dir(out_dir)
    ctx = ExportContext(self_contained(shape, out_dir), links, out_dir, name or shape.id, progress,
                        collision, meshes)
    return {f: EXPORTERS[f].write(ctx) for f in fmts}


def self_contained(shape: Shape, out_dir: Path) -> Shape:
    """``shape`` with its meshes inside ``out_dir``: every leaf mesh hard-linked (or copied)
    to ``out_dir/textured_objs/<name>.obj`` unless the mesh folder already lies inside
    ``out_dir``, so every path the formats write is relative inside the object folder and the
    folder can be moved, zipped or sent (issue 21, finding 11). Mesh names were checked when
    the hierarchy was read (:mod:`kinmo.data.names`).

    Returns
    -------
    Shape
        A copy whose ``mesh_dir`` is ``out_dir/textured_objs`` (or ``shape`` itself).
    """
    import dataclasses


    if inside(shape.mesh_dir, out_dir):
        return shape
    dest = out_dir / "textured_objs"
    for node in shape.hierarchy.nodes.values():
        for o in node.objs:
            link_or_copy(shape.mesh_path(o), dest / f"{o}.obj")
    return dataclasses.replace(shape, mesh_dir=dest)


def export_folder(src: str | Path, out: str | Path, fmts: Iterable[str],
                  source: str | Path | None = None, collision: str = DEFAULT_COLLISION,
                  progress: bool = True) -> dict[str, list[Path]]:
    """Export a PartNet-Mobility-format folder (real, generated or predicted) to ``out``.

    The leaf meshes are hard-linked or copied into ``out/textured_objs`` (:func:`self_contained`):
    every mesh reference is relative inside ``out``.

    Parameters
    ----------
    src : str or Path
        A PartNet-Mobility folder; or a folder with only ``mobility_v2.json`` (a ``kinmo
        predict`` output) whose shape folder (hierarchy, meshes) is ``source`` or named in
        ``src/source.txt`` (:func:`kinmo.view.write_view_links`).
    out : str or Path
    fmts : iterable of str
    source : str or Path, optional
    collision : str
        Collision geometry method (:mod:`kinmo.export.collision`).
    progress : bool
        Show the exporters' progress bars.

    Raises
    ------
    KinmoDataError
        ``src`` is not a readable PartNet-Mobility folder (no ``mobility_v2.json``), or
        without meshes and no ``source``, or as :func:`export`.
    KinmoUsageError
        ``out`` is, lies inside or holds ``src`` or ``source`` (outputs never overwrite
        inputs).
    """

    src = Path(src)
    if source is None and (src / "source.txt").is_file():
        source = (src / "source.txt").read_text(encoding="utf-8").strip()
    check_outputs_apart(out, [src, *([source] if source is not None else [])])
    if source is not None:
        shape = read_shape(source)
        if not (src / "mobility_v2.json").is_file():
            raise KinmoDataError(src / "mobility_v2.json", "file is missing")
        return _staged(shape, out, fmts, read_links(src / "mobility_v2.json", shape.hierarchy),
                       collision, progress)
    if not any((src / n).is_file() for n in ("result.json", "result_after_merging.json")) \
            and (src / "mobility_v2.json").is_file():
        raise KinmoDataError(src, "links without meshes (a `kinmo predict` output?): give the "
                                  "shape folder they were predicted for with --source")
    shape = read_shape(src)
    if not shape.links:
        raise KinmoDataError(src, "not a PartNet-Mobility folder: mobility_v2.json is missing")
    return _staged(shape, out, fmts, None, collision, progress)


def _staged(shape: Shape, out: str | Path, fmts: Iterable[str], links: Sequence[Link] | None,
            collision: str = DEFAULT_COLLISION, progress: bool = True) -> dict[str, list[Path]]:
    """:func:`export` into a temporary sibling of ``out`` that appears at ``out`` whole
    (:func:`kinmo.io.staged_folder`); the returned paths are those under ``out``."""

    out = Path(out)
    with staged_folder(out) as tmp:
        files = export(shape, tmp, fmts, links=links, progress=progress, collision=collision)
    return {f: [out / p.relative_to(tmp) for p in ps] for f, ps in files.items()}
