"""``kinmo eval user-format``: a motion GNN on the test split given as users give objects
(:mod:`kinmo.evaluate.user_format`, issue 22)."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

from kinmo.cli._apps import eval_app
from kinmo.cli._refine import REFINE, RefineOptions, with_refine_options


@eval_app.command("user-format")
@with_refine_options
def user_format_cmd(
    model: Path = typer.Option(..., "--model", "-m", help="Model bundle folder (`kinmo train all` writes runs/all/model; the learned selector by default) or a run folder of `kinmo train gnn` (as `kinmo predict --model`)."),
    data: Path = typer.Option(..., "--data", "-d", help="PartNet-Mobility dataset folder."),
    out: Path = typer.Option(..., "--out", "-o", help="Work and result folder (glb/, pred/, user_format.json, user_format.md)."),
    split: Optional[Path] = typer.Option(None, "--split", help="Split file whose test ids are evaluated [default: the GNN run's split.json]."),  # noqa: UP007
    variants: str = typer.Option("generic,semantic,leaf,partnet", "--variants", help="Comma-separated: generic (node per link, part_<k>), semantic (link names), leaf (node per PartNet leaf), partnet (PartNet format)."),
    axis_model: Optional[Path] = typer.Option(None, "--axis-model", "-a", help="Run folder of `kinmo train axis`: refine the axes (as `kinmo predict --axis-model`)."),  # noqa: UP007
    refine: RefineOptions = REFINE,
    device: str = typer.Option("auto", "--device", help="auto, cpu, cuda ..."),
    turn: int = typer.Option(0, "--turn", min=0, max=3, help="Give each GLB turned this many quarter turns about its up axis (its box centre); scored once turned back (issue 36)."),
    write_up: str = typer.Option("y", "--write-up", help="Write the GLBs y-up (glTF's convention) or z-up; read as `kinmo predict FILE` does without --up (issue 36)."),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="No progress bar."),
) -> None:
    """Convert the test objects to user GLBs (a node per link or PartNet leaf, generic or
    semantic names), predict each as `kinmo predict FILE` does, and score recall (moved-node
    IoU >= 0.5) and the mean axis angle beside the PartNet-format result."""
    from kinmo.cli._errors import cli_errors
    from kinmo.evaluate.user_format import evaluate_user_format, input_rotation, results_markdown
    from kinmo.inference.bundle import resolve_bundle
    from kinmo.inference.predictor import Predictor
    from kinmo.progress import console as new_console
    from kinmo.progress import literal
    from kinmo.train.split import Split

    console = new_console()
    vs = [v.strip() for v in variants.split(",") if v.strip()]
    with cli_errors(2, also=(ValueError,)):
        input_rotation(turn, write_up)  # a bad --write-up: one line, exit 2
        trained_on = set(resolve_bundle(model).trained_on)
        gnn, axis_model, rc = refine.resolve(model, axis_model)
        sp = Split.load(split if split is not None else gnn / "split.json")
        ids = [i for i in sp.test if i not in trained_on]  # never score a bundle on its training objects
        if len(ids) < len(sp.test):
            console.print(f"left out {len(sp.test) - len(ids)} test object(s) the model bundle was trained on")
        if not ids:
            raise ValueError("every test object of the split is one the model bundle was trained on")
    with cli_errors(1):
        predictor = Predictor.from_parts(gnn, axis_model, rc, device=device)
        console.print(predictor.describe(), markup=False)
        res = evaluate_user_format(data, predictor, ids, out, vs, progress=not quiet, turn=turn,
                                   write_up=write_up)
    console.print(results_markdown(res), markup=False)
    console.print(f"wrote {literal(out / 'user_format.json')} and {literal(out / 'user_format.md')}")
