"""The twinreg command line: a thin typer layer over the library (see ../shared/docs/CONTRACT.md)."""

from __future__ import annotations

import typer

from . import models, objects, scenes

app = typer.Typer(
    name="twinreg",
    help="Digital-twin registration workbench: COSCO symmetric cross-sections, a CAD catalogue, geo-referenced twins.",
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    add_completion=False,
)
app.add_typer(models.app)
app.add_typer(objects.app)
app.add_typer(scenes.app)


def main() -> None:
    app()
