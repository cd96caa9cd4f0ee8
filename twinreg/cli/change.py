"""compare: the twin over time (the change package does the work)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from ._common import Command, JsonOpt, LibraryOpt, RunProgress, command_app, handled, info, library_folder, print_json

app = command_app()

_SHOWN = ("same", "moved", "replaced", "left", "arrived", "unobserved")


@app.command("compare", cls=Command)
@handled
def compare_cmd(
    twins: Annotated[list[Path], typer.Argument(help="Two or more build-twin folders of the same place, any order.",
                                                show_default=False)],
    out: Annotated[Path, typer.Option("--out", help="Folder for changes.json, changes.geojson, changes.html "
                                      "(replaced as a whole).", show_default=False)],
    library: LibraryOpt = None,
    json_: JsonOpt = False,
):
    """What stayed, moved, left, arrived or was replaced between surveys of one place, and where a survey saw
    nothing. The twins are put in survey-date order (twin.json's survey_date)."""
    from ..change.compare import compare

    with RunProgress("compare") as bars:
        doc = compare(twins, out, say=info, progress=bars.update,
                      protect=[library_folder(library)])
    if json_:
        print_json(doc)
        return
    for s, a in zip(doc["summary"], doc["alignment"]):
        e0, e1 = doc["epochs"][s["from"]], doc["epochs"][s["to"]]
        counts = ", ".join(f"{s[k]} {k}" for k in _SHOWN if s[k])
        shift = ", ".join(f"{v * 100:+.1f}" for v in a["shift"])
        info(f"{e0['date'] or 'epoch ' + str(s['from'])} -> {e1['date'] or 'epoch ' + str(s['to'])}: {counts} "
             f"(shift {shift} cm from {a['n_pairs']} vehicles)")
    info(f"{out}: changes.json, changes.geojson, changes.html (twinreg view {out} shows the epochs in 3D)")
