"""``kinmo train axis``: train the axis-selection network (:mod:`kinmo.refine.train`)."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

import kinmo.cli._values as _values

from kinmo.cli._apps import train_app


@train_app.command("axis")
def train_axis_cmd(
    data: Path = typer.Option(..., "--data", "-d", help="Cache folder of `kinmo prepare` (PartNet-Mobility)."),
    out: Path = typer.Option(..., "--out", "-o", help="Run folder to write (model.pt, last.pt, config.json, metrics.csv)."),
    preset: str = typer.Option("quick", "--preset", envvar="KINMO_PRESET", help="quick (CPU, minutes), paper (the paper code's network, GPU) or tiny (seconds: a check, not results)."),
    seed: int = typer.Option(0, "--seed", help="Random seed (also the default split's)."),
    split: Optional[Path] = typer.Option(None, "--split", help="The GNN run's split.json: its test shapes are never used."),  # noqa: UP007
    epochs: Optional[int] = typer.Option(None, "--epochs", min=1, help="Override the preset's epochs."),  # noqa: UP007
    batch_size: Optional[int] = typer.Option(None, "--batch-size", min=1, help="(rest, positive, negative) triples per step."),  # noqa: UP007
    lr: Optional[float] = typer.Option(None, "--lr", callback=_values.learning_rate, help="Learning rate."),  # noqa: UP007
    n_points: Optional[int] = typer.Option(None, "--n-points", min=8, help="Points per cloud."),  # noqa: UP007
    device: str = typer.Option("auto", "--device", callback=_values.device, help="auto, cpu, cuda, cuda:1 ..."),
    threads: int = typer.Option(0, "--threads", min=0, help="CPU threads for torch (0: default)."),
    per_category: Optional[int] = typer.Option(None, "--per-category", min=0, help="Fine-tune a network per category with at least this many training objects, kept when it beats the global one on the category's validation objects (0: off; default: the preset's)."),  # noqa: UP007
    quiet: bool = typer.Option(False, "--quiet", "-q", help="No progress bar."),
) -> None:
    """Train the Siamese DGCNN that judges candidate motions (Liu et al. 2023, Sec. 3.3).

    Positives move each labelled moving part about its true axis within its limits, negatives
    about a wrong OBB candidate by the same amount. Validation shapes come from the training
    part of the split; the selection accuracy (best candidate = true axis) is logged per epoch
    in OUT/metrics.csv and picks the saved model (OUT/model.pt).
    """
    from kinmo.progress import console as new_console, literal

    from kinmo.cli._errors import cli_errors
    from kinmo.refine.train import preset_config, train_axis_model

    console = new_console()
    overrides: dict = {"seed": seed, "device": device, "threads": threads}
    for key, val in (("epochs", epochs), ("batch_size", batch_size), ("lr", lr)):
        if val is not None:
            overrides[key] = val
    if per_category is not None:
        overrides["category_min_objects"] = per_category
    if n_points is not None:
        overrides["net"] = {"n_points": n_points}
    with cli_errors(2, also=(ValueError,)):
        cfg = preset_config(preset, **overrides)
    with cli_errors(1):
        res = train_axis_model(data, out, cfg, split=split, progress=not quiet)
    best = res.metrics[res.best_epoch - 1]
    console.print(
        f"trained axis network ({cfg.preset}) on {res.n_train_edges} moving edges "
        f"({res.n_val_edges} validation): best epoch {res.best_epoch}, "
        f"val selection accuracy {best['val_select_acc']:.3f} "
        f"(chance {best['val_select_chance']:.3f}), val acc {best['val_acc']:.3f}",
        highlight=False, soft_wrap=True,
    )
    kept = res.categories_kept
    if kept:
        console.print(f"per-category networks: {literal(', '.join(kept))}", highlight=False)
    console.print(f"run folder: {literal(res.run_dir)}", highlight=False)
