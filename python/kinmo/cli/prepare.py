"""``kinmo prepare``: read dataset folders into part-graph caches (:mod:`kinmo.prepare`)."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

import kinmo.cli._values as _values

from kinmo.cli._apps import app
from kinmo.cli._executor import EXECUTOR


@app.command("prepare")
def prepare(
    data_dir: Path = typer.Argument(
        ...,
        metavar="DIR",
        help="Dataset folder (PartNet or PartNet-Mobility, possibly nested) or one shape folder.",
    ),
    out: Optional[Path] = typer.Option(  # noqa: UP007 (typer needs Optional on 3.10)
        None, "--out", "-o", help="Cache folder (default: ./cache/NAME, NAME the name of DIR)."
    ),
    workers: int = typer.Option(
        0, "--workers", "-j", min=0, help="Worker processes (0: one per CPU, 1: no pool)."
    ),
    strict: bool = typer.Option(False, "--strict", help="Stop at the first failed shape."),
    n_points: int = typer.Option(
        1024, "--n-points", min=1, max=1 << 20,
        help="Surface points per node (at most 1048576: the cache holds them all in memory).",
    ),
    seed: int = typer.Option(0, "--seed", help="Sampling seed."),
    contact_tolerance: float = typer.Option(
        0.01, "--contact-tolerance", min=0.0, callback=_values.finite,
        help="Contact threshold, fraction of the shape's bounding-box diagonal.",
    ),
    distance_cap: float = typer.Option(
        0.1, "--distance-cap", min=0.0, callback=_values.finite, help="Distance clip, fraction of the diagonal."
    ),
    merged: bool = typer.Option(
        False, "--merged",
        help="Read result_after_merging.json for PartNet shapes that have it.",
    ),
    force: bool = typer.Option(False, "--force", help="Rebuild shapes whose cache is up to date."),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="No progress bar."),
    executor: str = EXECUTOR,
) -> None:
    """Build the part-graph cache of every shape under DIR (one .npz each + manifest.csv).

    Re-running resumes: up-to-date shapes are skipped. Failed shapes are listed at the end;
    the exit code is 1 if any failed.
    """
    from kinmo.progress import console as new_console, literal
    from rich.table import Table

    from kinmo.cli._errors import cli_errors
    from kinmo.prepare import PrepareConfig, prepare_dataset

    console = new_console()
    try:
        config = PrepareConfig(
            n_points=n_points,
            seed=seed,
            contact_tolerance=contact_tolerance,
            distance_cap=distance_cap,
            hierarchy="merged" if merged else "result",
        )
    except ValueError as e:
        raise typer.BadParameter(str(e)) from None
    with cli_errors(2):
        result = prepare_dataset(
            data_dir, out, config=config, workers=workers, strict=strict, force=force,
            progress=not quiet, executor=executor,
        )

    console.print(
        f"{result.n_shapes} shapes in {result.seconds:.1f} s: "
        f"{result.count('ok')} built, {result.count('skipped')} up to date, "
        f"{result.count('failed')} failed -> {literal(result.out)}/manifest.csv",
        highlight=False,
        soft_wrap=True,
    )
    if result.failures:
        table = Table(title="Failed shapes", show_lines=False)
        table.add_column("id", no_wrap=True)
        table.add_column("error", overflow="fold")
        for r in result.failures:
            table.add_row(literal(r.id), literal(r.error))
        console.print(table)
    if result.stopped:
        console.print(
            f"--strict: stopped at the first failure, {result.n_shapes - len(result.rows)} "
            "shapes not processed", highlight=False,
        )
    if result.failures or result.stopped:
        raise typer.Exit(1)
