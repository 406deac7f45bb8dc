"""``kinmo export``: a PartNet-Mobility folder as URDF, MJCF, USD, glTF (:mod:`kinmo.export`)."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

from collections.abc import Iterator
from contextlib import contextmanager

import typer

import kinmo.cli._values as _values

from kinmo.cli._apps import app

#: Help of the repeatable ``--format`` option (shared by predict and pseudo-label).
FORMAT_HELP = ("Output format, repeatable: mobility_v2, semantics, urdf, mjcf, usd, gltf "
               "(see kinmo.export).")

#: Help of ``--collision`` (export, predict, pseudo-label).
COLLISION_HELP = ("Collision geometry of URDF/MJCF: parts (convex hull of each part mesh, "
                  "concave ones split into convex pieces; milliseconds), hull (convex hull of "
                  "each part mesh), vhacd (V-HACD per link; seconds), coacd (CoACD per link; "
                  "needs `pip install coacd`). See docs/results/collision.md.")


def check_formats(fmt: list[str] | None) -> None:
    """Reject unknown ``--format`` values before any work (exit code 2, the known ones named)."""
    from kinmo.export import formats

    known = formats()
    bad = [f for f in fmt or [] if f not in known]
    if bad:
        raise typer.BadParameter(f"unknown format(s) {', '.join(bad)}; known: {', '.join(known)}",
                                 param_hint="--format")


@contextmanager
def _locked(out: Path, inputs: list[Path], command: str = "kinmo export") -> Iterator[None]:
    """The checks and lock every writing command takes on its OUT (issue 21, finding 12):
    outputs apart from inputs, SIGTERM runs the cleanups (temporary folders of V-HACD, the
    staged object), one run per OUT at a time."""
    from kinmo.io import check_outputs_apart, folder_lock, output_dir
    from kinmo.parallel import sigterm_raises

    check_outputs_apart(out, inputs)
    with sigterm_raises(), folder_lock(output_dir(out), command):
        yield


@app.command("export")
def export_cmd(
    src: Path = typer.Argument(..., metavar="SRC", exists=True, file_okay=False, help="A PartNet-Mobility-format folder (real, generated or predicted), or a folder of them."),
    fmt: list[str] = typer.Option(..., "--format", "-f", help=FORMAT_HELP),
    out: Path = typer.Option(..., "--out", "-o", help="Output folder (OUT/<id>/ per object when SRC holds several)."),
    source: Optional[Path] = typer.Option(None, "--source", "-s", exists=True, file_okay=False, help="For a `kinmo predict` output SRC (mobility_v2.json only): the shape folder it was predicted for (meshes)."),  # noqa: UP007
    collision: str = typer.Option("parts", "--collision", callback=_values.collision, help=COLLISION_HELP),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="No progress bar."),
) -> None:
    """Write the articulated object(s) in SRC in each --format, loadable by its simulator.

    urdf: PyBullet/SAPIEN/ROS (convex collision pieces); mjcf: MuJoCo; usd: Isaac Sim
    (UsdPhysics joints); gltf: any 3D viewer, one animation per joint.
    """
    from kinmo.progress import console as new_console, literal

    from kinmo.cli._errors import cli_errors
    from kinmo.data.readers import find_shapes
    from kinmo.export import export_folder

    check_formats(fmt)
    console = new_console()
    with cli_errors(1), _locked(out, [src, *([source] if source is not None else [])]):
        if source is not None or not find_shapes(src):
            if (src / "mobility_v2.json").is_file():  # one predicted folder
                files = export_folder(src, out, fmt, source=source, collision=collision,
                                      progress=not quiet)
                console.print(f"exported 1 object as {', '.join(dict.fromkeys(fmt))}: "
                              f"{sum(len(v) for v in files.values())} file(s) -> {literal(out)}",
                              highlight=False)
                return
        folders = find_shapes(src)
        if not folders:
            from kinmo.errors import KinmoDataError

            raise KinmoDataError(src, "no PartNet-Mobility folder found")
        single = len(folders) == 1 and folders[0].resolve() == src.resolve()
        n = 0
        for folder in folders:
            files = export_folder(folder, out if single else out / folder.name, fmt,
                                  collision=collision, progress=not quiet)
            n += sum(len(v) for v in files.values())
    console.print(f"exported {len(folders)} object(s) as {', '.join(dict.fromkeys(fmt))}: "
                  f"{n} file(s) -> {literal(out)}", highlight=False)
