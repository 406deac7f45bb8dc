"""The rich progress bars of kinmo: per-shape stages (prepare, render, pseudo-label) and training loops."""

from __future__ import annotations

from typing import Any


def _rich_progress(title: str, fields: str) -> Any:
    """kinmo's rich progress layout on stderr: bold ``title`` and the task description, bar,
    done/total, ``fields`` (a rich ``TextColumn`` format), elapsed and remaining time."""
    from rich.console import Console
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )

    return Progress(
        TextColumn(f"[bold]{title}[/] {{task.description}}"),
        BarColumn(),
        MofNCompleteColumn(),
        TextColumn(fields),
        TimeElapsedColumn(),
        TimeRemainingColumn(),
        console=Console(stderr=True),
    )


class CountingBar:
    """A rich progress bar (on stderr) with running counters, e.g. of failures.

    A no-op when ``enabled`` is False. Use as a context manager.

    Parameters
    ----------
    total : int
        Number of items.
    enabled : bool
    title : str
        Bold prefix, e.g. ``"prepare"``.
    description : str
        Task description after the title.
    counters : dict of str to str
        Counter name → rich colour, shown as ``"<n> <name>"`` in that colour, in order.
    """

    def __init__(
        self, total: int, enabled: bool, title: str, description: str = "",
        counters: dict[str, str] | None = None,
    ) -> None:
        self.total, self.enabled = total, enabled
        self.title, self.description = title, description
        self.colours = dict(counters if counters is not None else {"failed": "red"})
        self.counts = {name: 0 for name in self.colours}
        self._progress: Any = None

    def __enter__(self) -> CountingBar:
        if self.enabled:
            fields = " ".join(
                f"[{colour}]{{task.fields[{name}]}} {name}[/]" for name, colour in self.colours.items()
            )
            self._progress = _rich_progress(self.title, fields)
            self._progress.__enter__()
            self._task = self._progress.add_task(self.description, total=self.total, **self.counts)
        return self

    def advance(self, n: int = 1, **increments: int) -> None:
        """Count ``n`` finished items and add ``increments`` to the named counters."""
        for name, inc in increments.items():
            self.counts[name] += int(inc)
        if self._progress is not None:
            self._progress.update(self._task, advance=n, **self.counts)

    def __exit__(self, *exc: Any) -> None:
        if self._progress is not None:
            self._progress.__exit__(*exc)


class TrainingBar:
    """The rich progress bar (on stderr) of kinmo's training loops (GNN, axis network, ANCSH).

    One bar per task (a training stage), each with a free-text ``info`` field (loss, accuracy)
    after the step count. A no-op when ``enabled`` is False (e.g. on the ranks other than 0
    of a ``torchrun`` run). Use as a context manager.

    Parameters
    ----------
    enabled : bool
    title : str
        Bold prefix of every task, e.g. ``"train gnn"``.
    """

    def __init__(self, enabled: bool, title: str) -> None:
        self.enabled, self.title = enabled, title
        self._progress: Any = None

    def __enter__(self) -> TrainingBar:
        if self.enabled:
            self._progress = _rich_progress(self.title, "{task.fields[info]}")
            self._progress.__enter__()
        return self

    def task(self, description: str, total: int) -> Any:
        """Add a task of ``total`` steps; returns its handle (None when disabled)."""
        if self._progress is None:
            return None
        return self._progress.add_task(description, total=total, info="")

    def advance(self, task: Any, n: int = 1, info: str | None = None) -> None:
        """Count ``n`` steps of ``task``, replacing its info text when given."""
        if self._progress is not None:
            fields = {} if info is None else {"info": info}
            self._progress.update(task, advance=n, **fields)

    def describe(self, task: Any, description: str) -> None:
        """Replace ``task``'s description."""
        if self._progress is not None:
            self._progress.update(task, description=description)

    def log(self, text: str) -> None:
        """Print a line above the bar (nothing when disabled)."""
        if self._progress is not None:
            self._progress.console.print(text, highlight=False, soft_wrap=True)

    def __exit__(self, *exc: Any) -> None:
        if self._progress is not None:
            self._progress.__exit__(*exc)
