"""``kinmo predict``: predict mobile parts, joint types and axes of pre-segmented shapes."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

import kinmo.cli._values as _values

from kinmo.cli._apps import app
from kinmo.cli._executor import EXECUTOR
from kinmo.cli.export import COLLISION_HELP, FORMAT_HELP, _locked, check_formats
from kinmo.cli._refine import REFINE, RefineOptions, model_or_pretrained, with_refine_options


@app.command("predict")
@with_refine_options
def predict_cmd(
    data: Path = typer.Argument(..., metavar="DIR|FILE", help="Dataset folder (PartNet or PartNet-Mobility) or one shape folder; or your own part-segmented asset: a GLB/glTF scene (a node per part), an OBJ with o/g groups, a folder of part meshes, a URDF (a link per part) or an MJCF model (.xml, a body per part)."),
    model: Optional[Path] = typer.Option(None, "--model", "-m", help="Model bundle folder (`kinmo train all` writes runs/all/model: GNN, axis network, ranker; the learned selector by default) or a run folder of `kinmo train gnn` [default: the pretrained model, `kinmo models`]."),  # noqa: UP007
    out: Path = typer.Option(..., "--out", "-o", help="Output folder: OUT/<id>/{mobility_v2.json,mobility.urdf,edges.json}."),
    cache: Optional[Path] = typer.Option(None, "--cache", help="Part-graph cache of DIR (`kinmo prepare`), to skip building graphs."),  # noqa: UP007
    device: str = typer.Option("auto", "--device", callback=_values.device, help="auto, cpu, cuda ..."),
    hinge_max: float = typer.Option(90.0, "--hinge-max", callback=_values.angle_deg, help="Upper limit of predicted hinges (degrees) where no range is predicted (a model without a range prior, or a joint it has no group for)."),
    slider_fraction: float = typer.Option(0.3, "--slider-fraction", min=0.0, callback=_values.finite, help="Slider range as a fraction of the part's size, where no range is predicted (as --hinge-max)."),
    render: bool = typer.Option(False, "--render", help="Also write OUT/<id>/prediction.png."),
    axis_model: Optional[Path] = typer.Option(None, "--axis-model", "-a", help="Run folder of `kinmo train axis`: refine the predicted axes (paper Sec. 3.3)."),  # noqa: UP007
    refine: RefineOptions = REFINE,
    quiet: bool = typer.Option(False, "--quiet", "-q", help="No progress bar."),
    up: Optional[str] = typer.Option(None, "--up", callback=_values.up_axis, help="Up axis of FILE, y or z. Default: by its format (glTF, OBJ, a mesh folder: y; URDF: z, as ROS; a URDF kinmo wrote: y). Outputs stay in FILE's frame and units."),  # noqa: UP007
    package_path: Optional[list[Path]] = typer.Option(None, "--package-path", metavar="DIR", help="For a URDF FILE: a folder holding ROS packages by name, so that package://NAME/... meshes resolve to DIR/NAME/... when no package.xml named NAME lies above FILE (repeatable)."),  # noqa: UP007
    fmt: Optional[list[str]] = typer.Option(None, "--format", "-f", help=FORMAT_HELP + " Default: mobility_v2, semantics, urdf."),  # noqa: UP007
    collision: str = typer.Option("parts", "--collision", callback=_values.collision, help=COLLISION_HELP),
    turns: str = typer.Option("unnamed", "--turns", callback=_values.turn_policy, help="Predict an object as the average of its four quarter turns about the up axis, so that its facing does not matter: unnamed (an object none of whose part names the model knows, as a GLB's part_<k>; your own asset is read as unnamed when fewer than half are known), always, or never."),
    workers: int = typer.Option(1, "--workers", "-j", min=0, help="Worker processes for a DIR of shapes (0: one per CPU, 1: no pool); every count writes the same files."),
    executor: str = EXECUTOR,
) -> None:
    """Predict the motion of every shape under DIR (or of FILE); write PartNet-Mobility files and URDFs.

    FILE (a GLB/glTF, OBJ with groups, folder of part meshes, URDF or MJCF) becomes OUT/<name>/,
    a complete PartNet-Mobility folder (see kinmo.assets for the parts of each format,
    kinmo.user_input for the part hierarchy rule).

    Exit code 1 when any shape failed (listed at the end, and in OUT/predictions.csv).
    """
    from kinmo.progress import console as new_console, literal

    from kinmo.cli._errors import cli_errors
    from kinmo.mobility_tree import TreeOptions
    from kinmo.predict import predict_dataset

    console = new_console()
    err = new_console(stderr=True)
    check_formats(fmt)
    with cli_errors(1), _locked(out, [data], "kinmo predict"):
        from kinmo.assets import is_user_input
        from kinmo.inference.predictor import Predictor
        from kinmo.user_input import predict_user_input

        if out.exists() and not out.is_dir():  # named before the models load
            from kinmo.io import output_dir

            output_dir(out)
        own = is_user_input(data)
        if (up is not None or package_path) and not own:  # refused before the models load
            from kinmo.cli._errors import fail

            fail("--up is for your own asset (FILE); PartNet and PartNet-Mobility folders are y-up"
                 if up is not None else "--package-path is for your own asset (FILE: a URDF with "
                 "package://NAME/... meshes)", 2)
        model, axis_model, rc = refine.resolve(model_or_pretrained(model), axis_model)
        options = TreeOptions((0.0, hinge_max), slider_fraction)
        predictor = Predictor.from_parts(model, axis_model, rc, options, device)
        predictor.turns = turns  # type: ignore[assignment]  # checked by its callback
        err.print(predictor.describe(), markup=False, highlight=False, soft_wrap=True)
        kw = dict(device=device, options=options, progress=not quiet, render=render,
                  collision=collision)
        if own:
            rows = predict_user_input(data, predictor, out, formats=fmt or None, up=up,
                                      package_path=package_path or (), **kw)
        else:
            rows = predict_dataset(data, predictor, out, cache=cache, formats=fmt or None,
                                   workers=workers, executor=executor, **kw)
    ok = [r for r in rows if r.status == "ok"]
    bad = [r for r in rows if r.status != "ok"]
    console.print(f"predicted {len(ok)} shape(s), {sum(r.n_moving for r in ok)} moving link(s) -> {literal(out)}")
    for r in bad:
        err.print(f"[red]failed[/] {literal(r.id)}: {literal(r.error)}")
    if bad:
        raise typer.Exit(1)
