"""The report as a tree of blocks, written out by :mod:`kinmo.report.html` and
:mod:`kinmo.report.markdown`.

Both writers render the same :class:`Document`, so the HTML page and the Markdown file always
say the same thing. Text is plain (the writers escape it); a :class:`Table` cell may carry a
mark (``"better"``/``"worse"``) that the HTML page colours and the Markdown file bolds.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

__all__ = ["Block", "Document", "Figure", "Gallery", "Heading", "Note", "Section", "Table",
           "Text"]


@dataclass
class Text:
    """A paragraph of plain text; spans in backticks are shown as code."""

    text: str


@dataclass
class Heading:
    """A sub-heading inside a section (level 3 or 4)."""

    text: str
    level: int = 3


@dataclass
class Note:
    """A highlighted remark: something missing from the run, a problem, or a hint."""

    text: str
    kind: Literal["missing", "problem", "info"] = "missing"


@dataclass
class Table:
    """A table of preformatted cells.

    Attributes
    ----------
    columns : list of str
    rows : list of list of str
    align : str
        One letter per column, ``l`` or ``r`` (default: first left, the others right).
    marks : dict of (int, int) to str
        ``(row, column) -> "better" | "worse"``.
    caption : str
    bold_rows : set of int
        Rows shown in bold (the ``mean`` row).
    """

    columns: list[str]
    rows: list[list[str]]
    align: str = ""
    marks: dict[tuple[int, int], str] = field(default_factory=dict)
    caption: str = ""
    bold_rows: set[int] = field(default_factory=set)

    def alignment(self) -> str:
        """The alignment letters, one per column."""
        a = self.align or ("l" + "r" * (len(self.columns) - 1))
        return (a + "r" * len(self.columns))[: len(self.columns)]


@dataclass
class Figure:
    """A PNG image: ``name`` is its file in the report's ``img/`` folder.

    Attributes
    ----------
    name : str
        File name under ``img/`` (may contain ``/``).
    png : bytes
    alt : str
    caption : str
    width, height : int
        Pixel size (from the PNG header).
    """

    name: str
    png: bytes
    alt: str
    caption: str = ""
    width: int = 0
    height: int = 0


@dataclass
class Gallery:
    """Thumbnails in a grid, each with a caption."""

    figures: list[Figure]


Block = Text | Heading | Note | Table | Figure | Gallery


@dataclass
class Section:
    """A top-level section (one entry of the table of contents)."""

    id: str
    title: str
    blocks: list[Block] = field(default_factory=list)


@dataclass
class Document:
    """The whole report.

    Attributes
    ----------
    title : str
    meta : list of (str, str)
        Key/value lines under the title (run folder, date, kinmo version).
    sections : list of Section
    """

    title: str
    meta: list[tuple[str, str]]
    sections: list[Section]

    def figures(self) -> list[Figure]:
        """Every figure of the document, in order."""
        out: list[Figure] = []
        for s in self.sections:
            for b in s.blocks:
                if isinstance(b, Figure):
                    out.append(b)
                elif isinstance(b, Gallery):
                    out.extend(b.figures)
        return out
