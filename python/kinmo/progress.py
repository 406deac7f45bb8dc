"""What kinmo shows on stderr while it works: rich progress bars and :mod:`logging` diagnostics.

Both go to one rich console on stderr (:func:`stderr_console`), so a diagnostic logged while a
progress bar is live is printed above the bar instead of breaking it.

- :class:`CountingBar`: the progress bar of the per-shape stages (prepare, render,
  pseudo-label, :mod:`kinmo.stages`) with running counters, e.g. of failures;
  :class:`TrainingBar`: the epoch / step bar of the training loops (:mod:`kinmo.train.loop`).
- Diagnostics (shapes skipped or resumed, failed shapes, worker failures, fallbacks) are
  records of the ``kinmo`` logger hierarchy (``logging.getLogger(__name__)`` in the module
  that emits them). :func:`setup_logging` gives that hierarchy one
  :class:`rich.logging.RichHandler` on the stderr console and its level: the command line
  calls it with the count of ``--verbose/-v`` (0: warnings, ``-v``: info, ``-vv``: debug);
  without ``-v`` the environment variable :data:`LOG_ENV` (``KINMO_LOG=info``, a level name
  or number) sets it. Library users configure :mod:`logging` as they like instead.
  That handler prints a warning (or a lower record) once: a record whose logger, level and
  message it has already printed is dropped (:class:`RepeatFilter`), so a long run's log does
  not repeat the same fallback for the same part once per model that predicts it. Errors are
  always printed.
"""

from __future__ import annotations

import logging
import os
from collections.abc import Mapping
from typing import Any

from kinmo.errors import KinmoError

__all__ = [
    "LOG_ENV", "LOG_WIDTH", "CountingBar", "RepeatFilter", "TrainingBar", "console", "literal", "log_level", "plain",
    "print_table", "setup_logging", "stderr_console",
]

#: Environment variable giving the ``kinmo`` loggers' level when ``-v`` is not given.
LOG_ENV = "KINMO_LOG"

_CONSOLE: Any = None
#: Width of the stderr console when it writes to a file or pipe, not a terminal.
LOG_WIDTH = 200


def stderr_console() -> Any:
    """The rich :class:`~rich.console.Console` on stderr shared by progress bars and logging.

    It writes to whatever ``sys.stderr`` is at the time (so captured streams of tests work).
    """
    global _CONSOLE
    if _CONSOLE is None:
        from rich.console import Console

        _CONSOLE = Console(stderr=True, emoji=False, highlight=False)
        if not _CONSOLE.is_terminal and "COLUMNS" not in os.environ:
            # a log file (a cluster job): bars and their metrics never cut to 80 columns
            _CONSOLE = Console(stderr=True, emoji=False, highlight=False, width=LOG_WIDTH)
    return _CONSOLE


def console(stderr: bool = False, **kw: Any) -> Any:
    """A rich console for a command's report: no emoji codes (``:x:`` stays text), no
    automatic highlighting, :data:`LOG_WIDTH` columns when it writes to a file or pipe.
    Names in its messages go through :func:`literal`."""
    from rich.console import Console

    kw = {"emoji": False, "highlight": False, "soft_wrap": True, **kw}
    c = Console(stderr=stderr, **kw)
    if "width" not in kw and not c.is_terminal and "COLUMNS" not in os.environ:
        # a log file or pipe (a cluster job): tables are laid out at LOG_WIDTH columns,
        # never cut to 80 with an ellipsis
        c.width = LOG_WIDTH
    return c


def print_table(console: Any, table: Any) -> None:
    """Print a rich table on ``console``; in a log file or pipe, at the table's full width.

    A terminal lays the table out at its own width, as rich does. A console that is not a
    terminal (:func:`console` gives it :data:`LOG_WIDTH` columns) is widened for this one table
    to the width the table needs, so a wide one (Table 2 of a category with four joints) keeps
    one line per row instead of wrapping its cells over several.
    """
    if console.is_terminal:
        console.print(table)
        return
    from rich.measure import Measurement

    need = Measurement.get(console, console.options.update_width(1_000_000), table).maximum
    width = console.width
    console.width = max(width, need)
    try:
        console.print(table)
    finally:
        console.width = width


def literal(text: object) -> str:
    """``text`` (a name from an input file, a path, an error message) as literal rich text.

    Square brackets are escaped so rich never reads them as markup (``brk[old]/`` prints as
    is and ``[/]`` cannot raise :class:`rich.errors.MarkupError`); characters UTF-8 cannot
    encode (lone surrogates of non-UTF-8 file names) become ``\\udcxx`` escapes and control
    characters ``\\xNN`` escapes, so a name can never move the cursor or end a line. Emoji
    codes are left alone: the consoles of :func:`console` and :func:`stderr_console` do not
    replace them.

    Source: issue 21, finding 6 (printed names are literal text).
    """
    from rich.markup import escape

    return escape(plain(text))


def plain(text: object) -> str:
    """``text`` with lone surrogates as ``\\udcxx`` and other unprintable characters (control
    characters, line breaks) as ``\\xNN`` escapes: one line, safe on any terminal. For places
    that never read markup (the description columns of the progress bars)."""
    s = str(text).encode("utf-8", "backslashreplace").decode("utf-8")
    return "".join(c if c.isprintable() or c == " " else f"\\x{ord(c):02x}" for c in s)


def log_level(verbosity: int = 0, environ: Mapping[str, str] | None = None) -> int:
    """The ``kinmo`` loggers' level for ``verbosity`` (count of ``-v``) and :data:`LOG_ENV`.

    Parameters
    ----------
    verbosity : int
        0: :data:`LOG_ENV` if set, else ``WARNING``; 1: ``INFO``; 2 or more: ``DEBUG``.
    environ : mapping, optional
        ``os.environ`` by default.

    Returns
    -------
    int
        A :mod:`logging` level.

    Raises
    ------
    KinmoError
        :data:`LOG_ENV` holds neither a level name (``debug``, ``info``, ``warning``,
        ``error``) nor a number.
    """
    if verbosity >= 2:
        return logging.DEBUG
    if verbosity == 1:
        return logging.INFO
    value = (os.environ if environ is None else environ).get(LOG_ENV, "").strip()
    if not value:
        return logging.WARNING
    if value.isdigit():
        return int(value)
    level = logging.getLevelName(value.upper())
    if not isinstance(level, int):

        raise KinmoError(f"{LOG_ENV}={value!r}: expected debug, info, warning, error or a number")
    return level


class RepeatFilter(logging.Filter):
    """Drops a record below ``ERROR`` whose logger name, level and message this filter has
    already let through (module docstring); errors and above always pass.

    It remembers at most ``limit`` messages; past that, new messages pass and are not
    remembered, so memory stays bounded on runs over many shapes.
    """

    def __init__(self, limit: int = 100_000) -> None:
        super().__init__()
        self.limit = limit
        self._seen: set[tuple[str, int, str]] = set()

    def filter(self, record: logging.LogRecord) -> bool:
        if record.levelno >= logging.ERROR:
            return True
        key = (record.name, record.levelno, record.getMessage())
        if key in self._seen:
            return False
        if len(self._seen) < self.limit:
            self._seen.add(key)
        return True


def setup_logging(verbosity: int = 0, environ: Mapping[str, str] | None = None) -> logging.Logger:
    """Give the ``kinmo`` logger its level (:func:`log_level`) and one rich handler on stderr.

    Calling it again replaces the handler it installed before (never stacks them).

    Returns
    -------
    logging.Logger
        The ``kinmo`` logger.
    """
    from rich.logging import RichHandler

    log = logging.getLogger("kinmo")
    log.setLevel(log_level(verbosity, environ))
    for h in list(log.handlers):
        if getattr(h, "_kinmo", False):
            log.removeHandler(h)
    handler = RichHandler(console=stderr_console(), show_path=False, markup=False,
                          rich_tracebacks=False)
    handler._kinmo = True  # type: ignore[attr-defined]
    handler.addFilter(RepeatFilter())
    log.addHandler(handler)
    return log


def _rich_progress(title: str, fields: str, markup_fields: bool = True) -> Any:
    """kinmo's rich progress layout on stderr: bold ``title`` and the task description, bar,
    done/total, ``fields`` (a rich ``TextColumn`` format, read as markup when ``markup_fields``),
    elapsed and remaining time. The description is never read as markup (it often holds a
    folder name)."""
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )

    return Progress(
        TextColumn(f"[bold]{literal(title)}[/]"),
        TextColumn("{task.description}", markup=False),
        BarColumn(),
        MofNCompleteColumn(),
        TextColumn(fields, markup=markup_fields),
        TimeElapsedColumn(),
        TimeRemainingColumn(),
        console=stderr_console(),
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
            self._task = self._progress.add_task(plain(self.description), total=self.total,
                                                 **self.counts)
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
            self._progress = _rich_progress(self.title, "{task.fields[info]}", markup_fields=False)
            self._progress.__enter__()
        return self

    def task(self, description: str, total: int) -> Any:
        """Add a task of ``total`` steps; returns its handle (None when disabled)."""
        if self._progress is None:
            return None
        return self._progress.add_task(plain(description), total=total, info="")

    def advance(self, task: Any, n: int = 1, info: str | None = None) -> None:
        """Count ``n`` steps of ``task``, replacing its info text when given."""
        if self._progress is not None:
            fields = {} if info is None else {"info": plain(info)}
            self._progress.update(task, advance=n, **fields)

    def describe(self, task: Any, description: str) -> None:
        """Replace ``task``'s description."""
        if self._progress is not None:
            self._progress.update(task, description=plain(description))

    def log(self, text: str) -> None:
        """Print a line above the bar (nothing when disabled)."""
        if self._progress is not None:
            self._progress.console.print(text, highlight=False, soft_wrap=True)

    def __exit__(self, *exc: Any) -> None:
        if self._progress is not None:
            self._progress.__exit__(*exc)
