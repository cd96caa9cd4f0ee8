"""Library commands: export-library, import-library (portable catalogues, twinreg/catalogue/bundle.py) and coverage
(what the catalogue lacks, twinreg/catalogue/coverage.py)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, List, Optional

import typer

from ._common import (
    Command,
    JsonOpt,
    LibraryOpt,
    command_app,
    err_console,
    handled,
    info,
    library_folder,
    open_catalogue,
    print_json,
)

app = command_app()


@app.command("export-library", cls=Command)
@handled
def export_library(
    zip_path: Annotated[Path, typer.Argument(help="The bundle to write (a .zip).")],
    force: Annotated[bool, typer.Option("--force", help="Overwrite an existing file that is not a bundle.")] = False,
    library: LibraryOpt = None,
    json_: JsonOpt = False,
):
    """Write the catalogue (models, sampled clouds, sections, meshes, provenance, schema) to one zip."""
    from ..catalogue.bundle import export_library as export

    folder = library_folder(library)
    with err_console.status(f"exporting {folder}"):
        manifest = export(folder, zip_path, force=force)
    size = sum(m["bytes"] for m in manifest["members"].values())
    if json_:
        print_json({"zip": str(zip_path), "n_models": manifest["n_models"], "schema_revision":
                    manifest["schema_revision"], "n_files": len(manifest["members"]), "bytes": size})
    else:
        info(f"{manifest['n_models']} models ({len(manifest['members'])} files, {size / 1e6:.1f} MB) written to "
             f"{zip_path}")


@app.command("import-library", cls=Command)
@handled
def import_library(
    zip_path: Annotated[Path, typer.Argument(help="A bundle written by export-library.")],
    rename: Annotated[bool, typer.Option("--rename", help="Give clashing names a free one (name-2).")] = False,
    skip: Annotated[bool, typer.Option("--skip", help="Leave models whose name is taken out.")] = False,
    library: LibraryOpt = None,
    json_: JsonOpt = False,
):
    """Add a bundle's models, checksums verified; clashing names change nothing without --rename or --skip."""
    from ..catalogue.bundle import import_library as do_import

    cat = open_catalogue(library)
    with err_console.status(f"importing {zip_path.name}"):
        result = do_import(cat, zip_path, rename=rename, skip=skip)
    if json_:
        print_json(result.as_dict())
    else:
        renamed = {a: b for a, b in result.added.items() if a != b}
        info(f"{len(result.added)} models imported into {cat.folder}, {len(result.skipped)} left out"
             + (f"; renamed: {', '.join(f'{a} -> {b}' for a, b in renamed.items())}" if renamed else ""))


@app.command("coverage", cls=Command)
@handled
def coverage(
    twins: Annotated[List[Path], typer.Argument(help="twin.json files written by build-twin.")],
    plot: Annotated[Optional[Path], typer.Option("--plot", help="Draw object sizes over the catalogue's (PNG).")
                    ] = None,
    library: LibraryOpt = None,
    json_: JsonOpt = False,
):
    """The objects that got no model (or one outside the size window), grouped by kind and size, and the sizes
    the catalogue is missing."""
    import numpy as np

    from ..catalogue.coverage import coverage as cover
    from ..catalogue.coverage import plot as draw
    from ..catalogue.coverage import read_objects

    objects = read_objects(twins)
    rows = open_catalogue(library, create=False).list()
    models = np.array([[r.length, r.width, r.height] for r in rows]).reshape(-1, 3)
    names = [r.name for r in rows]
    doc = cover(objects, models, names, [r.category or "car" for r in rows])
    if plot:
        draw(objects, models, names, plot)
        doc["plot"] = str(plot)
    if json_:
        print_json(doc)
        return
    info(f"{doc['n_lacking']} of {doc['n_objects']} objects got no model or one outside the size window"
         + ("" if rows else " (no catalogue: give --library to name the nearest models)"))
    info("by kind: " + ", ".join(f"{k} {v['n_lacking']} of {v['n_objects']}" for k, v in doc["per_kind"].items()))
    for g in doc["groups"]:
        info("  " + g["text"])


@app.command("library-report", cls=Command)
@handled
def library_report(
    density: Annotated[float, typer.Option("--density", help=(
        "The survey's density (points per m2); the default is that of airborne city scans such as AHN (about 17) "
        "and Autzen (about 8): give a mobile or drone survey's own (100-300)."))] = 20.0,
    out: Annotated[Path, typer.Option("--out", help="Output folder.")] = Path("exports/library"),
    scans: Annotated[int, typer.Option("--scans", help="Simulated scans of each model.")] = 10,
    seed: Annotated[int, typer.Option("--seed", help="Seed of the simulated scans.")] = 0,
    workers: Annotated[int, typer.Option("--workers", help="Processes the models are spread over.")] = 2,
    library: LibraryOpt = None,
    json_: JsonOpt = False,
):
    """A gallery of the models, their taxonomy and near-duplicates, and which of them a scan of the given density
    confuses (library.html, library.json)."""
    from ..errors import require_positive
    from ..evaluation.library_report import report

    require_positive("--density", density)
    if scans < 1 or workers < 1:
        from ..errors import ParameterError

        raise ParameterError("--scans and --workers must be at least 1")
    cat = open_catalogue(library, create=False)
    with err_console.status("library report") as status:
        doc = report(cat, out, density=density, scans=scans, seed=seed, workers=workers,
                     progress=lambda stage, *_: status.update(stage))
    if json_:
        print_json(doc)
        return
    info(f"{doc['n_models']} models; {len(doc['taxonomy']['near_duplicates'])} near-duplicate pair(s); "
         f"{len(doc['cannot_tell_apart'])} pair(s) confused at {density:g} pts/m2; {doc['timing_s']:.1f} s")
    for p in doc["cannot_tell_apart"]:
        info("  " + p["text"])
    info(f"written: {out / 'library.html'}, {out / 'library.json'}")
