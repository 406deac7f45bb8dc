"""One rule for names read from input files: a name is a name, never a path.

Input folders are untrusted (third-party assets, shared folders): a mesh name in
``result.json`` becomes the file name ``<name>.obj`` that readers open and writers create
(``pseudo-label`` links or copies every mesh into its output folder). A name such as
``../../victim`` would lead them outside the object folder. :func:`check_mesh_name` is applied
where names are read (:mod:`kinmo.data.readers`), so that no reader or writer downstream sees
such a name; :func:`inside` is the containment test for paths that resolve through symbolic
links.

Rules (:func:`check_mesh_name`): a non-empty string of at most :data:`MAX_NAME_BYTES` UTF-8
bytes; not ``.`` or ``..``; no path separator (``/``, ``\\``), no drive or stream colon
(``:``); no NUL or other control character (Unicode category ``Cc``).
"""

from __future__ import annotations

import os
import unicodedata
from pathlib import Path
from typing import Any

from kinmo.errors import KinmoDataError

__all__ = [
    "MAX_NAME_BYTES", "check_mesh_name", "clean_text", "clean_xml_tree", "inside", "markdown_text",
    "name_problem",
]

#: Longest accepted name, in UTF-8 bytes (file names are limited to 255 bytes; ``.obj``
#: is appended).
MAX_NAME_BYTES = 200


def name_problem(name: object) -> str | None:
    """Why ``name`` is not a safe file-name stem, or ``None`` when it is.

    Parameters
    ----------
    name : object
        A name as read from a file.

    Returns
    -------
    str or None
        One phrase (``"contains a path separator"``), or ``None``.
    """
    if not isinstance(name, str):
        return f"is not a string ({type(name).__name__})"
    if not name:
        return "is empty"
    if name in (".", ".."):
        return "is a relative folder reference"
    if "/" in name or "\\" in name:
        return "contains a path separator"
    if ":" in name:
        return "contains ':' (a drive or stream separator)"
    if any(unicodedata.category(c) == "Cc" for c in name):
        return "contains a control character"
    if len(name.encode("utf-8", "surrogatepass")) > MAX_NAME_BYTES:
        return f"is longer than {MAX_NAME_BYTES} bytes"
    return None


def check_mesh_name(name: object, file: str | Path, where: str) -> str:
    """Return ``name`` when it is a safe mesh name (module rules), else raise.

    Parameters
    ----------
    name : object
        The mesh name as read.
    file : str or Path
        The file it was read from (named in the error).
    where : str
        Where in the file (``"leaf node 12"``).

    Returns
    -------
    str
        ``name`` unchanged.

    Raises
    ------
    KinmoDataError
        ``"<file>: mesh name '<name>' of <where> <problem>: a mesh name is a file name, not
        a path"`` (the name shown with :func:`repr`, so control characters are visible).
    """
    problem = name_problem(name)
    if problem is not None:
        shown = repr(name)[:80]
        raise KinmoDataError(file, f"mesh name {shown} of {where} {problem}: a mesh name is a "
                             "file name, not a path")
    return name  # type: ignore[return-value]


def inside(path: str | Path, folder: str | Path) -> bool:
    """True when ``path``, with every symbolic link resolved, lies inside ``folder`` (also
    resolved).

    Parameters
    ----------
    path, folder : str or Path
        ``path`` need not exist (its existing prefix is resolved).

    Returns
    -------
    bool
    """
    p = Path(os.path.realpath(path))
    f = Path(os.path.realpath(folder))
    return p == f or f in p.parents


def clean_text(text: object) -> str:
    """``text`` without the characters XML 1.0 cannot hold and that garble HTML, Markdown or a
    terminal: every C0/C1 control character (tab and newline included) becomes a space, lone
    surrogates (shown as ``\\udcxx``). For every name a writer puts
    into XML (URDF, MJCF, USD), HTML (``kinmo view``, the report) or Markdown.

    Source: issue 21, finding 10 (a part name with ``\\u0001`` made ``mobility.urdf``
    ill-formed).
    """
    s = str(text)
    if s.isascii() and s.isprintable():  # nothing to replace (ASCII's non-printables are Cc)
        return s
    s = s.encode("utf-8", "backslashreplace").decode("utf-8")
    return "".join(" " if unicodedata.category(c) == "Cc" or c in "\ufffe\uffff" else c for c in s)


def clean_xml_tree(root: Any) -> Any:
    """Apply :func:`clean_text` to every attribute value, text and tail of an
    :mod:`xml.etree.ElementTree` tree (in place) and return ``root``, so the serialised file is
    well-formed whatever names the input carried (escaping of ``<``, ``&``, quotes is
    ElementTree's)."""
    for el in root.iter():
        for k, v in list(el.attrib.items()):
            el.attrib[k] = clean_text(v)
        if el.text:
            el.text = clean_text(el.text)
        if el.tail:
            el.tail = clean_text(el.tail)
    return root


def markdown_text(text: object) -> str:
    """``text`` as literal Markdown inline text: :func:`clean_text`, then Markdown and HTML
    special characters backslash- or entity-escaped (``<`` ``>`` ``&`` ``|`` ``*`` ``_`` ``[``
    ``]`` `````` ``#``), so a part name can neither start markup nor break a table."""
    s = clean_text(text).replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;")
    for c in "\\`*_[]|#":
        s = s.replace(c, "\\" + c)
    return s
