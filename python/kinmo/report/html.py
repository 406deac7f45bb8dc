"""Write a :class:`~kinmo.report.document.Document` as one self-contained HTML page.

Every image is inlined as a base64 ``data:image/png`` URI and the style sheet and script are
embedded, so ``index.html`` is a single file that can be mailed or archived and opens in any
browser without the ``img/`` folder. A small script checks, once the page has loaded, that
every image decoded: it sets ``data-images-loaded`` and ``data-images-total`` on ``<body>``
(read by the tests through a headless browser) and outlines broken images in red. Clicking a
gallery image toggles it to full width.
"""

from __future__ import annotations

import base64
import html
import re

from kinmo.report.document import Document, Figure, Gallery, Heading, Note, Section, Table, Text

__all__ = ["render_html"]

_CSS = """
:root { --fg:#1f2328; --muted:#59636e; --line:#d1d9e0; --bg:#ffffff; --soft:#f6f8fa;
        --good:#1a7f37; --goodbg:#dafbe1; --bad:#cf222e; --badbg:#ffebe9; --accent:#0969da; }
* { box-sizing: border-box; }
body { font: 15px/1.5 -apple-system, "Segoe UI", Helvetica, Arial, sans-serif; color: var(--fg);
       background: var(--bg); margin: 0; }
header { background: #24292f; color: #fff; padding: 18px 32px; }
header h1 { margin: 0 0 4px; font-size: 22px; }
header dl { margin: 0; display: flex; flex-wrap: wrap; gap: 4px 24px; font-size: 13px;
            color: #c9d1d9; }
header dt { display: inline; font-weight: 600; } header dd { display: inline; margin: 0 0 0 6px; }
nav { padding: 8px 32px; background: var(--soft); border-bottom: 1px solid var(--line);
      position: sticky; top: 0; z-index: 2; }
nav a { margin-right: 18px; color: var(--accent); text-decoration: none; font-size: 14px; }
nav a.missing { color: var(--muted); text-decoration: line-through; }
main { padding: 8px 32px 48px; max-width: 1400px; }
section { margin-top: 28px; }
h2 { border-bottom: 1px solid var(--line); padding-bottom: 4px; font-size: 20px; }
h3 { font-size: 16px; margin: 22px 0 6px; font-family: ui-monospace, Menlo, monospace; }
h4 { font-size: 14px; margin: 16px 0 4px; }
code { font: 13px ui-monospace, Menlo, monospace; background: var(--soft); padding: 1px 4px;
       border-radius: 4px; }
.table-wrap { overflow-x: auto; margin: 6px 0 14px; }
table { border-collapse: collapse; font-size: 13px; }
th, td { border: 1px solid var(--line); padding: 4px 9px; white-space: nowrap; }
th { background: var(--soft); font-weight: 600; white-space: normal; min-width: 60px;
     max-width: 150px; vertical-align: bottom; }
td.l { white-space: normal; max-width: 720px; }
td.r, th.r { text-align: right; font-variant-numeric: tabular-nums; }
tr.bold td { font-weight: 700; background: #fbfbfc; }
td.better { color: var(--good); background: var(--goodbg); }
td.worse { color: var(--bad); background: var(--badbg); }
caption { caption-side: bottom; text-align: left; color: var(--muted); font-size: 12px;
          padding-top: 4px; white-space: normal; }
.note { border-left: 4px solid; padding: 6px 12px; margin: 8px 0; border-radius: 4px;
        font-size: 14px; }
.note.missing { border-color: #bf8700; background: #fff8c5; }
.note.problem { border-color: var(--bad); background: var(--badbg); }
.note.info { border-color: var(--accent); background: #ddf4ff; }
figure { margin: 10px 0 18px; }
figure img { max-width: 100%; height: auto; border: 1px solid var(--line); border-radius: 4px; }
figcaption { color: var(--muted); font-size: 12px; }
.gallery { display: grid; grid-template-columns: repeat(auto-fill, minmax(230px, 1fr));
           gap: 12px; }
.gallery figure { margin: 0; }
.gallery img { width: 100%; cursor: zoom-in; background: #fff; }
.gallery figure.zoom { grid-column: 1 / -1; }
.gallery figure.zoom img { width: auto; max-width: 100%; cursor: zoom-out; }
img.broken { outline: 3px solid var(--bad); }
footer { color: var(--muted); font-size: 12px; padding: 0 32px 24px; }
"""

_JS = """
window.addEventListener('load', function () {
  var imgs = document.getElementsByTagName('img'), ok = 0;
  for (var i = 0; i < imgs.length; i++) {
    if (imgs[i].complete && imgs[i].naturalWidth > 0) { ok++; }
    else { imgs[i].classList.add('broken'); }
  }
  document.body.setAttribute('data-images-total', String(imgs.length));
  document.body.setAttribute('data-images-loaded', String(ok));
});
document.addEventListener('click', function (e) {
  var f = e.target.closest && e.target.closest('.gallery figure');
  if (f) { f.classList.toggle('zoom'); }
});
"""


def _text(s: str) -> str:
    """Escape plain text; spans in backticks become ``<code>``."""
    return re.sub(r"`([^`]+)`", r"<code>\1</code>", html.escape(s))


def _data_uri(png: bytes) -> str:
    return "data:image/png;base64," + base64.b64encode(png).decode("ascii")


def _img(f: Figure) -> str:
    size = f' width="{f.width}" height="{f.height}"' if f.width and f.height else ""
    return f'<img src="{_data_uri(f.png)}" alt="{html.escape(f.alt, quote=True)}"{size}>'


def _table(t: Table) -> str:
    al = t.alignment()
    out = ['<div class="table-wrap"><table>']
    if t.caption:
        out.append(f"<caption>{_text(t.caption)}</caption>")
    out.append("<thead><tr>" + "".join(
        f'<th class="{"r" if a == "r" else "l"}">{_text(c)}</th>' for c, a in zip(t.columns, al))
        + "</tr></thead><tbody>")
    for i, row in enumerate(t.rows):
        cls = ' class="bold"' if i in t.bold_rows else ""
        cells = []
        for j, (v, a) in enumerate(zip(row, al)):
            c = ["r" if a == "r" else "l"]
            if (i, j) in t.marks:
                c.append(t.marks[(i, j)])
            cells.append(f'<td class="{" ".join(c)}">{_text(v)}</td>')
        out.append(f"<tr{cls}>" + "".join(cells) + "</tr>")
    out.append("</tbody></table></div>")
    return "\n".join(out)


def _block(b) -> str:
    if isinstance(b, Text):
        return f"<p>{_text(b.text)}</p>"
    if isinstance(b, Heading):
        lv = min(max(b.level, 3), 4)
        return f"<h{lv}>{_text(b.text)}</h{lv}>"
    if isinstance(b, Note):
        return f'<div class="note {b.kind}">{_text(b.text)}</div>'
    if isinstance(b, Table):
        return _table(b)
    if isinstance(b, Figure):
        cap = f"<figcaption>{_text(b.caption)}</figcaption>" if b.caption else ""
        return f"<figure>{_img(b)}{cap}</figure>"
    if isinstance(b, Gallery):
        items = [f"<figure>{_img(f)}<figcaption>{_text(f.caption)}</figcaption></figure>"
                 for f in b.figures]
        return '<div class="gallery">' + "\n".join(items) + "</div>"
    raise TypeError(f"unknown report block {type(b).__name__}")


def _section_missing(s: Section) -> bool:
    return all(isinstance(b, (Text, Note)) for b in s.blocks) and any(
        isinstance(b, Note) and b.kind == "missing" for b in s.blocks)


def render_html(doc: Document) -> str:
    """The report as a self-contained HTML page (module docstring).

    Parameters
    ----------
    doc : Document

    Returns
    -------
    str
        The page, UTF-8 text.
    """
    meta = "".join(f"<div><dt>{_text(k)}</dt><dd>{_text(v)}</dd></div>" for k, v in doc.meta)
    nav = "".join(
        f'<a href="#{s.id}"{" class=missing" if _section_missing(s) else ""}>{_text(s.title)}</a>'
        for s in doc.sections)
    body = []
    for s in doc.sections:
        body.append(f'<section id="{s.id}"><h2>{_text(s.title)}</h2>')
        body += [_block(b) for b in s.blocks]
        body.append("</section>")
    return "\n".join([
        "<!DOCTYPE html>",
        '<html lang="en"><head><meta charset="utf-8">',
        '<meta name="viewport" content="width=device-width, initial-scale=1">',
        '<meta name="generator" content="kinmo report">',
        f"<title>{_text(doc.title)}</title>",
        f"<style>{_CSS}</style>",
        f"<script>{_JS}</script>",
        "</head><body>",
        f"<header><h1>{_text(doc.title)}</h1><dl>{meta}</dl></header>",
        f"<nav>{nav}</nav>",
        "<main>", *body, "</main>",
        "<footer>Self-contained page: every image is embedded. Paper: Liu et al., "
        "Semi-Weakly Supervised Object Kinematic Motion Prediction, CVPR 2023.</footer>",
        "</body></html>", "",
    ])
