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
