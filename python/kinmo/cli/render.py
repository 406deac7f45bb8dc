"""``kinmo render``: partial depth scans with ANCSH ground truth (:mod:`kinmo.render.dataset`)."""

from __future__ import annotations

from pathlib import Path

import typer

import kinmo.cli._values as _values

from kinmo.cli._apps import app
from kinmo.cli._executor import EXECUTOR


@app.command("render")
def render(
    data_dir: Path = typer.Argument(
        ..., metavar="DIR",
        help="PartNet-Mobility-format objects (real, generated or pseudo-labelled; possibly "
             "nested) or one object folder.",
    ),
    out: Path = typer.Option(..., "--out", "-o", help="Output folder (frames + manifest.csv)."),
    frames_per_object: int = typer.Option(
        10, "--frames-per-object", "-n", min=1, help="Frames per object."
    ),
    seed: int = typer.Option(0, "--seed", help="Seed of joint states and viewpoints."),
    size: int = typer.Option(
        256, "--size", min=8, max=4096, help="Image width and height (pixels)."
    ),
    fov: float = typer.Option(
        45.0, "--fov", min=1.0, max=170.0, callback=_values.finite, help="Vertical field of view (degrees)."
    ),
    workers: int = typer.Option(
        0, "--workers", "-j", min=0, help="Worker processes (0: one per CPU, 1: no pool)."
    ),
    force: bool = typer.Option(False, "--force", help="Re-render frames that are up to date."),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="No progress bar."),
    executor: str = EXECUTOR,
) -> None:
    """Render random partial scans (random joint states and viewpoints) of every object.

    PyBullet DIRECT with the CPU TinyRenderer; one .npz per frame (OpenCV camera-frame points,
    link labels, NPCS, NAOCS, part poses, joints) and manifest.csv. Re-running resumes:
    up-to-date frames are skipped. Exit code 1 if any object failed.
    """
    from kinmo.progress import console as new_console, literal
    from rich.table import Table

    from kinmo.cli._errors import cli_errors
    from kinmo.render.dataset import RenderConfig, render_dataset

    console = new_console()
    try:
        config = RenderConfig(width=size, height=size, fov_y=fov, seed=seed)
    except ValueError as e:
        raise typer.BadParameter(str(e)) from None
    with cli_errors(2):
        result = render_dataset(data_dir, out, frames_per_object, config, workers=workers,
                                force=force, progress=not quiet, executor=executor)
    console.print(
        f"{len(result.rows)} frames of {result.n_objects} objects in {result.seconds:.1f} s: "
        f"{result.count('ok')} rendered, {result.count('skipped')} skipped (up to date), "
        f"{result.count('failed')} failed -> {literal(result.out)}/manifest.csv",
        highlight=False, soft_wrap=True,
    )
    failed = [r for r in result.rows if r.status == "failed"]
    if failed:
        table = Table(title="Failed")
        table.add_column("id", no_wrap=True)
        table.add_column("frames")
        table.add_column("error", overflow="fold")
        by_obj: dict[str, list] = {}
        for r in failed:
            by_obj.setdefault(r.id, []).append(r)
        for oid, rows in sorted(by_obj.items()):
            table.add_row(literal(oid), str(len(rows)), literal(rows[0].error))
        console.print(table)
        raise typer.Exit(1)
