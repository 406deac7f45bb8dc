"""``kinmo synth``: generate procedural articulated objects (PartNet-Mobility / PartNet)."""

from __future__ import annotations

from pathlib import Path

import typer

from kinmo.cli._apps import app


@app.command("synth")
def synth(
    out: Path = typer.Argument(..., help="Output folder; one sub-folder per object."),
    n: int = typer.Option(20, "--n", min=0, max=100000, help="Number of objects."),
    seed: int = typer.Option(0, "--seed", min=0, help="Random seed (same seed: same files)."),
    partnet: bool = typer.Option(
        False,
        "--partnet",
        help="Write PartNet folders (objs/, no motion) instead of PartNet-Mobility.",
    ),
    categories: list[str] = typer.Option(
        None,
        "--categories",
        "-c",
        help="Categories to generate (repeat the option; default: all). One of StorageFurniture, "
        "Refrigerator, Oven, Microwave, Dishwasher, Laptop, Table, Bucket, KitchenPot, Bottle.",
    ),
    structure: str | None = typer.Option(
        None,
        "--structure",
        help="Keep only objects of this ANCSH kinematic structure, e.g. 0<R-1 (one revolute child "
        "of the base: laptops, one-door refrigerators) or 0<R-1,0<R-2.",
    ),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="No progress bar."),
) -> None:
    """Generate N randomised articulated objects with exact motion ground truth.

    Object k goes to OUT/9<seed:05d><k:05d>/, an id no real PartNet object has.
    OUT/synth-<seed>.json lists the objects and their sampled parameters. With --structure,
    objects of other structures are drawn and dropped (ids then have gaps).
    """
    from kinmo.cli._errors import cli_errors
    from kinmo.synth import CATEGORIES, generate_dataset

    cats = None
    if categories:
        cats = [c for item in categories for c in item.replace(",", " ").split()]
        bad = [c for c in cats if c not in CATEGORIES]
        if bad:
            raise typer.BadParameter(
                f"unknown categories {', '.join(bad)}; choose from {', '.join(CATEGORIES)}",
                param_hint="--categories",
            )
    keep = None
    if structure is not None:
        from kinmo.ancsh.objects import structure_filter

        try:
            keep = structure_filter(structure)
        except ValueError as e:
            raise typer.BadParameter(str(e), param_hint="--structure") from None
    with cli_errors(2, also=(ValueError,)):
        folders = generate_dataset(out, n, seed, categories=cats, partnet=partnet, progress=not quiet, keep=keep)
    typer.echo(f"wrote {len(folders)} objects to {out}")
