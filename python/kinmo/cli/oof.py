"""``kinmo eval oof``: Table 1's four settings out of fold on every labelled object
(:mod:`kinmo.evaluate.oof`, issue 34)."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

from kinmo.cli._apps import eval_app
from kinmo.cli._executor import EXECUTOR


@eval_app.command("oof")
def oof_cmd(
    data: Path = typer.Option(..., "--data", "-d", help="Part-graph cache of `kinmo prepare` (PartNet-Mobility); every labelled object is evaluated."),
    out: Path = typer.Option(..., "--out", "-o", help="Folder for table1.csv, table1.md, shapes.csv, oof.json, the fold GNNs and rankers (resumes its trained folds)."),
    folds: int = typer.Option(5, "--folds", min=2, help="Folds (stratified by category)."),
    preset: str = typer.Option("quick", "--preset", help="GNN preset (as `kinmo train all`)."),
    seed: int = typer.Option(0, "--seed", help="Random seed (folds, GNNs, rankers)."),
    augment: bool = typer.Option(True, "--augment/--no-augment", help="Fine GNNs with the preset's hierarchy and name augmentations, as `kinmo train all`."),
    workers: int = typer.Option(1, "--workers", "-j", min=0, help="GNNs trained at once (0: one per CPU)."),
    members: int = typer.Option(0, "--members", min=0, help="Ensemble members of every fold GNN (seeds SEED+1 ...): each fold predicted by the average of 1 + N GNNs (as `kinmo train gnn --members`)."),
    pseudo_rule: bool = typer.Option(True, "--pseudo-rule/--no-pseudo-rule", help="Also grade the pseudo-label rule out of fold (its defaults, the fold's coarse GNN as the second model) into OUT/pseudo-label-rule/."),
    extra: Optional[Path] = typer.Option(None, "--extra", help="Part-graph cache of more labelled objects (e.g. `kinmo synth`, then `kinmo prepare`) added to every fold GNN's training; never evaluated, never in the selectors' or range priors' fits."),  # noqa: UP007
    executor: str = EXECUTOR,
    quiet: bool = typer.Option(False, "--quiet", "-q", help="No progress bar."),
) -> None:
    """Train a fine and a coarse motion GNN per fold, fit the learned selector per fold on the
    other folds' out-of-fold predictions, and write Table 1 (GNN_coarse, GNN_fine, OBB_coarse,
    OBB_fine) per category over every labelled object."""
    from kinmo.cli._errors import cli_errors
    from kinmo.evaluate.oof import oof_summary, oof_table1
    from kinmo.evaluate.pseudo_rule import summary_line
    from kinmo.evaluate.tables import print_report
    from kinmo.progress import console as new_console
    from kinmo.progress import literal

    console = new_console()
    if not console.is_terminal:  # logs: do not squeeze the tables
        console = new_console(width=max(console.width, 140))
    with cli_errors(1):
        res = oof_table1(data, out, folds=folds, preset=preset, seed=seed, workers=workers,
                         augment=augment, executor=executor, progress=not quiet, members=members,
                         pseudo_rule=pseudo_rule, extra=extra)
    print_report(res.report, console)
    s = oof_summary(res.report)
    for t in ("fine", "coarse"):
        if f"gain_{t}" in s:
            g = s[f"gain_{t}"]
            console.print(f"selector vs GNN_{t}: per-category mean {g['mean']:+.1%}, pooled {g['all']:+.1%}")
    if res.pseudo_rule is not None:
        a = res.pseudo_rule.summary()
        console.print(f"pseudo-label rule at {res.pseudo_rule.threshold:g} out of fold: {int(a['objects'])} "
                      f"objects, {summary_line(a)} ({literal(out / 'pseudo-label-rule' / 'summary.md')})")
    console.print(f"wrote {literal(out / 'table1.md')} and {literal(out / 'oof.json')}")
