"""``kinmo view``: an interactive HTML page of an articulated object (:mod:`kinmo.view`)."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

from kinmo.cli._apps import app


@app.command("view")
def view_cmd(
    folder: Path = typer.Argument(..., metavar="FOLDER", help="A PartNet-Mobility folder, or a `kinmo predict` output folder (with --source)."),
    out: Optional[Path] = typer.Option(None, "--out", "-o", help="The HTML page (default FOLDER/view.html)."),  # noqa: UP007
    source: Optional[Path] = typer.Option(None, "--source", "-s", help="Shape folder with the meshes FOLDER's links refer to (the input of `kinmo predict`); its own links are drawn as the true axes."),  # noqa: UP007
    truth: Optional[Path] = typer.Option(None, "--truth", "-t", help="A labelled PartNet-Mobility folder of the same shape: true axes, dashed."),  # noqa: UP007
    open_page: bool = typer.Option(False, "--open", help="Open the page in the default browser."),
) -> None:
    """Write a self-contained HTML page (no network needed) with a slider per joint.

    Moving parts are coloured, predicted axes solid, true axes dashed.
    """
    from kinmo.progress import console as new_console, literal

    from kinmo.cli._errors import cli_errors
    from kinmo.view import view_folder

    with cli_errors(1):
        page = view_folder(folder, out, source=source, truth=truth)
    new_console().print(f"viewer -> {literal(page)}", highlight=False)
    if open_page:
        import webbrowser

        webbrowser.open(page.resolve().as_uri())
