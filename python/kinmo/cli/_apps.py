"""The Typer applications every command module registers on."""

from __future__ import annotations

import typer

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
