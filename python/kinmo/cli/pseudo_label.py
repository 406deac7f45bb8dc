"""``kinmo pseudo-label``: PartNet shapes -> PartNet-Mobility objects (:mod:`kinmo.pseudo_label`)."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

import kinmo.cli._values as _values

from kinmo.cli._apps import app
from kinmo.cli.export import COLLISION_HELP, FORMAT_HELP, check_formats
from kinmo.cli._executor import EXECUTOR
from kinmo.cli._refine import REFINE, RefineOptions, model_or_pretrained, with_refine_options


@app.command("pseudo-label")
@with_refine_options
def pseudo_label_cmd(
    data_dir: Path = typer.Argument(..., metavar="DIR", help="PartNet dataset folder (or one shape folder)."),
    model: Optional[Path] = typer.Option(None, "--model", "-m", help="Model bundle folder (`kinmo train all` writes runs/all/model) or a run folder of `kinmo train gnn` [default: the pretrained model, `kinmo models`]."),  # noqa: UP007
    axis_model: Optional[Path] = typer.Option(None, "--axis-model", "-a", help="Run folder of `kinmo train axis` (its ranker.json, or ../ranker/ranker.json, when present, selects the axes), or a folder holding only a ranker.json [default: the bundle's]."),  # noqa: UP007
    out: Path = typer.Option(..., "--out", "-o", help="Output folder: one PartNet-Mobility folder per kept shape."),
    threshold: float = typer.Option(0.6, "--threshold", "-t", min=0.0, max=1.0, callback=_values.finite, help="Minimum score of every joint of a kept shape."),
    score: str = typer.Option("joint", "--score", help="A joint's score: joint (its refined line's confidence times its type's probability) or line (the line's confidence alone)."),
    workers: int = typer.Option(1, "--workers", "-j", min=0, help="Worker processes (0: one per CPU, 1: no pool)."),
    cache: Optional[Path] = typer.Option(None, "--cache", help="A `kinmo prepare` cache of DIR (graphs are built when missing)."),  # noqa: UP007
    refine: RefineOptions = REFINE,
    consistent: bool = typer.Option(False, "--consistent/--raw-types", help="Make the fine types agree with the GNN's axes before refining (as `kinmo eval` does; the threshold then rejects far fewer, and fewer wrong, shapes). Default: the paper's arg-max types."),
    sign: str = typer.Option("tree", "--sign", help="Direction of motion: tree (away from the reference part) or feasibility (the network's)."),
    link: str = typer.Option("hardlink", "--link", help="How meshes get into OUT/<id>/textured_objs/: hardlink (default; a copy across file systems) or copy make self-contained folders; symlink links to the source dataset by absolute path, for a dataset that stays in place (kinmo's own readers refuse such links)."),
    copy: bool = typer.Option(False, "--copy", help="Same as --link copy."),
    device: str = typer.Option("cpu", "--device", callback=_values.device, help="Torch device of both networks."),
    force: bool = typer.Option(False, "--force", help="Redo shapes already processed with the same inputs."),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="No progress bar."),
    fmt: Optional[list[str]] = typer.Option(None, "--format", "-f", help=FORMAT_HELP + " Default: mobility_v2, semantics, urdf (mobility_v2 is always written)."),  # noqa: UP007
    collision: str = typer.Option("parts", "--collision", callback=_values.collision, help=COLLISION_HELP),
    executor: str = EXECUTOR,
    check_model: Optional[Path] = typer.Option(None, "--check-model", help="Run folder of a second `kinmo train gnn` (e.g. the coarse-type GNN) that must agree on every joint of a kept shape: its probability of the joint's motion at least --agree-prob, its refined axis within --agree-deg [default: the bundle's check/ model; none for bundles without one]."),  # noqa: UP007
    agree_prob: float = typer.Option(0.5, "--agree-prob", min=0.0, max=1.0, callback=_values.finite, help="With a second model: the least probability it gives each kept joint's motion (R, P, PR)."),
    agree_deg: float = typer.Option(20.0, "--agree-deg", min=0.0, max=90.0, callback=_values.finite, help="With a second model: the largest angle (degrees) between its refined axis and the kept joint's."),
    no_check: bool = typer.Option(False, "--no-check", help="Judge with the first model alone, even when the bundle has a check/ model."),
) -> None:
    """Predict and refine the motions of every shape under DIR; keep the confident ones.

    A shape is kept when every predicted moving joint scores at least --threshold after
    refinement (Liu et al. 2023, Sec. 3.3): its refined line's confidence times its type's
    probability (--score joint) or the line's confidence alone (--score line); with a second
    model (--check-model, or a bundle's check/ model as `kinmo train all` writes it), that model
    must agree on each joint (issue 34). Kept shapes become OUT/<id>/ in the
    PartNet-Mobility format (mobility_v2.json, semantics.txt, mobility.urdf, textured_objs/,
    scores.json). OUT/summary.csv counts kept and rejected shapes per category,
    OUT/shapes.csv gives every shape's status and reason. Re-running resumes.
    """
    from kinmo.progress import console as new_console, literal, print_table
    from rich.table import Table

    from kinmo.cli._errors import cli_errors
    from kinmo.pseudo_label import (
        STATUSES,
        PseudoLabelConfig,
        pseudo_label_dataset,
        summary_rows,
    )

    from kinmo.cli._errors import fail

    console = new_console()
    check_formats(fmt)
    if no_check and check_model is not None:
        fail("--no-check and --check-model contradict each other: give one of them", 2)
    with cli_errors(2):
        bundle, axis_model, rc = refine.resolve_bundle(model_or_pretrained(model), axis_model)
    model = bundle.gnn
    check = None if no_check else (check_model if check_model is not None else bundle.check)
    if axis_model is None:
        fail("no axis network and no ranker: give a model bundle with them, or --axis-model", 2)
    with cli_errors(2, also=(ValueError,)):
        config = PseudoLabelConfig(
            threshold=threshold, score=score,
            refine=rc,
            sign=sign, consistent=consistent, link="copy" if copy else link, device=device,
            collision=collision, agree_prob=agree_prob, agree_deg=agree_deg,
            **({"formats": tuple(fmt)} if fmt else {}),
        )
    with cli_errors(2):
        res = pseudo_label_dataset(data_dir, model, axis_model, out, config, workers=workers,
                                   cache=cache, force=force, progress=not quiet,
                                   executor=executor, check_run=check)

    table = Table(title=f"Pseudo-labels (threshold {threshold:g})")
    table.add_column("category")
    table.add_column("shapes", justify="right")
    for s in STATUSES:
        table.add_column(s.replace("_", " "), justify="right")
    for row in summary_rows(res.records):
        table.add_row(literal(row["category"]), str(row["shapes"]), *(str(row[s]) for s in STATUSES),
                      end_section=row["category"] == "all")
    print_table(console, table)
    failed = [r for r in res.records if r.status == "failed"]
    if failed:
        ft = Table(title="Failed shapes")
        ft.add_column("id", no_wrap=True)
        ft.add_column("reason", overflow="fold")
        for r in failed:
            ft.add_row(literal(r.id), literal(r.reason))
        console.print(ft)
    console.print(
        f"{len(res.records)} shapes in {res.seconds:.1f} s ({res.n_skipped} up to date): "
        f"{res.count('kept')} kept -> {literal(res.out)}/summary.csv, {literal(res.out)}/shapes.csv",
        highlight=False, soft_wrap=True,
    )
