"""The rich progress bar of kinmo's per-shape stages (prepare, render, pseudo-label)."""

from __future__ import annotations

from typing import Any


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
            from rich.console import Console
            from rich.progress import (
                BarColumn,
                MofNCompleteColumn,
                Progress,
                TextColumn,
                TimeElapsedColumn,
                TimeRemainingColumn,
            )

            fields = " ".join(
                f"[{colour}]{{task.fields[{name}]}} {name}[/]" for name, colour in self.colours.items()
            )
            self._progress = Progress(
                TextColumn(f"[bold]{self.title}[/] {{task.description}}"),
                BarColumn(),
                MofNCompleteColumn(),
                TextColumn(fields),
                TimeElapsedColumn(),
                TimeRemainingColumn(),
                console=Console(stderr=True),
            )
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
