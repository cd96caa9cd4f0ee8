"""The twinreg command line: a thin typer layer over the library (see ../shared/docs/CONTRACT.md)."""

from typing import Annotated, Optional

import typer

from . import change, city, library, models, objects, scenes

app = typer.Typer(
    name="twinreg",
    help="Digital-twin registration workbench: COSCO symmetric cross-sections, a CAD catalogue, geo-referenced twins.",
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    add_completion=False,
    rich_markup_mode=None,
)


@app.callback()
def _global(
    ctx: typer.Context,
    library: Annotated[Optional[str], typer.Option(
        "--library", help="Catalogue folder for every sub-command (default: $TWINREG_LIBRARY or ./library).",
        show_default=False)] = None,
    json_: Annotated[bool, typer.Option("--json", help="Every sub-command prints one JSON document.")] = False,
    verbose: Annotated[bool, typer.Option("-v", "--verbose", help="Say more (every object of a twin).")] = False,
    quiet: Annotated[bool, typer.Option("-q", "--quiet", help="Say only warnings and errors.")] = False,
    log: Annotated[Optional[str], typer.Option("--log", metavar="FILE", help="Also append every line to FILE.",
                                               show_default=False)] = None,
):
    """--library and --json also work before the sub-command, as in git-like tools: they become the defaults of
    the sub-command's own options (click's default map), which the sub-command may still override."""
    from ._common import OUTPUT, _open_log, _set_level

    if OUTPUT["log"] is not None:  # a command run before in this process (tests) leaves nothing behind
        OUTPUT["log"].close()
    OUTPUT.update(level=0, log=None)
    _set_level(1)(ctx, None, verbose)
    _set_level(-1)(ctx, None, quiet)
    _open_log(ctx, None, log)
    given = {k: v for k, v in (("library", library), ("json_", True if json_ else None)) if v is not None}
    if given:
        ctx.default_map = {name: dict(given) for name in ctx.command.list_commands(ctx)}


app.add_typer(models.app)
app.add_typer(library.app)
app.add_typer(objects.app)
app.add_typer(scenes.app)
app.add_typer(city.app)
app.add_typer(change.app)


def main() -> None:
    """Run the CLI, then leave without the interpreter's teardown (half a second of freeing modules once every
    file is written and renamed, the catalogue committed and the output flushed)."""
    import os
    import sys

    from ..memory import keep_freed_memory

    keep_freed_memory()
    code = 0
    try:
        app()
    except SystemExit as exc:
        code = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)
