"""``kinmo train ranker``: fit the learned candidate selector (:mod:`kinmo.train.ranker`)."""

from __future__ import annotations

from pathlib import Path

import typer

from kinmo.cli._apps import train_app
from kinmo.cli._executor import EXECUTOR


@train_app.command("ranker")
def train_ranker_cmd(
    data: Path = typer.Option(..., "--data", "-d", help="Cache folder of `kinmo prepare` (PartNet-Mobility)."),
    out: Path = typer.Option(..., "--out", "-o", help="Folder for ranker.json, cv.json, oof_groups.npz and the fold GNNs (an axis run folder works: the CLI then finds the ranker there)."),
    split: Path = typer.Option(..., "--split", help="The GNN runs' split.json: only its training ids are used."),
    folds: int = typer.Option(3, "--folds", min=2, help="Out-of-fold GNNs on the training ids."),
    preset: str = typer.Option("quick", "--preset", help="Preset of the fold GNNs."),
    types: str = typer.Option("fine,coarse", "--types", help="Comma-separated type sets of the fold GNNs (a ranker per type set, in one file; the coarse one fit on the groups of both)."),
    seed: int = typer.Option(0, "--seed", help="Random seed (folds, GNNs, ranker)."),
    threads: int = typer.Option(1, "--threads", min=0, help="CPU threads for torch (per fold GNN)."),
    workers: int = typer.Option(1, "--workers", "-j", min=0, help="Fold GNNs trained at once (0: one per CPU)."),
    members: int = typer.Option(0, "--members", min=0, max=16, help="Ensemble members of every fold GNN (seeds SEED+1 ...): fit the ranker on the averaged predictions of 1 + N GNNs, as it will refine a motion GNN trained with `kinmo train gnn --members N` (kinmo extension)."),
    executor: str = EXECUTOR,
    quiet: bool = typer.Option(False, "--quiet", "-q", help="No progress bar."),
) -> None:
    """Fit the ranker of candidate axes on out-of-fold GNN predictions of the training objects."""
    from kinmo.progress import console as new_console, literal

    from kinmo.cli._errors import cli_errors, fail
    from kinmo.train.ranker import train_ranker

    ts = tuple(t.strip() for t in types.split(",") if t.strip())
    if not ts or any(t not in ("fine", "coarse") for t in ts):
        fail(f"--types: expected fine and/or coarse, got {types!r}", 2)
    with cli_errors(1):
        _, st = train_ranker(data, out, split, folds=folds, preset=preset, types=ts, seed=seed,
                             threads=threads, progress=not quiet, workers=workers, executor=executor,
                             members=members)
    c = new_console()
    what = "one ranker on the type sets pooled" if "pooled" in st else "a ranker per type set"
    c.print(f"wrote {literal(out / 'ranker.json')}: {what}")
    for t, s in st.items():
        c.print(f"  {t}: {s['groups']} edges, candidate recall {s['recall']:.3f}, out-of-fold top-1 "
                f"{s['oof_top1']:.3f} (angle {s['oof_angle']:.2f}° vs GNN {s['gnn_angle']:.2f}°)")
        if "position_dist_before" in s:
            c.print(f"  {t} position stage {'kept' if s['position_kept'] else 'not kept'}: hinge line "
                    f"distance {s['position_dist_before']:.4f} -> {s['position_dist_after']:.4f}, "
                    f"per category {s['position_cat_dist_before']:.4f} -> "
                    f"{s['position_cat_dist_after']:.4f} (out of fold, / diagonal)")
