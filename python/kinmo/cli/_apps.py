"""The Typer applications every command module registers on."""

from __future__ import annotations

import os
import sys

import typer

from kinmo.progress import LOG_WIDTH

if not sys.stdout.isatty() and "COLUMNS" not in os.environ and "TERMINAL_WIDTH" not in os.environ:
    # help captured in a file or pipe (a log, a cluster job): defaults and option texts are
    # wrapped at LOG_WIDTH columns, never cut at 80 with an ellipsis (typer reads the variable
    # when it renders help; set here, not imported, so startup stays light)
    os.environ["TERMINAL_WIDTH"] = str(LOG_WIDTH)

app = typer.Typer(
    name="kinmo",
    help="Predict how the parts of 3D objects move (PartNet / PartNet-Mobility).",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_show_locals=False,
)

train_app = typer.Typer(help="Train models: gnn, axis, ancsh, or all of them.", no_args_is_help=True)
app.add_typer(train_app, name="train")

eval_app = typer.Typer(
    help="Evaluate models (paper Table 1 on pre-segmented shapes, Table 2 on partial scans).",
    invoke_without_command=True,
)
app.add_typer(eval_app, name="eval")


@app.callback()
def _root(
    verbose: int = typer.Option(
        0, "--verbose", "-v", count=True, show_default=False,
        help="Show diagnostics (skipped and resumed shapes, failures, fallbacks): -v info, "
        "-vv debug. Without it the KINMO_LOG environment variable sets the level.",
    ),
    limits: list[str] = typer.Option(
        [], "--limit", metavar="NAME=N",
        help="Raise (or lower) a resource limit on inputs: parts, edges, triangles, file_bytes, "
        "nodes (docs/security.md; also KINMO_MAX_<NAME>).",
    ),
) -> None:
    """Predict how the parts of 3D objects move (PartNet / PartNet-Mobility)."""
    from kinmo.cli._errors import cli_errors
    from kinmo.progress import setup_logging

    with cli_errors(2):
        setup_logging(verbose)
        if limits:
            from kinmo.limits import set_limit

            for spec in limits:
                set_limit(spec)
