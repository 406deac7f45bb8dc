"""``kinmo train all`` and ``kinmo demo``: the whole pipeline (:mod:`kinmo.pipeline`)."""

from __future__ import annotations

from pathlib import Path

import typer

from kinmo.cli._apps import app, train_app


@train_app.command("all")
def train_all(
    labeled: Path = typer.Option(..., "--labeled", help="PartNet-Mobility folders (labelled objects)."),
    unlabeled: Path | None = typer.Option(None, "--unlabeled", help="PartNet folders to pseudo-label."),
    out: Path = typer.Option(Path("runs/all"), "--out", help="Run folder (resumes if it exists)."),
    preset: str = typer.Option("quick", help="quick (2 CPU cores) or paper (GPU)."),
    category: list[str] | None = typer.Option(None, "--category", help="ANCSH categories (repeatable)."),
    labeled_fraction: float = typer.Option(1.0, help="Share of labelled training objects for ANCSH."),
    seed: int = typer.Option(0),
    workers: int = typer.Option(0, "--workers", "-j", help="Processes for per-shape stages (0: all cores)."),
) -> None:
    """Prepare, train the motion GNN and the axis network, pseudo-label, render and train
    ANCSH in three settings, evaluate (Tables 1 and 2) and write the report."""
    from rich.console import Console

    from kinmo.errors import KinmoError
    from kinmo.pipeline import PipelineConfig, run_pipeline

    console = Console(stderr=True)
    try:
        cfg = PipelineConfig(
            labeled=labeled, unlabeled=unlabeled, out=out, preset=preset, categories=category or None,
            labeled_fraction=labeled_fraction, seed=seed, workers=workers,
        )
        res = run_pipeline(cfg, console=console)
    except (KinmoError, ValueError) as e:
        console.print(f"[red]error:[/] {e}")
        raise typer.Exit(1) from None
    console.print(f"[green]done[/]: report at {res.report}")


@app.command("demo")
def demo(
    out: Path = typer.Option(Path("runs/demo"), "--out", help="Run folder."),
    data: Path | None = typer.Option(None, "--data", help="Real PartNet-Mobility folders instead of generated objects."),
    unlabeled: Path | None = typer.Option(None, "--unlabeled", help="Real PartNet folders (with --data)."),
    n: int = typer.Option(24, "--n", help="Generated labelled objects."),
    seed: int = typer.Option(0),
    tiny: bool = typer.Option(False, help="A minimal configuration (seconds per stage), for tests."),
) -> None:
    """The whole pipeline on objects kinmo generates itself: synth, prepare, train all (quick),
    pseudo-label, eval, report."""
    from rich.console import Console

    from kinmo.errors import KinmoError
    from kinmo.pipeline import run_demo

    console = Console(stderr=True)
    try:
        res = run_demo(out, n_labeled=n, n_unlabeled=max(n // 2, 2), seed=seed, data=data, unlabeled=unlabeled,
                       tiny=tiny, console=console)
    except (KinmoError, ValueError) as e:
        console.print(f"[red]error:[/] {e}")
        raise typer.Exit(1) from None
    console.print(f"[green]done[/]: open {res.report}")
