"""Object commands: inspect (one object) and cluster (a set of objects)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Optional

import typer

from ..errors import require_positive
from ..given import cluster_objects, inspect_file, shape_json
from ..settings import DEFAULT
from ._common import (
    Command,
    JsonOpt,
    LibraryOpt,
    PointsUnitOpt,
    RunProgress,
    command_app,
    fail,
    handled,
    info,
    open_catalogue,
    print_json,
)

app = command_app()


@app.command("inspect", cls=Command)
@handled
def inspect(
    obj: Annotated[Path, typer.Argument(metavar="OBJECT", help="One object's points: PLY, PCD, LAS, LAZ, XYZ, BIN.")],
    unit: PointsUnitOpt = "auto",
    plot: Annotated[Optional[Path], typer.Option("--plot", help="Draw the sections to this PNG.")] = None,
    json_: JsonOpt = False,
):
    """Symmetry, heading, size and cross-sections of ONE object's points."""
    notes: list[str] = []
    shape, points = inspect_file(obj, unit=unit, notes=notes)
    for note in notes:
        info(f"warning: {note}")
    doc = shape_json(shape)
    if plot is not None:
        from ..report.plots import plot_sections

        plot_sections(shape.sections, f"{obj.name}: {shape.size.length:.2f} x {shape.size.width:.2f} x "
                      f"{shape.size.height:.2f} m", plot, points=shape.frame.to_local(points))
        doc["plot"] = str(plot)
    if json_:
        print_json(doc)
    else:
        s, y = doc["size"], doc["symmetry"]
        info(f"{obj.name}: {doc['n_points']} points, symmetry {'found' if y['found'] else 'not found'} "
             f"(PCR {y['pcr']:.2f}), heading {doc['heading_rad']:.3f} rad, size {s['length']:.2f} x {s['width']:.2f}"
             f" x {s['height']:.2f} m, centre ({doc['centroid'][0]:.2f}, {doc['centroid'][1]:.2f})")


@app.command("cluster", cls=Command)
@handled
def cluster_cmd(
    scene: Annotated[Path, typer.Argument(help="A scene file (objects are detected) or a folder of object files.")],
    threshold: Annotated[Optional[float], typer.Option(
        help=f"Dendrogram cut (m) [default: {DEFAULT.taxonomy.threshold}, the paper's].")] = None,
    plot: Annotated[Optional[Path], typer.Option("--plot", help="Folder for heatmap.png and dendrogram.png.")] = None,
    unit: PointsUnitOpt = "auto",
    json_: JsonOpt = False,
):
    """Dissimilarity matrix and hierarchical clustering of objects."""
    threshold = require_positive("--threshold", threshold)
    with RunProgress(scene.name) as bars:
        doc = cluster_objects(scene, unit=unit, threshold=threshold, plot=plot, progress=bars.update)
    if json_:
        print_json(doc)
    else:
        info(f"{len(doc['objects'])} objects, {doc['n_clusters']} clusters at {doc['threshold_m'] * 100:.1f} cm")
        for o in doc["objects"]:
            info(f"  {o['id']}: cluster {o['cluster']}")


@app.command("classify", cls=Command)
@handled
def classify_cmd(
    objects: Annotated[list[Path], typer.Argument(
        metavar="OBJECT", help="Object files, one object each (PLY, PCD, LAS, LAZ, XYZ); a folder stands for its "
                               "point files.", show_default=False)],
    unit: PointsUnitOpt = "auto",
    min_confidence: Annotated[Optional[float], typer.Option(
        "--min-confidence", help="Below this confidence no model is claimed (match null, candidates listed) "
                                 f"[default: {DEFAULT.min_confidence}, build-twin's].", show_default=False)] = None,
    library: LibraryOpt = None,
    json_: JsonOpt = False,
):
    """The kind, type and (when the scan decides it) model of objects given one per file."""
    from ..recognition.classify import classify_files
    from ..recognition.summary import classify_lines

    cat = open_catalogue(library, create=False)
    said: list[str] = []
    with RunProgress(f"{len(objects)} paths") as bars:
        items = classify_files(objects, cat, unit=unit, min_confidence=min_confidence, progress=bars.update,
                               warn=said.append)
    failed = [it["error"] for it in items if it.get("error")]
    if items and len(failed) == len(items):  # nothing classified: one line, the first file's error
        fail(failed[0] + (f" (and {len(failed) - 1} more files could not be read)" if len(failed) > 1 else ""))
    for line in said:
        info(f"warning: {line}")
    if json_:
        print_json(items)
    else:
        for line in classify_lines(items):
            info(line)
