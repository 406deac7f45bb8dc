"""``kinmo train gnn``: train the motion GNN on a part-graph cache (:mod:`kinmo.train.gnn`)."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

import kinmo.cli._values as _values

from kinmo.cli._apps import train_app


@train_app.command("gnn")
def train_gnn_cmd(
    data: Path = typer.Option(..., "--data", "-d", help="Cache folder of `kinmo prepare` (PartNet-Mobility)."),
    out: Path = typer.Option(..., "--out", "-o", help="Run folder to write (model.pt, config.json, metrics.csv, split.json)."),
    preset: str = typer.Option("quick", "--preset", envvar="KINMO_PRESET", help="quick (CPU, minutes), paper (the paper's sizes, GPU) or tiny (seconds: a check, not results)."),
    types: Optional[str] = typer.Option(None, "--types", help="fine (10 types) or coarse (5 types) [default: fine]."),  # noqa: UP007
    epochs: Optional[int] = typer.Option(None, "--epochs", min=1, help="Override the preset's epochs."),  # noqa: UP007
    seed: Optional[int] = typer.Option(None, "--seed", help="Random seed [default: 0]."),  # noqa: UP007
    split: Optional[Path] = typer.Option(None, "--split", help="A split.json to use instead of making one."),  # noqa: UP007
    device: Optional[str] = typer.Option(None, "--device", callback=_values.device, help="auto, cpu, cuda, cuda:1 ... [default: auto]."),  # noqa: UP007
    batch_size: Optional[int] = typer.Option(None, "--batch-size", min=1, help="Shapes per step."),  # noqa: UP007
    lr: Optional[float] = typer.Option(None, "--lr", callback=_values.learning_rate, help="Learning rate."),  # noqa: UP007
    threads: Optional[int] = typer.Option(None, "--threads", min=0, help="CPU threads for torch (0: default)."),  # noqa: UP007
    flatten_prob: Optional[float] = typer.Option(None, "--flatten-prob", min=0.0, max=1.0, help="Share of training shapes also trained flattened (one leaf per link or PartNet leaf) [preset's: quick/paper 1, tiny 0]."),  # noqa: UP007
    drop_names_prob: Optional[float] = typer.Option(None, "--drop-names-prob", min=0.0, max=1.0, help="Share of training graphs with node names dropped to 'unknown' [preset's]."),  # noqa: UP007
    augment_turn: Optional[float] = typer.Option(None, "--augment-turn", min=0.0, max=1.0, help="Share of training shapes seen a random quarter turn off PartNet's facing each step [preset's: quick/paper 0.15, tiny 0]."),  # noqa: UP007
    members: int = typer.Option(0, "--members", min=0, help="Also train this many models like it with seeds SEED+1, SEED+2 ... into OUT/members/<k>/: an ensemble whose answers inference averages (kinmo extension)."),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="No progress bar."),
) -> None:
    """Train the motion GNN (Liu et al. 2023, Sec. 3.2) and write a run folder.

    The labelled graphs of DATA are split into train and test sets by category (written to
    OUT/split.json); test metrics are logged every epoch in OUT/metrics.csv.
    """
    from kinmo.progress import console as new_console, literal

    from kinmo.cli._errors import cli_errors, fail
    from kinmo.train.config import preset as make_preset
    from kinmo.train.gnn import train_gnn, train_members

    console = new_console()
    if types not in (None, "fine", "coarse"):
        fail(f"--types must be fine or coarse, got {types!r}", 2)
    with cli_errors(2, also=(ValueError,)):
        cfg = make_preset(preset, types=types, epochs=epochs, seed=seed, device=device,
                          batch_size=batch_size, lr=lr, threads=threads,
                          flatten_prob=flatten_prob, drop_names_prob=drop_names_prob,
                          augment_turn=augment_turn)
    with cli_errors(1):
        res = train_gnn(data, out, cfg, split=split, progress=not quiet)
    last = res.history[-1]
    console.print(
        f"trained {cfg.model.types} GNN ({cfg.preset}) on {len(res.split.train)} shapes in "
        f"{res.seconds:.1f} s: loss {last['loss']:.3f}, train acc {last['train_acc']:.3f}"
        + (f", test acc {last['test_acc']:.3f}" if res.split.test else "")
    )
    if members:
        with cli_errors(1):
            extra = train_members(data, out, cfg, members, progress=not quiet)
        console.print(f"trained {len(extra)} ensemble member(s) into {literal(Path(out) / 'members')}")
    console.print(f"run folder: {literal(res.run_dir)}")
