"""Exceptions raised by kinmo.

Every error caused by bad input names the file (or argument) and the problem in one line,
so a failed shape can be recorded in a manifest and reported without a traceback.
"""

from __future__ import annotations

from pathlib import Path


class KinmoError(Exception):
    """Base class of kinmo's own exceptions."""


class KinmoDataError(KinmoError, ValueError):
    """A dataset file is missing, malformed or inconsistent.

    Parameters
    ----------
    path : str or Path
        The offending file (or folder).
    problem : str
        One line saying what is wrong.
    """

    def __init__(self, path: str | Path, problem: str) -> None:
        self.path = str(path)
        self.problem = problem
        super().__init__(f"{self.path}: {problem}")


class KinmoUsageError(KinmoError):
    """A command was asked to do something it refuses before any work (the command line
    exits with code 2): an output that would overwrite an input, an option out of range.

    Parameters
    ----------
    path : str or Path
        The offending argument (an ``--out`` folder, a file).
    problem : str
        One line saying what is wrong and what to do instead.
    """

    def __init__(self, path: str | Path, problem: str) -> None:
        self.path = str(path)
        self.problem = problem
        super().__init__(f"{self.path}: {problem}")


class KinmoTrainingError(KinmoError):
    """Training diverged: a loss, gradient or parameter became ``nan`` or ``inf`` (for
    instance with a learning rate far too large). No model is saved.

    Parameters
    ----------
    what : str
        The training run or checkpoint concerned.
    problem : str
        One line: what became non-finite and at which step, and what to try instead.
    """

    def __init__(self, what: str | Path, problem: str) -> None:
        self.path = str(what)
        self.problem = problem
        super().__init__(f"{self.path}: {problem}")
