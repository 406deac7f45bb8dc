"""``kinmo report RUN``: an HTML page and a Markdown file summarising a run (:mod:`kinmo.report`)."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

from kinmo.cli._apps import app


@app.command("report")
def report_cmd(
    run: Path = typer.Argument(..., help="Run folder (a training run, an evaluation folder or a whole pipeline's root)."),
    out: Optional[Path] = typer.Option(None, "--out", "-o", help="Report folder (default: RUN/report)."),  # noqa: UP007
    max_images: int = typer.Option(48, "--max-images", min=0, help="Most shape images in the gallery."),
    title: Optional[str] = typer.Option(None, "--title", help="Page title (default: 'kinmo report: RUN name')."),  # noqa: UP007
) -> None:
    """Write OUT/index.html (self-contained: images inlined) and OUT/report.md (+ OUT/img/).

    The report gathers whatever RUN holds: Table 1 and Table 2 evaluations next to the
    paper's means, bar charts per category, training curves of every metrics.csv, the
    pseudo-label summary, prediction counts and a gallery of rendered shapes; it says what
    is missing. Exit code 1 when RUN does not exist.
    """
    from kinmo.progress import console as new_console, literal

    from kinmo.cli._errors import cli_errors
    from kinmo.report import write_report

    console = new_console()
    with cli_errors(1):
        res = write_report(run, out=out, max_images=max_images, title=title)
    found = ", ".join(f"{k} {n}" for k, n in res.found.items() if n)
    console.print(f"found: {literal(found or 'nothing')}")
    if res.missing:
        console.print(f"[yellow]missing:[/] {literal(', '.join(res.missing))}")
    for rel, problem in res.problems:
        console.print(f"[red]problem:[/] {literal(rel)}: {literal(problem)}")
    console.print(f"wrote {literal(res.html)} and {literal(res.markdown)}")
