"""Run reports (``kinmo report RUN``): one HTML page and one Markdown file per run.

:func:`write_report` finds the artefacts of a run folder (:mod:`kinmo.report.collect`),
composes the report (:mod:`kinmo.report.build`, its Table 1/2 sections in
:mod:`kinmo.report.paper_tables`: paper Table 1 and Table 2 next to the
paper's means, bar charts per category, training curves, pseudo-label summary, predictions,
gallery of renders) and writes, into ``RUN/report`` by default:

- ``index.html``: self-contained (every image inlined as a base64 data URI, style and script
  embedded), so the single file can be mailed or archived (:mod:`kinmo.report.html`);
- ``report.md``: the same content in Markdown, images referenced as ``img/<name>.png``
  (:mod:`kinmo.report.markdown`);
- ``viewer.html``: when the run's evaluation wrote predicted links of its test shapes
  (``eval/.../viewers/<model>/<id>/``, :func:`kinmo.view.write_view_links`), one
  interactive viewer per test shape (:func:`kinmo.view.gallery_page`: a slider per joint,
  moving parts coloured, predicted axes solid, true ones dashed), linked from the gallery;
- ``img/``: the charts and the copied gallery images; images an earlier report wrote and
  this one does not are removed (listed in ``img/.kinmo-report-images``; no other file is
  ever deleted).

A partial run gives a partial report that says what is missing; only a run folder that does
not exist is an error. All files are written atomically (:mod:`kinmo.io`).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

__all__ = ["MANIFEST", "ReportResult", "write_report"]

#: File in ``img/`` listing the images the last report wrote: only those are ever removed.
MANIFEST = ".kinmo-report-images"


@dataclass
class ReportResult:
    """What :func:`write_report` wrote.

    Attributes
    ----------
    out : Path
        The report folder.
    html, markdown : Path
        ``index.html`` and ``report.md``.
    images : list of Path
        PNG files under ``out/img``.
    found : dict of str to int
        Artefacts found per kind (:data:`kinmo.report.collect.ARTEFACTS`).
    missing : list of str
        Kinds with nothing found.
    problems : list of (str, str)
        Files that could not be used, with the reason.
    """

    out: Path
    html: Path
    markdown: Path
    images: list[Path]
    found: dict[str, int]
    missing: list[str]
    problems: list[tuple[str, str]]


def write_report(run: str | Path, out: str | Path | None = None, max_images: int = 48,
                 title: str | None = None) -> ReportResult:
    """Write the HTML and Markdown report of a run folder.

    Parameters
    ----------
    run : str or Path
        The run folder (a training run, an evaluation folder or a whole pipeline's root).
    out : str or Path, optional
        Report folder (default ``RUN/report``); it is never searched for artefacts.
    max_images : int
        Most gallery images (spread evenly over the folders holding PNGs).
    title : str, optional

    Returns
    -------
    ReportResult

    Raises
    ------
    KinmoDataError
        ``run`` does not exist or is not a folder, or ``out`` is ``run`` itself.
    """
    from kinmo.errors import KinmoDataError
    from kinmo.io import atomic_write, write_text
    from kinmo.report.build import build_document
    from kinmo.report.collect import collect_run
    from kinmo.report.html import render_html
    from kinmo.report.markdown import render_markdown

    run = Path(run)
    out = Path(out) if out is not None else run / "report"
    if run.is_dir() and out.resolve() == run.resolve():
        raise KinmoDataError(out, "the report folder cannot be the run folder itself")
    art = collect_run(run, exclude=[out], max_images=max_images)
    doc = build_document(art, title)
    _viewer_page(run, out, doc)
    img = out / "img"
    manifest = img / MANIFEST
    previous: set[str] = set()
    if manifest.is_file():
        previous = set(manifest.read_text(encoding="utf-8").split("\n")) - {""}
    written: list[Path] = []
    names: list[str] = []
    for f in doc.figures():
        p = img / f.name
        atomic_write(p, lambda fh, data=f.png: fh.write(data), mode="wb")
        written.append(p)
        names.append(f.name)
    for stale in sorted(previous - set(names)):  # only files an earlier report wrote
        p = img / stale
        if ".." not in Path(stale).parts and p.suffix == ".png" and p.is_file():
            p.unlink()
    if names or manifest.is_file():
        write_text(manifest, "\n".join(names) + "\n")
    write_text(out / "report.md", render_markdown(doc))
    write_text(out / "index.html", render_html(doc))
    counts = art.counts()
    return ReportResult(out, out / "index.html", out / "report.md", written, counts,
                        [k for k, n in counts.items() if n == 0], list(art.problems))


#: Models whose predictions the interactive gallery shows, by preference.
_VIEWER_MODELS = ("OBB_fine", "GNN_fine", "OBB_coarse", "GNN_coarse")


def _viewer_page(run: Path, out: Path, doc) -> Path | None:
    """Write ``out/viewer.html`` from the run's ``viewers/<model>/<id>/`` folders, if any,
    and say so in the gallery section of ``doc``."""
    from kinmo.report.document import Note
    from kinmo.view import SOURCE_FILE, gallery_page

    if not run.is_dir():
        return None
    found: dict[str, list[Path]] = {}
    for src in sorted(run.rglob(f"viewers/*/*/{SOURCE_FILE}")):
        if out.resolve() in src.resolve().parents:
            continue
        found.setdefault(src.parent.parent.name, []).append(src.parent)
    if not found:
        return None
    model = next((m for m in _VIEWER_MODELS if m in found), sorted(found)[0])
    page, problems = gallery_page(found[model], out / "viewer.html",
                                  title=f"kinmo: {model} predictions of the test shapes")
    for s in doc.sections:
        if s.id == "gallery":
            s.blocks.insert(0, Note(
                f"Interactive: viewer.html (next to this page) shows the {len(found[model])} "
                f"test shapes with {model}'s joints on sliders"
                + (f"; {len(problems)} could not be shown" if problems else "") + ".", "info"))
    return page
