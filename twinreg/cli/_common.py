"""Shared pieces of the thin CLI: error handling, JSON output, the console on stderr."""

from __future__ import annotations

import functools
import json
import os
import sys
from typing import Annotated, Optional

import typer
from rich.console import Console

from ..catalogue.names import printable
from ..errors import TwinregError

err_console = Console(stderr=True)
out_console = Console(width=max(Console().width, 110))

LibraryOpt = Annotated[
    Optional[str],
    typer.Option("--library", help="Catalogue folder (default: $TWINREG_LIBRARY or ./library).", show_default=False),
]
JsonOpt = Annotated[bool, typer.Option("--json", envvar="TWINREG_JSON",
                                       help="Print one JSON document to stdout.")]


def fail(message: str, code: int = 1):
    """One line on stderr (control characters of names in it shown as escapes), then exit ``code``."""
    err_console.print(f"error: {printable(message)}", markup=False, highlight=False, soft_wrap=True)
    raise typer.Exit(code)


def handled(fn):
    """Turn twinreg errors (and anything unexpected) into one ``error: ...`` line and exit status 1."""

    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        try:
            return fn(*args, **kwargs)
        except TwinregError as exc:
            fail(str(exc), getattr(exc, "exit_code", 1))
        except (typer.Exit, typer.Abort, KeyboardInterrupt):
            raise
        except OSError as exc:  # a full or read-only disk, a vanished file: the file and the fix, not an errno
            if os.environ.get("TWINREG_DEBUG"):
                raise
            where = exc.filename or "a file this command writes or reads"
            fail(f"{where}: {exc.strerror or exc}; free space on its disk or check that it can be read and written, "
                 "then run again (nothing half-written was kept)")
        except Exception as exc:  # pragma: no cover - a bug; keep the one-line promise unless debugging
            if os.environ.get("TWINREG_DEBUG"):
                raise
            fail(f"unexpected {type(exc).__name__}: {exc} (set TWINREG_DEBUG=1 for a traceback)")

    return wrapper


def library_folder(library: str | None):
    """The catalogue folder of ``--library`` (else $TWINREG_LIBRARY, else ./library)."""
    from ..catalogue.db import library_path

    return library_path(library)


def open_catalogue(library: str | None, create: bool = True):
    """The :class:`~twinreg.catalogue.repository.Catalogue` of ``--library``, imported here: a command that never
    opens it (``--help``, view, compare) starts without SQLAlchemy, SciPy and the matching code."""
    from ..catalogue.repository import Catalogue

    return Catalogue(library_folder(library), create=create)


def print_json(doc) -> None:
    sys.stdout.write(json.dumps(doc, indent=2) + "\n")
    sys.stdout.flush()


def info(message: str) -> None:
    """A message on stderr; a name's control characters (a newline, a terminal escape) are shown as escapes."""
    err_console.print(printable(message), markup=False, highlight=False, soft_wrap=True)


class RunProgress:
    """Progress on stderr: ``update(stage, done, total)`` draws one bar per stage (a tiled run);
    ``update(message, None, None)`` shows a spinner with the message (a scene's stages)."""

    def __init__(self, title: str = ""):
        from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

        self.title = title
        self.progress = Progress(TextColumn("{task.description:<12}"), BarColumn(), MofNCompleteColumn(),
                                 TimeElapsedColumn(), console=err_console, transient=False)
        self.status = None
        self.tasks: dict = {}

    def __enter__(self) -> "RunProgress":
        return self

    def __exit__(self, *exc):
        if self.status is not None:
            self.status.stop()
        if self.tasks:
            self.progress.stop()
        return False

    def update(self, stage: str, done: int | None = 0, total: int | None = 0) -> None:
        if done is None:  # a stage message
            text = f"{self.title}: {stage}" if self.title else stage
            if self.status is None:
                self.status = err_console.status(text)
                self.status.start()
            else:
                self.status.update(text)
            return
        if not self.tasks:
            self.progress.start()
        if stage not in self.tasks:
            self.tasks[stage] = self.progress.add_task(stage, total=max(total, 1))
        self.progress.update(self.tasks[stage], completed=done, total=max(total, 1))
