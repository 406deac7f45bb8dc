"""``kinmo train ancsh`` and ``kinmo eval --category C``: ANCSH on partial scans, paper Table 2
(:mod:`kinmo.ancsh.train`, :mod:`kinmo.ancsh.evaluate`)."""

from __future__ import annotations

import os
import re
from pathlib import Path
from typing import Optional

import typer

import kinmo.cli._values as _values

from kinmo.cli._apps import eval_app, train_app


def _snake(name: str) -> str:
    """``StorageFurniture`` -> ``storage_furniture``; other spellings lower-cased."""
    s = re.sub(r"(?<=[a-z0-9])(?=[A-Z])", "_", name.strip())
    return re.sub(r"[\s\-]+", "_", s).lower()


def _single_blas_thread() -> None:
    """numpy / scipy BLAS on one thread unless the user chose otherwise: the post-processing
    solves many tiny least-squares problems, which multi-threaded OpenBLAS slows down by up to
    20x on busy machines. Effective when numpy is not imported yet (the normal CLI case)."""
    for var in ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):  # not OMP: torch uses it
        os.environ.setdefault(var, "1")


def _default_data(sub: str) -> Optional[Path]:  # noqa: UP007
    root = os.environ.get("KINMO_DATA")
    return Path(root) / sub if root else None


@train_app.command("ancsh")
def train_ancsh_cmd(
    category: str = typer.Option(..., "--category", "-c", help="Object category, any case or snake_case (laptop, storage_furniture)."),
    setting: str = typer.Option("supervised", "--setting", "-s", help="supervised, semi (self-training on unlabelled PartNet scans) or semi-weakly (adds `kinmo pseudo-label` shapes)."),
    out: Optional[Path] = typer.Option(None, "--out", "-o", help="Run folder (default: runs/ancsh/<category>/<setting>)."),  # noqa: UP007
    preset: str = typer.Option("quick", "--preset", envvar="KINMO_PRESET", help="quick (CPU, minutes), paper (ANCSH's sizes, GPU) or tiny (seconds: a check, not results)."),
    labeled_fraction: Optional[float] = typer.Option(None, "--labeled-fraction", min=0.0, max=1.0, callback=_values.finite, help="Share of the labelled training objects used (default: 1)."),  # noqa: UP007
    seed: Optional[int] = typer.Option(None, "--seed", help="Seed of the split, renders, initialisation and sampling (default: 0)."),  # noqa: UP007
    data: Optional[Path] = typer.Option(None, "--data", "-d", help="PartNet-Mobility dataset folder (default: $KINMO_DATA/partnet-mobility)."),  # noqa: UP007
    partnet: Optional[Path] = typer.Option(None, "--partnet", help="semi: PartNet folder of unlabelled shapes (default: DATA/../partnet)."),  # noqa: UP007
    pseudo: Optional[Path] = typer.Option(None, "--pseudo", help="semi-weakly: output folder of `kinmo pseudo-label`."),  # noqa: UP007
    split: Optional[Path] = typer.Option(None, "--split", help="A split.json (e.g. the GNN run's) instead of making one."),  # noqa: UP007
    scans: Optional[Path] = typer.Option(None, "--scans", help="Render cache, shareable by the runs of an experiment (default: OUT/scans)."),  # noqa: UP007
    init: Optional[Path] = typer.Option(None, "--init", help="A supervised run. semi: start from it instead of retraining it; semi-weakly: its weights when no pseudo-labelled shape fits (the same training)."),  # noqa: UP007
    epochs: Optional[int] = typer.Option(None, "--epochs", min=1, help="Override the preset's epochs."),  # noqa: UP007
    steps_per_epoch: Optional[int] = typer.Option(None, "--steps-per-epoch", min=1, help="Override the preset's batches per epoch."),  # noqa: UP007
    semi_epochs: Optional[int] = typer.Option(None, "--semi-epochs", min=1, help="semi: epochs on labelled + pseudo-targeted scans."),  # noqa: UP007
    frames_per_object: Optional[int] = typer.Option(None, "--frames-per-object", min=1, help="Training scans per object."),  # noqa: UP007
    batch_size: Optional[int] = typer.Option(None, "--batch-size", min=2, help="Scans per step."),  # noqa: UP007
    device: Optional[str] = typer.Option(None, "--device", callback=_values.device, help="auto, cpu, cuda, cuda:1 ... (default: auto)."),  # noqa: UP007
    threads: Optional[int] = typer.Option(None, "--threads", min=0, help="CPU threads for torch (0: torch's default)."),  # noqa: UP007
    workers: Optional[int] = typer.Option(None, "--workers", "-j", min=0, help="Rendering processes (0: one per CPU, 1: none)."),  # noqa: UP007
    synth: Optional[int] = typer.Option(None, "--synth", min=0, max=100000, help="Add N generated objects of the trained structure (kinmo synth) to the labelled scans."),  # noqa: UP007
    synth_as: Optional[str] = typer.Option(None, "--synth-as", help="mix (same batches, --synth-share of the draws; default) or pretrain (the first --synth-share of the epochs, then real)."),  # noqa: UP007
    synth_share: Optional[float] = typer.Option(None, "--synth-share", min=0.0, max=1.0, callback=_values.finite, help="Share of draws (mix) or epochs (pretrain) on generated scans (default: 0.5)."),  # noqa: UP007
    quiet: bool = typer.Option(False, "--quiet", "-q", help="No progress bars."),
) -> None:
    """Train ANCSH on rendered partial scans of one category (Liu et al. 2023, Table 2).

    Renders scans of the category's labelled training objects (random joint states and
    viewpoints), trains ANCSH, and for `semi` / `semi-weakly` adds unlabelled or
    pseudo-labelled PartNet shapes. Writes model.pt, config.json, split.json, metrics.csv
    and data.json to OUT. Test objects of the split are never used.
    """
    _single_blas_thread()
    from kinmo.progress import console as new_console, literal

    from kinmo.ancsh.config import SETTINGS
    from kinmo.ancsh.config import preset as make_preset
    from kinmo.ancsh.train import train_ancsh
    from kinmo.cli._errors import cli_errors, fail

    console = new_console()
    if setting not in SETTINGS:
        fail(f"--setting must be one of {', '.join(SETTINGS)}, got {setting!r}", 2)
    data = data or _default_data("partnet-mobility")
    if data is None:
        fail("give --data (the PartNet-Mobility folder) or set KINMO_DATA", 2)
    with cli_errors(2, also=(ValueError,)):
        cfg = make_preset(preset, labeled_fraction=labeled_fraction, seed=seed, epochs=epochs,
                          steps_per_epoch=steps_per_epoch, semi_epochs=semi_epochs,
                          frames_per_object=frames_per_object,
                          batch_size=batch_size, device=device, threads=threads, render_workers=workers,
                          synth_objects=synth, synth_as=synth_as, synth_share=synth_share)
    out = out or Path("runs") / "ancsh" / _snake(category) / setting
    with cli_errors(1):
        res = train_ancsh(category, setting, out, cfg, data=data, partnet=partnet, pseudo=pseudo,
                          split=split, scans=scans, init=init, progress=not quiet, console=console)
    last = res.history[-1]
    d = res.data
    console.print(
        f"trained ANCSH ({res.config.preset}, {setting}) for {res.config.category} "
        f"{literal('[' + res.structure.signature() + ']')} in {res.seconds:.1f} s on {d['labeled_scans']} labelled, "
        f"{d['pseudo_labeled_scans']} pseudo-labelled, {d['pseudo_target_scans']} pseudo-target and "
        f"{d['generated_scans']} generated scans: "
        f"loss {last['loss']:.3f}, segmentation accuracy {last['seg_acc']:.3f}",
        highlight=False, soft_wrap=True,
    )
    console.print(f"run folder: {literal(res.run_dir)}", highlight=False, soft_wrap=True)


@eval_app.callback()
def eval_ancsh_cmd(
    ctx: typer.Context,
    category: Optional[str] = typer.Option(None, "--category", "-c", help="Category to evaluate ANCSH on (paper Table 2), any case or snake_case."),  # noqa: UP007
    runs: Optional[list[Path]] = typer.Option(None, "--runs", "-r", help="ANCSH run folder(s), or folders holding them (default: those of the last `kinmo train all`, runs/all/ancsh/<Category>, else runs/ancsh/<category>)."),  # noqa: UP007
    data: Optional[Path] = typer.Option(None, "--data", "-d", help="PartNet-Mobility dataset folder (default: the runs' dataset, its test objects); another folder: every fitting object there the runs did not train on."),  # noqa: UP007
    out: Optional[Path] = typer.Option(None, "--out", "-o", help="Folder for table2.csv, table2.md, frames.csv (default: RUNS/eval-<category>)."),  # noqa: UP007
    scans: Optional[Path] = typer.Option(None, "--scans", help="Render cache of the test scans (default: OUT/scans)."),  # noqa: UP007
    frames: Optional[int] = typer.Option(None, "--frames", min=1, help="Scans per test object (default: the run's preset)."),  # noqa: UP007
    seed: int = typer.Option(0, "--seed", help="Seed of the test renders and point sampling."),
    device: str = typer.Option("auto", "--device", callback=_values.device, help="auto, cpu, cuda ..."),
    workers: int = typer.Option(0, "--workers", "-j", min=0, help="Rendering processes (0: one per CPU, 1: none)."),
    symmetric: bool = typer.Option(True, "--symmetry/--no-symmetry", help="Evaluate rotationally symmetric parts (bucket bodies, dials) up to their symmetry axis, as NOCS / ANCSH do."),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="No progress bar."),
) -> None:
    """Evaluate models. With --category: ANCSH on partial scans of the held-out objects, one
    row per training setting (paper Table 2): part rotation / translation errors, 3D IoU,
    joint state, axis angle and axis distance errors, next to the paper's means. A category
    with one model per kinematic structure: each object is evaluated with the model of its
    structure and the row averages all of them. Interchangeable parts (leaf siblings with one
    joint type, e.g. two doors) are also scored permutation-matched, beside the raw errors."""
    if ctx.invoked_subcommand is not None:
        return
    _single_blas_thread()
    from kinmo.progress import console as new_console, literal, print_table

    console = new_console()
    if not console.is_terminal:  # pipes and logs: do not squeeze the 9-column tables
        console = new_console(width=max(console.width, 140))
    if category is None:
        console.print(ctx.get_help())
        raise typer.Exit(0)

    from kinmo.ancsh.evaluate import evaluate_category, paper_table
    from kinmo.cli._errors import cli_errors, fail

    if runs:
        run_paths = list(runs)
    else:
        from kinmo.pipeline import category_runs

        found = category_runs(category)
        if found.runs is None:
            fail(found.message)
        new_console(stderr=True).print(f"{literal(found.category)}: {literal(found.message)}", highlight=False, soft_wrap=True)
        run_paths, category = [found.runs], found.category
        if scans is None and found.scans is not None and data is None:
            scans = found.scans  # the test scans `kinmo train all` rendered
    with cli_errors(1):
        rows, paths = evaluate_category(category, run_paths, data=data, out=out, scans=scans, frames=frames,
                                        seed=seed, device=device, workers=workers, progress=not quiet,
                                        console=console, symmetric=symmetric)
    print_table(console, paper_table(rows, category))
    console.print(f"wrote {paths['csv']}, {paths['markdown']} and {paths['frames']}", highlight=False,
                  soft_wrap=True)
