"""Load one of the repository's scripts (``bench/*.py``, ``scripts/*.py``) as a module, for the
tests of the functions inside it."""

from __future__ import annotations

import importlib.util
from pathlib import Path
from types import ModuleType

#: The repository's root (the folder holding ``bench/`` and ``scripts/``).
REPO = Path(__file__).resolve().parent.parent


def load_script(relative: str) -> ModuleType:
    """The script at ``REPO / relative`` (e.g. ``"bench/bench_ancsh.py"``), executed as a
    module named after its file."""
    path = REPO / relative
    spec = importlib.util.spec_from_file_location(path.stem, path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod
