"""Files named inside an input file (URDF meshes, ``package://`` names, MJCF includes and
assets): the containment rule, applied before any library opens them (issue 21; issue 36).

A reference is text from an untrusted file, never a path as given. It is accepted when:

- it is relative, with ``/`` (or ``\\``) separated pieces that are plain names
  (:func:`kinmo.data.names.name_problem`: no ``:``, no control characters; empty and
  ``.`` pieces are skipped) or ``..``;
- joined to the folder it is relative to, with its ``..`` pieces folded in (lexically), it
  lies inside its root folder: ``..`` may go up within the root, never above it
  (``../meshes/door.stl`` from ``pkg/urdf/`` inside the package ``pkg``; Meta-World's
  ``../objects/meshes/...`` from ``objects/``), and is refused as "climbs out with '..'"
  otherwise;
- with every symbolic link resolved, it still lies inside that root
  (:func:`kinmo.data.names.inside`).

The root is the input file's folder (a URDF inside a ROS package: the package's folder,
:func:`enclosing_package`), or for ``package://NAME/rest`` the package NAME's folder
(:func:`package_root`).
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

from kinmo.data.names import inside, name_problem
from kinmo.errors import KinmoDataError
from kinmo.io import parse_xml

__all__ = ["enclosing_package", "file_inside", "package_root", "reference_problem"]


def reference_problem(ref: str) -> str | None:
    """Why the relative file reference ``ref`` is refused on its own, or None (module rule;
    where its ``..`` pieces lead and symbolic links are checked by :func:`file_inside`)."""
    if not ref:
        return "is empty"
    pieces = ref.replace("\\", "/").split("/")
    if ref.startswith(("/", "\\")) or Path(ref).is_absolute():
        return "is an absolute path"
    for p in pieces:
        if p not in ("", ".", "..") and (problem := name_problem(p)) is not None:
            return f"has a piece that {problem}"
    return None


def file_inside(root: Path, ref: str, source: Path, what: str, fix: str, base: Path | None = None) -> Path:
    """``base / ref`` once the rule holds (module docs); it need not exist. Both ways of
    reading its ``..`` pieces must stay inside ``root``: folded in lexically, and as the file
    system follows it (each symbolic link resolved before the ``..`` after it).

    Parameters
    ----------
    root : Path
        The folder the reference must stay inside.
    ref : str
        The reference, relative to ``base``.
    source : Path
        The input file it was read from (named in the error).
    what : str
        What holds it, with the reference as written shown literally (``"link 'door': mesh
        'package://cab/x.obj'"``).
    fix : str
        The rule in words, told with the error (``"mesh paths stay inside the URDF's folder"``).
    base : Path, optional
        The folder ``ref`` is relative to, inside ``root`` (default: ``root``).

    Raises
    ------
    KinmoDataError
        ``"<source>: <what> refused: it <problem> (<fix>)"``.
    """
    problem = reference_problem(ref)
    start = root if base is None else base
    folded = Path(os.path.abspath(Path(start) / ref.replace("\\", "/")))  # '..' folded lexically
    top = Path(os.path.abspath(root))
    if problem is None and not (folded == top or top in folded.parents):
        problem = "climbs out with '..'"
    path = Path(start) / ref.replace("\\", "/")  # as a library opens it: links, then '..'
    if problem is None and not inside(path, root):
        problem = "leads outside through a symbolic link"
    if problem is not None:
        raise KinmoDataError(source, f"{what} refused: it {problem} ({fix})")
    return path


def _package_name(folder: Path) -> str | None:
    """The ``<name>`` of ``folder/package.xml``, or None (absent or unreadable: not a package)."""
    if not (folder / "package.xml").is_file():
        return None
    try:
        el = parse_xml(folder / "package.xml").getroot().find("name")
    except KinmoDataError:
        return None
    return None if el is None or el.text is None else el.text.strip()


def enclosing_package(source: Path) -> Path | None:
    """The folder of the ROS package holding ``source``: the nearest folder above it with a
    readable ``package.xml`` that has a ``<name>``, or None."""
    for folder in Path(os.path.abspath(source)).parents:
        if _package_name(folder):
            return folder
    return None


def package_root(name: str, source: Path, package_path: Sequence[Path] = ()) -> Path | None:
    """The folder of the ROS package ``name`` for ``package://name/...`` in ``source``.

    Looked for, in order: the nearest folder above ``source`` holding a ``package.xml`` whose
    ``<name>`` is ``name`` (as a ROS workspace lays packages out); then ``DIR/name`` for each
    ``DIR`` of ``package_path`` (``--package-path``). ``name`` must be a plain name
    (:func:`kinmo.data.names.name_problem`), checked by the caller.

    Returns
    -------
    Path or None
        The package folder, or None when neither holds it.
    """
    for folder in Path(os.path.abspath(source)).parents:
        if _package_name(folder) == name:
            return folder
    for d in package_path:
        if (Path(d) / name).is_dir():
            return Path(d) / name
    return None
