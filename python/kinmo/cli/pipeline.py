"""``kinmo train all`` and ``kinmo demo``: the whole pipeline (:mod:`kinmo.pipeline`)."""

from __future__ import annotations

from pathlib import Path

import typer

import kinmo.cli._values as _values

from kinmo.cli._apps import app, train_app


@train_app.command("all")
def train_all(
    labeled: Path | None = typer.Option(None, "--labeled", help="PartNet-Mobility folders (labelled objects); default: found as described above."),
    unlabeled: Path | None = typer.Option(None, "--unlabeled", help="PartNet folders to pseudo-label; default: found as described above."),
    out: Path = typer.Option(Path("runs/all"), "--out", help="Run folder (resumes if it exists)."),
    preset: str = typer.Option("quick", envvar="KINMO_PRESET",
                               help="quick (2 CPU cores), paper (GPU) or tiny (seconds per stage: a check, not results)."),
    category: list[str] | None = typer.Option(None, "--category", help="ANCSH categories (repeatable)."),
    labeled_fraction: float = typer.Option(1.0, callback=_values.finite, help="Share of labelled training objects for ANCSH."),
    seed: int = typer.Option(0),
    ancsh_seeds: int = typer.Option(1, "--ancsh-seeds", min=1, max=10,
                                    help="Train ANCSH this many times (seeds seed, seed+1, ...): Table 2 gives mean and spread."),
    ancsh_synth: int = typer.Option(0, "--ancsh-synth", min=0, max=100000,
                                    help="Add N generated objects of each trained structure kinmo synth makes to ANCSH's labelled data."),
    ancsh_synth_as: str = typer.Option("mix", "--ancsh-synth-as",
                                       help="mix (in the same batches, half the draws) or pretrain (the first half of "
                                            "the epochs, then fine-tuning on real): how --ancsh-synth objects are used."),
    workers: int = typer.Option(0, "--workers", "-j", help="Processes for per-shape stages, and models trained at once (motion GNNs, axis network, the ranker's fold GNNs; 0: all cores)."),
    skip_ancsh: bool = typer.Option(False, "--skip-ancsh", help="Stop after the pseudo-labels (Table 1 only)."),
    render: bool = typer.Option(True, "--render/--no-render", help="Render Table 1 predictions for the gallery."),
    refine: bool = typer.Option(True, "--refine/--no-refine",
                                help="Train the axis network (OBB rows of Table 1, pseudo-labels)."),
    synth_extra: int = typer.Option(0, "--synth-extra", min=0,
                                    help="Also train with N generated objects added; the report compares."),
    synth_as: str = typer.Option("labeled", "--synth-as",
                                 help="labeled or unlabeled: how the generated objects are used."),
    synth_seed: int | None = typer.Option(None, "--synth-seed",
                                          help="Seed of the generated objects (default seed+500)."),
    selector: str = typer.Option("learned", "--selector",
                                 help="learned (a ranker fit on out-of-fold GNNs; Table 1 adds the paper's rows) "
                                      "or paper (0.5/0.3/0.2): how refinement picks an axis."),
    gnn_members: int = typer.Option(0, "--gnn-members", min=0, max=16, help="Ensemble members of every motion GNN (seeds seed+1, ...): each GNN, the ranker's fold GNNs included, predicts as the average of 1 + N models (kinmo extension; N+1 times the GNN training time)."),
    release: bool = typer.Option(False, "--release", help="Also train the release bundle OUT/release/model: the fine GNN, the coarse GNN (its check/ for pseudo-labelling) and the axis network again on every labelled object and the kept pseudo-labels (the pretrained model's recipe)."),
    release_synth: int | None = typer.Option(None, "--release-synth", min=0, max=100000, show_default=False,
                                             help="With --release: N generated objects (kinmo synth, seed --synth-seed) added to the release fine GNN's training (default 120; 0: none)."),
    train_synth: int | None = typer.Option(None, "--train-synth", min=0, max=100000, show_default=False,
                                           help="N generated objects (kinmo synth, seed --synth-seed) added to the training of the motion GNNs and the ranker's fold GNNs (never to the test objects, the axis network or ANCSH; default 0: none; 120 helped Table 1 out of fold but cut Table 2's semi-weakly gain, docs/results/table2.md)."),
) -> None:
    """Prepare, train the motion GNN, the axis network and the ranker, pseudo-label, render and train
    ANCSH in three settings, evaluate (Tables 1 and 2) and write the report.

    Data, without --labeled / --unlabeled: for each of PartNet-Mobility (labelled) and PartNet
    (unlabelled), the source folder of a cache that `kinmo prepare DIR` wrote under ./cache/,
    else ./partnet-mobility and ./partnet, else $KINMO_DATA/partnet-mobility and
    $KINMO_DATA/partnet.

    With --synth-extra N, everything is trained and evaluated a second time, into
    OUT/synth-extra-<as>-<N>, with N procedurally generated objects (kinmo synth, of the labelled
    categories it supports) added as labelled training objects or as unlabelled shapes to
    pseudo-label; the test objects stay the real ones and the report's section "Generated
    shapes" says whether they helped.

    With --release, the release bundle is trained after the baseline (nothing held out; the
    baseline's Table 1 measures its recipe): what ships as kinmo's pretrained model. Its fine
    GNN also trains on --release-synth generated objects (default 120, kinmo synth of the
    labelled categories it makes; docs/results/foreign_assets.md)."""
    from kinmo.progress import console as new_console

    from kinmo.cli._errors import cli_errors, fail
    from kinmo.pipeline import TINY, PipelineConfig, find_data, missing_data_message, run_pipeline

    console = new_console(stderr=True)
    found = find_data(labeled=labeled, unlabeled=unlabeled)
    if found.labeled is None:
        fail(missing_data_message())
    console.print(f"data: labelled {found.labeled} ({found.why_labeled}); unlabelled "
                  + (f"{found.unlabeled} ({found.why_unlabeled})" if found.unlabeled is not None
                     else "none (no PartNet folder found: supervised ANCSH only)"), highlight=False, soft_wrap=True)
    with cli_errors(1, also=(ValueError,)):
        cfg = PipelineConfig(
            labeled=found.labeled, unlabeled=found.unlabeled if (refine or unlabeled is not None) else None, out=out,
            preset="quick" if preset == "tiny" else preset, categories=category or None,
            labeled_fraction=labeled_fraction, seed=seed, ancsh_seeds=ancsh_seeds,
            ancsh_synth=ancsh_synth, ancsh_synth_as=ancsh_synth_as, workers=workers, skip_ancsh=skip_ancsh,
            render=render, refine=refine, synth_extra=synth_extra, synth_as=synth_as, synth_seed=synth_seed,
            selector=selector, release=release, gnn_members=gnn_members,
            **({} if release_synth is None else {"release_synth": release_synth}),
            **({} if train_synth is None else {"train_synth": train_synth}),
            **(TINY if preset == "tiny" else {}),
        )
        res = run_pipeline(cfg, console=console)
    console.print(f"[green]done[/]: report at {res.report}")


@app.command("demo")
def demo(
    out: Path = typer.Option(Path("runs/demo"), "--out", help="Run folder."),
    data: Path | None = typer.Option(None, "--data", help="Real PartNet-Mobility folders instead of generated objects."),
    unlabeled: Path | None = typer.Option(None, "--unlabeled", help="Real PartNet folders (with --data)."),
    n: int = typer.Option(24, "--n", help="Generated labelled objects."),
    seed: int = typer.Option(0),
    tiny: bool = typer.Option(False, help="A minimal configuration (seconds per stage), for tests."),
    selector: str = typer.Option("learned", "--selector", help="learned (the default ranker) or paper (0.5/0.3/0.2 with the axis network): the axis selector of Table 1's OBB rows and the pseudo-labels."),
) -> None:
    """The whole pipeline on objects kinmo generates itself: synth, prepare, train all (quick),
    pseudo-label, eval, report."""
    from kinmo.progress import console as new_console

    from kinmo.cli._errors import cli_errors
    from kinmo.pipeline import run_demo

    console = new_console(stderr=True)
    with cli_errors(1, also=(ValueError,)):
        res = run_demo(out, n_labeled=n, n_unlabeled=max(n // 2, 2), seed=seed, data=data, unlabeled=unlabeled,
                       tiny=tiny, console=console, selector=selector)
    console.print(f"[green]done[/]: open {res.report}")
