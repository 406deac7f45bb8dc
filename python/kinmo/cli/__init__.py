"""The ``kinmo`` command line (Typer).

Commands are thin: they parse options and call the library. Each topic lives in its own
module of this package and registers itself on the apps of :mod:`kinmo.cli._apps`. Heavy
imports (torch, pybullet) happen inside the commands, so ``kinmo --help`` is instant.
"""

from kinmo.cli._apps import app, eval_app, train_app

# Importing a module registers its commands.
from kinmo.cli import prepare as _prepare  # noqa: F401,E402

__all__ = ["app", "eval_app", "train_app"]
