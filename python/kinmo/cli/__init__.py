"""The ``kinmo`` command line (Typer).

Commands are thin: they parse options and call the library. Each topic lives in its own
module of this package and registers itself on the apps of :mod:`kinmo.cli._apps`. Heavy
imports (torch, pybullet) happen inside the commands, so ``kinmo --help`` is instant.
"""

from kinmo.cli._apps import app, eval_app, train_app

# Importing a module registers its commands.
from kinmo.cli import prepare as _prepare  # noqa: F401,E402
from kinmo.cli import gnn as _gnn  # noqa: F401,E402
from kinmo.cli import predict as _predict  # noqa: F401,E402
from kinmo.cli import evaluate as _evaluate  # noqa: F401,E402
from kinmo.cli import synth as _synth  # noqa: F401,E402
from kinmo.cli import render as _render  # noqa: F401,E402
from kinmo.cli import axis as _axis  # noqa: F401,E402
from kinmo.cli import pseudo_label as _pseudo_label  # noqa: F401,E402
from kinmo.cli import ancsh as _ancsh  # noqa: F401,E402
from kinmo.cli import report as _report  # noqa: F401,E402
from kinmo.cli import pipeline as _pipeline  # noqa: F401,E402
from kinmo.cli import export as _export  # noqa: F401,E402
from kinmo.cli import view as _view  # noqa: F401,E402
from kinmo.cli import ranker as _ranker  # noqa: F401,E402
from kinmo.cli import user_format as _user_format  # noqa: F401,E402
from kinmo.cli import models as _models  # noqa: F401,E402
from kinmo.cli import oof as _oof  # noqa: F401,E402

__all__ = ["app", "eval_app", "train_app"]
