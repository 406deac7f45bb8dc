"""A folder of mesh files, one part per file (each file's meshes merged into one part).

Files are taken in sorted name order, with the suffixes of :data:`kinmo.assets.mesh.MESH_SUFFIXES`;
a symbolic link leaving the folder is skipped. A folder that holds PartNet shape folders
(:func:`kinmo.data.readers.find_shapes`) is a dataset, not an asset. The up axis is y.
"""

from __future__ import annotations

from pathlib import Path

from kinmo.assets import Part, ReadOptions, merge, register
from kinmo.assets.mesh import MESH_SUFFIXES, mesh_parts
from kinmo.data.frames import default_up
from kinmo.data.names import inside
from kinmo.data.readers import find_shapes

__all__ = ["mesh_files"]


def mesh_files(folder: Path) -> list[Path]:
    """The mesh files of ``folder`` that are parts, sorted (module docs)."""
    return sorted(p for p in folder.iterdir()
                  if p.is_file() and p.suffix.lower() in MESH_SUFFIXES and inside(p, folder))


def _accepts(path: Path) -> bool:
    return path.is_dir() and not find_shapes(path) and bool(mesh_files(path))


@register("folder", "a folder with one mesh file per part", _accepts, lambda p: default_up(""))
def read_folder(path: Path, options: ReadOptions) -> list[Part]:
    """One part per mesh file of ``path``, named after the file's stem; ``options`` unused."""
    return [merge(ps, f.stem) for f in mesh_files(path) if (ps := mesh_parts(f))]
