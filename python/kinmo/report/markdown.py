"""Write a :class:`~kinmo.report.document.Document` as Markdown (GitHub flavour).

Images are referenced as files relative to the Markdown file (``img/<name>``), written next
to it by :func:`kinmo.report.write_report`. Table cells marked ``better``/``worse`` are set in
bold with an arrow, since Markdown has no colours.
"""

from __future__ import annotations

import html

from kinmo.data.names import clean_text
from kinmo.report.document import Document, Figure, Gallery, Heading, Note, Table, Text

__all__ = ["render_markdown"]

_NOTE_PREFIX = {"missing": "**Missing:**", "problem": "**Problem:**", "info": "**Note:**"}


def _cell(s: str) -> str:
    """A table cell or caption: no control characters, no raw HTML (``<``, ``>`` as entities:
    names of shapes and parts come from input files, issue 21 finding 10), ``|`` escaped."""
    s = clean_text(s).replace("<", "&lt;").replace(">", "&gt;")
    return s.replace("|", "\\|")


def _table(t: Table) -> list[str]:
    al = t.alignment()
    lines = ["| " + " | ".join(_cell(c) for c in t.columns) + " |",
             "|" + "|".join("---:" if a == "r" else "---" for a in al) + "|"]
    for i, row in enumerate(t.rows):
        cells = []
        for j, v in enumerate(row):
            v = _cell(v)
            mark = t.marks.get((i, j))
            if mark == "better":
                v = f"**{v}** ✓"
            elif mark == "worse":
                v = f"{v} ✗"
            elif i in t.bold_rows and v:
                v = f"**{v}**"
            cells.append(v)
        lines.append("| " + " | ".join(cells) + " |")
    if t.caption:
        lines += ["", f"*{_cell(t.caption)}*"]
    return lines + [""]


def _img(f: Figure) -> str:
    alt = _cell(f.alt).replace("[", "(").replace("]", ")")
    return f"![{alt}](img/{f.name})"


def render_markdown(doc: Document) -> str:
    """The report as Markdown text, images as ``img/<name>`` links.

    Parameters
    ----------
    doc : Document

    Returns
    -------
    str
    """
    lines = [f"# {doc.title}", ""]
    lines += [f"- **{k}**: {v}" for k, v in doc.meta] + [""]
    lines += ["Contents: " + " · ".join(f"[{s.title}](#{s.id})" for s in doc.sections), ""]
    for s in doc.sections:
        lines += [f'<a id="{s.id}"></a>', "", f"## {s.title}", ""]
        for b in s.blocks:
            if isinstance(b, Text):
                lines += [b.text, ""]
            elif isinstance(b, Heading):
                lines += ["#" * min(max(b.level, 3), 4) + " " + b.text, ""]
            elif isinstance(b, Note):
                lines += [f"> {_NOTE_PREFIX.get(b.kind, '')} {b.text}", ""]
            elif isinstance(b, Table):
                lines += _table(b)
            elif isinstance(b, Figure):
                lines += [_img(b), ""]
                if b.caption:
                    lines += [f"*{_cell(b.caption)}*", ""]
            elif isinstance(b, Gallery):
                # a table of thumbnails, four per row
                figs = b.figures
                ncol = min(4, len(figs))
                lines += ["| " + " | ".join([" "] * ncol) + " |", "|" + "---|" * ncol]
                for k in range(0, len(figs), ncol):
                    row = [f'<img src="img/{f.name}" width="220" '
                           f'alt="{html.escape(f.alt, quote=True)}"><br>{_cell(f.caption)}'
                           for f in figs[k:k + ncol]]
                    row += [""] * (ncol - len(row))
                    lines.append("| " + " | ".join(row) + " |")
                lines.append("")
            else:
                raise TypeError(f"unknown report block {type(b).__name__}")
    return "\n".join(lines).rstrip() + "\n"
