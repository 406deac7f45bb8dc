"""``kinmo eval pre-segmented``: paper Table 1 (GNN rows) on pre-segmented test shapes."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

import kinmo.cli._values as _values

from kinmo.cli._apps import eval_app
from kinmo.cli._refine import REFINE, RefineOptions, with_refine_options


@eval_app.command("pre-segmented")
@with_refine_options
def pre_segmented_cmd(
    model: Optional[list[Path]] = typer.Option(None, "--model", "-m", help="Model bundle folder (runs/all/model) or run folder(s) of `kinmo train gnn`; give a fine and a coarse run for both columns (default: the motion GNNs and axis network of the last `kinmo train all`, runs/all)."),  # noqa: UP007
    data: Path = typer.Option(..., "--data", "-d", help="Part-graph cache (`kinmo prepare`) or PartNet-Mobility dataset folder."),
    out: Optional[Path] = typer.Option(None, "--out", "-o", help="Folder for table1.csv, table1.md, shapes.csv [default: first run folder/eval]."),  # noqa: UP007
    split: Optional[Path] = typer.Option(None, "--split", help="Split file; default: the first run's split.json. Shapes of DATA that are not its training ids are evaluated (the test split, or every new shape of another folder)."),  # noqa: UP007
    all_shapes: bool = typer.Option(False, "--all", help="Evaluate every labelled shape of DATA, training shapes of the split included."),
    render: bool = typer.Option(False, "--render", help="Write a PNG per shape and model (OUT/renders/<model>/<id>.png)."),
    axis_model: Optional[Path] = typer.Option(None, "--axis-model", "-a", help="Run folder of `kinmo train axis`: add OBB_fine / OBB_coarse columns with refined axes."),  # noqa: UP007
    refine: RefineOptions = REFINE,
    device: str = typer.Option("auto", "--device", callback=_values.device, help="auto, cpu, cuda ..."),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="No progress bar."),
) -> None:
    """Evaluate motion GNN(s) on the shapes they did not train on (the test split of their own
    data, or every shape of another folder): type accuracy, mobile-part detection, axis errors."""
    from kinmo.progress import console as new_console, literal

    from kinmo.cli._errors import cli_errors
    from kinmo.evaluate.pre_segmented import run_evaluation

    console = new_console()
    if not console.is_terminal:  # pipes and logs: do not squeeze the 11-column tables
        console = new_console(width=max(console.width, 140))
    if not model:
        from kinmo.cli._errors import fail
        from kinmo.runs import DEFAULT_RUN

        model = [DEFAULT_RUN / f"gnn_{t}" for t in ("fine", "coarse") if (DEFAULT_RUN / f"gnn_{t}").is_dir()]
        if not model:
            fail(f"no --model given and no motion GNN of `kinmo train all` in {DEFAULT_RUN}")
        if axis_model is None and (DEFAULT_RUN / "axis" / ".done").is_file():
            axis_model = DEFAULT_RUN / "axis"
        new_console(stderr=True).print(
            f"models of `kinmo train all`: {literal(', '.join(map(str, model + ([axis_model] if axis_model else []))))}",
            highlight=False, soft_wrap=True)
    with cli_errors(1):
        from kinmo.inference.bundle import resolve_bundle

        trained_on = {i for m in model for i in resolve_bundle(m).trained_on}
        resolved = [refine.resolve(m, axis_model) for m in model]
        model = [r[0] for r in resolved]
        axis_model, rc = resolved[0][1], resolved[0][2]
        report, paths = run_evaluation(model, data, out=out, split=split, all_shapes=all_shapes,
                                       render=render, device=device, progress=not quiet,
                                       console=console, axis_model=axis_model,
                                       refine_config=rc, exclude=trained_on)
    console.print(f"wrote {literal(paths['csv'])} and {literal(paths['markdown'])}")
