"""The one error handler of the command line.

Every command turns the errors a user can cause (bad data, a damaged cache or checkpoint, an
output path that is a file, a folder locked by another run) into one red line on stderr,
``error: <file>: <problem>``, and an exit code, never a traceback:

- :func:`cli_errors`: a context manager around a command's library call; it catches
  :class:`~kinmo.errors.KinmoError` (and its family, e.g.
  :class:`~kinmo.errors.KinmoDataError`), file-system errors that name a file
  (:class:`OSError` with a ``filename``: an ``--out`` that is a file, a missing folder, no
  permission, a full disk) and any extra exception types the command names (e.g.
  :class:`ValueError` for option validation);
- :func:`fail`: print one such line and exit, for checks made in the command itself.

Everything else (a bug) keeps its traceback.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from typing import NoReturn

import typer

__all__ = ["cli_errors", "error_line", "fail", "printable"]


def printable(text: str) -> str:
    """``text`` with characters UTF-8 cannot encode (the lone surrogates by which Python
    represents non-UTF-8 file names) shown as ``\\udcxx`` escapes, so printing it never
    raises :class:`UnicodeEncodeError`, whatever the terminal's error handler."""
    return text.encode("utf-8", "backslashreplace").decode("utf-8")


def error_line(e: BaseException | str) -> str:
    """One printable line for an exception (or a message).

    Whitespace runs (newlines included) become one space; characters the terminal cannot
    encode (lone surrogates of non-UTF-8 file names) are shown as ``\\udcxx`` escapes. An
    :class:`OSError` reads ``<filename>: <strerror>``.
    """
    if isinstance(e, OSError) and e.filename is not None and e.strerror:
        text = f"{e.filename}: {e.strerror}"
    else:
        text = str(e)
    return printable(" ".join(text.split()))


def fail(message: BaseException | str, code: int = 1) -> NoReturn:
    """Print ``error: <message>`` (red, one line, on stderr) and exit with ``code``.

    Raises
    ------
    typer.Exit
        Always, with ``code``.
    """
    from kinmo.progress import console as new_console, literal

    new_console(stderr=True, soft_wrap=True).print(
        f"[red]error:[/] {literal(error_line(message))}", highlight=False
    )
    raise typer.Exit(code)


@contextmanager
def cli_errors(code: int = 1, also: tuple[type[Exception], ...] = ()) -> Iterator[None]:
    """Turn user-caused errors raised in the block into :func:`fail` (one line, exit ``code``).

    Parameters
    ----------
    code : int
        Exit code for these errors (the commands use 1, or 2 for bad options / inputs that
        stop the run before it starts).
    also : tuple of exception types
        Further types to report the same way (e.g. ``(ValueError,)`` around option checks).

    A :class:`~kinmo.errors.KinmoUsageError` (a refused request, such as an output that
    would overwrite an input) always exits with code 2.

    Raises
    ------
    typer.Exit
        For :class:`~kinmo.errors.KinmoError`, an :class:`OSError` naming a file, or one of
        ``also``; other exceptions propagate unchanged.
    """
    from kinmo.errors import KinmoError, KinmoUsageError

    try:
        yield
    except KinmoUsageError as e:
        fail(e, 2)
    except KinmoError as e:
        fail(e, code)
    except OSError as e:
        if e.filename is None:
            raise
        fail(e, code)
    except also as e:  # type: ignore[misc]
        fail(e, code)
