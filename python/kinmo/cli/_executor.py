"""The ``--executor`` option of the per-shape commands (:mod:`kinmo.executor`)."""

from __future__ import annotations

import typer


def _check(value: str) -> str:
    from kinmo.errors import KinmoError
    from kinmo.executor import parse_executor

    try:
        parse_executor(value)
    except KinmoError as e:
        raise typer.BadParameter(str(e)) from None
    return value


EXECUTOR: str = typer.Option(
    "local", "--executor", callback=_check, metavar="local|ray[:ADDRESS]",
    help="Where the per-shape work runs: local (process pool of --workers), ray (a Ray started "
         "here with --workers CPUs, 0: all), ray:auto (the running Ray cluster) or "
         "ray:ADDRESS. Ray needs `pip install kinmo[ray]`.",
)
"""``--executor``: ``local``, ``ray``, ``ray:auto`` or ``ray:ADDRESS``."""
