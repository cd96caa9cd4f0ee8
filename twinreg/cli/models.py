"""Catalogue commands: add-model, import-models, list-models, show-model, update-model, remove-model, label."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, List, Optional

import typer
from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn
from rich.table import Table
from rich.text import Text

from ..catalogue.duplicates import near_duplicate_report
from ..catalogue.folder import import_folder, mesh_files
from ..catalogue.names import printable
from ._common import (
    OUTPUT,
    Command,
    JsonOpt,
    LibraryOpt,
    command_app,
    err_console,
    handled,
    info,
    open_catalogue,
    out_console,
    print_json,
)

app = command_app()

RefArg = Annotated[str, typer.Argument(
    help="The model: id:N, name:TEXT, or an id (digits) or unique name.", show_default=False)]
UnitOpt = Annotated[str, typer.Option("--unit", help="auto|m|cm|mm|in|ft (auto: the file's unit, else inferred).")]
UpOpt = Annotated[str, typer.Option("--up", help="auto|+x|-x|+y|-y|+z|-z: the file's up axis.")]
CategoryOpt = Annotated[Optional[str], typer.Option(
    "--category", help="The model's kind, lower-case: car, van, lamp_post, traffic_sign, hydrant, bin, barrier, cone, "
                       "tree, shelter... [default: car].", show_default=False)]
FrontOpt = Annotated[str, typer.Option(
    "--front", help="auto|+x|-x|+y|-y: the car's front, in the file's axes once up is Z.")]


def _summary(row) -> str:
    return (f"added model {row.id} '{row.name}' ({row.category}): {row.length:.2f} x {row.width:.2f} x "
            f"{row.height:.2f} m, symmetry {row.sym_level or ('found' if row.sym_found else 'not found')} (PCR "
            f"{row.sym_pcr:.2f}), {row.n_points} points; "
            f"{row.notes}")


@app.command("add-model", cls=Command)
@handled
def add_model(
    mesh: Annotated[Optional[Path], typer.Argument(
        help="Mesh file: OBJ, PLY, STL, OFF, GLB/glTF or DAE; or one scanned object's points (XYZ, PLY points, "
             "LAS/LAZ). Not with --from-twin.", show_default=False)] = None,
    name: Annotated[Optional[str], typer.Option(help="Unique name (default: the file name).")] = None,
    make: Annotated[Optional[str], typer.Option(help="Manufacturer.")] = None,
    model: Annotated[Optional[str], typer.Option(help="Model name.")] = None,
    body_class: Annotated[Optional[str], typer.Option("--body-class", help="e.g. hatchback, sedan, SUV.")] = None,
    category: CategoryOpt = None,
    unit: UnitOpt = "auto",
    scale: Annotated[float, typer.Option(
        "--scale", help="A factor after the unit (Gazebo's model.sdf scales some models, e.g. 3).")] = 1.0,
    up: UpOpt = "auto",
    front: FrontOpt = "auto",
    tag: Annotated[Optional[List[str]], typer.Option("--tag", metavar="TAG", help="A tag (repeatable).")] = None,
    from_twin: Annotated[Optional[Path], typer.Option(
        "--from-twin", metavar="OUT", help="A twin folder build-twin wrote: add its fused type --type as a model "
                                           "(--name required; --category defaults to the type's kind).",
        show_default=False)] = None,
    type_: Annotated[Optional[int], typer.Option(
        "--type", help="With --from-twin: the type's number (twin.json's objects carry theirs).",
        show_default=False)] = None,
    force: Annotated[bool, typer.Option(
        "--force", help="With --from-twin: add the type as --category even when its members' sizes say it is not "
                        "one.")] = False,
    library: LibraryOpt = None,
    json_: JsonOpt = False,
):
    """Load, normalise, sample the visible surface, detect symmetry, cut cross-sections, measure size, store.
    With --from-twin OUT --type T --name N: a type fused from a twin's scans becomes a model."""
    from ..errors import ParameterError

    if (mesh is None) == (from_twin is None):
        raise ParameterError("give a mesh file, or --from-twin OUT --type T --name N (not both)")
    cat = open_catalogue(library)
    if from_twin is not None:
        if type_ is None or not name:
            raise ParameterError("--from-twin needs --type T and --name N")
        from ..shapes.promote import promote

        with err_console.status(f"measuring type {type_} of {from_twin.name}"):
            row = promote(cat, from_twin, type_, name, category, force=force)
            dups, warning = near_duplicate_report(cat, row)
    else:
        with err_console.status(f"measuring {mesh.name}"):
            row = cat.add(mesh, name=name, make=make, model=model, body_class=body_class, tags=tag or (), unit=unit,
                          up=up, front=front, category=category, scale=scale)
            dups, warning = near_duplicate_report(cat, row)
    if warning:  # a warning, not a failure: the model is stored
        info(warning)
    if json_:
        print_json(row.to_dict() | {"near_duplicates": dups, "warnings": [warning] if warning else []})
    else:
        info(_summary(row))


@app.command("import-models", cls=Command)
@handled
def import_models(
    folder: Annotated[Path, typer.Argument(help="Folder searched recursively for mesh files.")],
    manifest: Annotated[Optional[Path], typer.Option(
        "--manifest", metavar="CSV", help="A CSV of file,name,category,scale,make,model,unit,up,front (file relative "
                                          "to the folder; an empty cell: the default).", show_default=False)] = None,
    category: CategoryOpt = None,
    scale: Annotated[float, typer.Option("--scale", help="A factor after the unit, for the files the manifest does "
                                                          "not scale.")] = 1.0,
    unit: UnitOpt = "auto",
    up: UpOpt = "auto",
    library: LibraryOpt = None,
    json_: JsonOpt = False,
):
    """Add every mesh in a folder; a bad file is reported and skipped, the rest go in. With --manifest, each listed
    file's name, category, scale, make and model as the manifest says."""
    from ..catalogue.categories import check_category
    from ..catalogue.folder import read_manifest
    from ..errors import CatalogueError

    if not (0.0001 <= scale <= 10000):
        raise CatalogueError(f"--scale {scale:g}: give a factor between 0.0001 and 10000")
    category = check_category(category) if category is not None else None
    listed = read_manifest(manifest, folder) if manifest is not None else {}
    files = mesh_files(folder, also=listed)
    cat = open_catalogue(library)
    with Progress(TextColumn("{task.description}"), BarColumn(), TextColumn("{task.completed}/{task.total}"),
                  TimeElapsedColumn(), console=err_console, disable=OUTPUT["level"] < 0) as bar:
        task = bar.add_task("importing", total=len(files))

        def say(event, path, text):
            if event == "start":
                bar.update(task, description=f"importing {path.name}")
            elif event == "done":
                bar.advance(task)
            elif OUTPUT["level"] >= 0 or event in ("warning", "skipped"):
                bar.console.print(printable(text), markup=False, highlight=False)

        result = import_folder(cat, files, unit=unit, up=up, progress=say, manifest=listed, category=category,
                               scale=scale, root=folder)
    if json_:
        print_json(result.as_dict())
    else:
        info(f"{len(result.added)} added, {len(result.skipped)} skipped"
             + (f", {len(result.left_out)} left out (not in the manifest)" if result.left_out else ""))
    added, skipped = result.added, result.skipped
    if not added and skipped:
        raise typer.Exit(1)


def _table(rows) -> Table:
    t = Table(title=None, header_style="bold")
    for col, just in (("id", "right"), ("name", "left"), ("category", "left"), ("make", "left"), ("model", "left"),
                      ("class", "left"), ("L m", "right"), ("W m", "right"), ("H m", "right"), ("symmetry", "left"),
                      ("PCR", "right"), ("points", "right")):
        t.add_column(col, justify=just)
    for r in rows:
        text = (Text(printable(x)) for x in (r.name, r.category or "car", r.make or "", (r.model or "")[:30],
                                             r.body_class or ""))
        sym = r.sym_level or ("yes" if r.sym_found else "no")
        t.add_row(str(r.id), *text, f"{r.length:.2f}", f"{r.width:.2f}", f"{r.height:.2f}", sym,
                  f"{r.sym_pcr:.2f}", str(r.n_points))
    return t


from ..catalogue.names import SORT_KEYS


@app.command("list-models", cls=Command)
@handled
def list_models(
    near: Annotated[Optional[tuple[float, float, float]], typer.Option(
        "--near", help="L W H (m): only models within --tol of this size.")] = None,
    tol: Annotated[Optional[float], typer.Option(
        help="Size tolerance (m) on each of L, W, H [default: 0.2, the matcher's].")] = None,
    body_class: Annotated[Optional[str], typer.Option(
        "--body-class", "--class", help="Only models whose body class contains this (any case): sedan, SUV.")] = None,
    tag: Annotated[Optional[List[str]], typer.Option("--tag", metavar="TAG", help="Only models with this tag (repeatable: all).")
                   ] = None,
    category: Annotated[Optional[str], typer.Option(
        "--category", help="Only models of this kind (car, lamp_post, ...).", show_default=False)] = None,
    sort: Annotated[str, typer.Option("--sort", help=f"Order: {', '.join(SORT_KEYS)}.")] = "id",
    csv_: Annotated[bool, typer.Option("--csv", help="Print CSV (the JSON fields, sizes flattened).")] = False,
    library: LibraryOpt = None,
    json_: JsonOpt = False,
):
    """List (or size-query) the catalogue."""
    rows = open_catalogue(library, create=False).listing(near=near, tol=tol, body_class=body_class, tags=tag,
                                                         sort=sort, category=category)
    if csv_:  # asked for on this command: it wins over a --json given for every command
        _print_csv(rows)
    elif json_:
        print_json([r.to_dict() for r in rows])
    elif rows:
        out_console.print(_table(rows))
    else:
        info("no models")


def _print_csv(rows) -> None:
    import csv
    import sys

    cols = ["id", "name", "make", "model", "body_class", "tags", "length", "width", "height", "symmetry_found",
            "pcr", "n_points", "sha256", "source_name", "unit", "up", "front", "category", "source", "symmetry_level"]
    w = csv.writer(sys.stdout, lineterminator="\n")
    w.writerow(cols)
    for r in rows:
        d = r.to_dict()
        text = [printable(v or "") for v in (d["name"], d["make"], d["model"], d["body_class"], ";".join(d["tags"]),
                                             d["source_name"])]  # a catalogue written before fields were checked
        w.writerow([d["id"], *text[:5],
                    d["size"]["length"], d["size"]["width"], d["size"]["height"], d["symmetry"]["found"],
                    d["symmetry"]["pcr"], d["n_points"], d["sha256"], text[5], d["unit"], d["up"],
                    d["front"], d["category"], d["source"], d["symmetry"]["level"] or ""])


@app.command("show-model", cls=Command)
@handled
def show_model(
    ref: RefArg,
    plot: Annotated[Optional[Path], typer.Option("--plot", help="Draw the cross-sections to this PNG.")] = None,
    library: LibraryOpt = None,
    json_: JsonOpt = False,
):
    """Show one model; --plot draws its cross-sections."""
    cat = open_catalogue(library, create=False)
    row = cat.get(ref)
    doc = row.to_dict()
    if plot is not None:
        from ..report.plots import plot_model

        plot_model(cat.geometry(row), row.to_dict(), plot)
        doc["plot"] = str(plot)
    if json_:
        geo = cat.geometry(row)
        doc["sections"] = {"longitudinal": geo.sections.longitudinal.round(3).tolist(),
                           "transverse": geo.sections.transverse.round(3).tolist()}
        print_json(doc)
    else:
        for key in ("id", "name", "make", "model", "body_class", "tags", "size", "mesh_size", "symmetry",
                    "n_points", "sample_spacing_m", "unit", "unit_source", "up", "front", "n_faces", "glass_fraction",
                    "sha256", "source_name", "notes", "created_at", "plot"):
            if key in doc:  # the values are text from a catalogue, perhaps someone else's: no markup, no escapes
                out_console.print(Text.assemble((key, "bold"), ": ", printable(doc[key])), highlight=False)


@app.command("update-model", cls=Command)
@handled
def update_model(
    ref: RefArg,
    name: Annotated[Optional[str], typer.Option()] = None,
    make: Annotated[Optional[str], typer.Option()] = None,
    model: Annotated[Optional[str], typer.Option()] = None,
    body_class: Annotated[Optional[str], typer.Option("--body-class")] = None,
    category: CategoryOpt = None,
    tag: Annotated[Optional[List[str]], typer.Option("--tag", metavar="TAG", help="Replace the tags (repeatable).")] = None,
    library: LibraryOpt = None,
    json_: JsonOpt = False,
):
    """Edit a model's name, make, model, body class or tags."""
    row = open_catalogue(library, create=False).update(
        ref, name=name, make=make, model=model, body_class=body_class, tags=tag, category=category)
    if json_:
        print_json(row.to_dict())
    else:
        info(f"updated model {row.id} '{row.name}'")


@app.command("remove-model", cls=Command)
@handled
def remove_model(
    ref: RefArg,
    yes: Annotated[bool, typer.Option("--yes", help="Do not ask for confirmation.")] = False,
    library: LibraryOpt = None,
    json_: JsonOpt = False,
):
    """Remove a model and its stored files."""
    cat = open_catalogue(library, create=False)
    row = cat.get(ref)
    if not yes and not typer.confirm(f"remove model {row.id} '{row.name}'?", err=True):
        raise typer.Exit(1)
    row = cat.remove(row.id)
    if json_:
        print_json({"removed": row.to_dict()})
    else:
        info(f"removed model {row.id} '{row.name}'")


@app.command("label", cls=Command)
@handled
def label(
    twin: Annotated[Path, typer.Argument(help="A twin folder build-twin wrote.", show_default=False)],
    type_: Annotated[int, typer.Option("--type", help="The type's number (twin.json's objects carry theirs).",
                                       show_default=False)],
    kind: Annotated[str, typer.Option("--kind", help="What its members are, lower-case: hedge, bicycle, wall, or a "
                                                     "negative such as not_a_car.", show_default=False)],
    library: LibraryOpt = None,
    json_: JsonOpt = False,
):
    """Store the members of a twin's type as scanned exemplars of a kind (at most 20, those with most points); the
    next run recognises the kind. Exemplars teach a kind and are never placed as a model."""
    from ..label.teach import label_type

    cat = open_catalogue(library)
    with err_console.status(f"labelling type {type_} of {twin.name} as {kind}"):
        rows, few = label_type(cat, twin, type_, kind)
    if json_:
        print_json({"kind": rows[0].category, "type": type_, "added": [r.to_dict() for r in rows],
                    "too_few_points": few})
    else:
        info(f"type {type_} of {twin.name}: {len(rows)} exemplars of {rows[0].category} added "
             f"({', '.join(r.name for r in rows[:5])}{', ...' if len(rows) > 5 else ''})"
             + (f"; {len(few)} members with too few points left out" if few else ""))
