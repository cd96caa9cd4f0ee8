"""Shared pieces of the thin CLI: error handling, JSON output, the console on stderr."""

from __future__ import annotations

import functools
import json
import os
import sys
from typing import Annotated, Optional

import typer
from rich.console import Console
from typer.core import TyperArgument, TyperCommand

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
#: a scan's unit (objects and scenes)
PointsUnitOpt = Annotated[str, typer.Option("--unit",
                                            help="auto|m|cm|mm|ft|us-ft|in (auto: metres or the LAS CRS unit).")]


#: what the console says (``-v``: every object too, ``-q``: warnings and errors only) and the ``--log`` file, which
#: gets every line whatever the console's level
OUTPUT = {"level": 0, "log": None}


def _log(line: str) -> None:
    if OUTPUT["log"] is not None:
        import time

        OUTPUT["log"].write(f"{time.strftime('%Y-%m-%d %H:%M:%S')} {line}\n")
        OUTPUT["log"].flush()


def _set_level(level: int):
    def callback(ctx, param, value):
        if value:
            OUTPUT["level"] = level
        return value
    return callback


def _open_log(ctx, param, value):
    if value:
        from ..errors import ParameterError

        try:
            OUTPUT["log"] = open(value, "a", encoding="utf-8")  # noqa: SIM115 - open for the command's life
        except OSError as exc:
            fail(str(ParameterError(f"--log {value}: cannot be written ({exc.strerror or exc}); give a file in a "
                                    "folder you can write to")), 2)
        _log("twinreg " + " ".join(sys.argv[1:]))
    return value


def output_options() -> list:
    """``-v``, ``-q`` and ``--log FILE``, which every command takes (before or after its name), as typer makes its
    options (typer builds commands with its own click)."""
    from typer.main import _get_param
    from typer.models import ParamMeta

    def option(name, annotation, default, *decls, **kw):
        return _get_param(ParamMeta(name=name, annotation=annotation, default=typer.Option(
            default, *decls, expose_value=False, show_default=False, **kw)))

    return [option("verbose", bool, False, "-v", "--verbose", callback=_set_level(1),
                   help="Say more: every object of a twin."),
            option("quiet", bool, False, "-q", "--quiet", callback=_set_level(-1),
                   help="Say only warnings and errors (no progress)."),
            option("log", Optional[str], None, "--log", metavar="FILE", callback=_open_log,
                   help="Also append every line (the -v ones too, with the time) to FILE.")]


def fail(message: str, code: int = 1):
    """One line on stderr (control characters of names in it shown as escapes), then exit ``code``."""
    err_console.print(f"error: {printable(message)}", markup=False, highlight=False, soft_wrap=True)
    _log(f"error: {printable(message)}")
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
    """A message on stderr (not with ``-q``, but for warnings); a name's control characters (a newline, a terminal
    escape) are shown as escapes."""
    _log(printable(message))
    if OUTPUT["level"] >= 0 or message.startswith("warning"):
        err_console.print(printable(message), markup=False, highlight=False, soft_wrap=True)


def detail(message: str) -> None:
    """A line said with ``-v`` (and always to the ``--log`` file)."""
    _log(printable(message))
    if OUTPUT["level"] > 0:
        err_console.print(printable(message), markup=False, highlight=False, soft_wrap=True)


def _clock(seconds: float) -> str:
    """A duration as people read it.

    >>> _clock(7.2), _clock(75), _clock(3725)
    ('7 s', '1 min 15 s', '1 h 02 min')
    """
    s = int(round(seconds))
    if s < 60:
        return f"{s} s"
    if s < 3600:
        return f"{s // 60} min {s % 60:02d} s"
    return f"{s // 3600} h {s % 3600 // 60:02d} min"


class RunProgress:
    """Progress on stderr. ``update(stage, done, total)``: a counted stage (cells, objects), drawn as a bar with its
    count, the time spent and the time left; ``update(message, None, None)``: a stage starting. On a terminal the
    bars and the stage are live (rich). Otherwise (a log, a CI job) plain lines: nothing in a run's first
    :attr:`quiet` seconds (a refused input stays one line), then the current stage with the run's elapsed time
    when it starts and every :attr:`every` seconds while it lasts, a counted stage with its count and time left."""

    #: seconds between two plain lines while a stage lasts
    every = 10.0
    #: seconds at the start of a run in which no plain line is printed ($TWINREG_PROGRESS_QUIET overrides it)
    quiet = float(os.environ.get("TWINREG_PROGRESS_QUIET", 2.0))

    def __init__(self, title: str = "", plain: bool | None = None):
        import threading
        import time

        self.title = title
        self.plain = (not err_console.is_terminal) if plain is None else plain
        self.t0 = time.monotonic()
        self.progress = None
        self.status = None
        self.tasks: dict = {}
        self.started: dict = {}
        self.current: str | None = None  # the plain line of the stage under way
        self.key: str | None = None  # the stage under way (a message, or a counted stage's name)
        self.printed: str | None = None  # the stage said last
        self.last = 0.0
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._ticker = None

    def __enter__(self) -> "RunProgress":
        if self.plain:
            import threading

            self._ticker = threading.Thread(target=self._tick, name="twinreg-progress", daemon=True)
            self._ticker.start()
        return self

    def __exit__(self, *exc):
        self._stop.set()
        if self.status is not None:
            self.status.stop()
        if self.progress is not None:
            self.progress.stop()
        return False

    def _tick(self) -> None:
        """Plain mode: the stage under way said again every :attr:`every` seconds (and first after :attr:`quiet`)."""
        import time

        while not self._stop.wait(0.5):
            with self._lock:
                now = time.monotonic()
                if self.current is not None and now - self.t0 >= self.quiet and (
                        self.printed != self.key or now - self.last >= self.every):
                    self._say(self.current, now)

    def _say(self, text: str, now: float) -> None:
        prefix = f"{self.title}: " if self.title else ""
        info(f"[{_clock(now - self.t0)}] {prefix}{text}")
        self.printed, self.last = self.key, now

    def update(self, stage: str, done: int | None = 0, total: int | None = 0) -> None:
        import time

        if OUTPUT["level"] < 0:  # -q
            return
        now = time.monotonic()
        if done is None:  # a stage message
            if self.plain:
                with self._lock:
                    self.current = self.key = stage
                    if now - self.t0 >= self.quiet:
                        self._say(stage, now)
                return
            text = f"{self.title}: {stage}" if self.title else stage
            if self.progress is not None:  # one live display at a time: the stage is a line above the bars
                self.progress.console.print(text, markup=False, highlight=False)
                return
            if self.status is None:
                self.status = err_console.status(text)
                self.status.start()
            else:
                self.status.update(text)
            return
        total = max(int(total or 0), 1)
        start = self.started.setdefault(stage, now)
        if self.plain:
            spent = now - start
            left = f", about {_clock(spent / done * (total - done))} left" if 0 < done < total else ""
            line = f"{stage} {done:,}/{total:,} ({100 * done / total:.0f} %), {_clock(spent)}{left}"
            with self._lock:
                self.current, self.key = (line if done < total else None), stage
                if now - self.t0 >= self.quiet and (done >= total or self.printed != stage
                                                    or now - self.last >= self.every):
                    self._say(line, now)
            return
        if self.status is not None:  # a bar from now on: the spinner's line gives way to it
            self.status.stop()
            self.status = None
        if self.progress is None:
            from rich.progress import (
                BarColumn,
                MofNCompleteColumn,
                Progress,
                TextColumn,
                TimeElapsedColumn,
                TimeRemainingColumn,
            )

            self.progress = Progress(TextColumn("{task.description:<12}"), BarColumn(), MofNCompleteColumn(),
                                     TimeElapsedColumn(), TextColumn("left"), TimeRemainingColumn(),
                                     console=err_console, transient=False)
            self.progress.start()
        if stage not in self.tasks:
            self.tasks[stage] = self.progress.add_task(stage, total=total)
        self.progress.update(self.tasks[stage], completed=done, total=total)


def _argument_name(param) -> str:
    """An argument as click's usage writes it: ``PATH...`` (several), ``[NAME]`` (optional)."""
    name = (param.metavar or param.name or "").upper().rstrip(".")
    name += "..." if param.nargs != 1 else ""
    return name if param.required else f"[{name}]"


class Command(TyperCommand):
    """A command whose help reads as click's: the usage line names arguments ``PATH...`` (typer writes
    ``{paths}...``), the arguments are listed with their help and no Python type, options as typer lists them
    (flags with no type: the apps use ``rich_markup_mode=None``, which also keeps ``[default: ...]`` in a help
    text instead of reading it as markup)."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.params += output_options()

    def collect_usage_pieces(self, ctx) -> list[str]:
        rv = [self.options_metavar] if self.options_metavar else []
        for p in self.get_params(ctx):
            rv.extend([_argument_name(p)] if isinstance(p, TyperArgument) else p.get_usage_pieces(ctx))
        return rv

    def format_options(self, ctx, formatter) -> None:
        args, opts = [], []
        for p in self.get_params(ctx):
            if isinstance(p, TyperArgument):
                if not p.hidden:
                    args.append((_argument_name(p).strip("[]"), p.help or ""))
            else:
                record = p.get_help_record(ctx)
                if record is not None:
                    opts.append(record)
        if args:
            with formatter.section("Arguments"):
                formatter.write_dl(args)
        if opts:
            with formatter.section("Options"):
                formatter.write_dl(opts)


def command_app() -> typer.Typer:
    """A group of commands rendered in plain text (see :class:`Command`)."""
    return typer.Typer(rich_markup_mode=None)
