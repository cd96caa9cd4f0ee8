"""Scene commands: detect (and, with the twin issue, build-twin and demo)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Optional

import typer

from ..detect import detect_file, detection_json, write_detection
from ._common import JsonOpt, err_console, handled, info, print_json

app = typer.Typer()

UnitOpt = Annotated[str, typer.Option("--unit", help="auto|m|cm|mm|ft|us-ft|in (auto: metres or the LAS CRS unit).")]


@app.command("detect")
@handled
def detect(
    scene: Annotated[Path, typer.Argument(help="Scene points: PLY, PCD, LAS, LAZ, XYZ/TXT or KITTI .bin.")],
    unit: UnitOpt = "auto",
    out: Annotated[Optional[Path], typer.Option("--out", help="Write one PLY per object and topview.png here.")] = None,
    all_objects: Annotated[bool, typer.Option("--all", help="List every object, not only car-sized ones.")] = False,
    json_: JsonOpt = False,
):
    """Ground removal and connectivity-based object detection."""
    with err_console.status(f"reading {scene.name}") as status:
        det = detect_file(scene, unit=unit, progress=lambda stage: status.update(f"{scene.name}: {stage} done"))
    doc = detection_json(det, all_objects)
    if det.scene.n_dropped:
        info(f"warning: {det.scene.n_dropped} points with NaN or infinite coordinates were dropped")
    if out is not None:
        doc["files"] = [str(p) for p in write_detection(det, out, all_objects)]
    if json_:
        print_json(doc)
    else:
        info(f"{scene.name}: {doc['n_points']} points, {doc['n_ground']} ground, {len(doc['objects'])} "
             f"{'objects' if all_objects else 'car-sized objects'} (unit {doc['unit']})")
        for o in doc["objects"]:
            f = o["footprint"]
            info(f"  {o['id']}: {o['n_points']} points, {f['length']:.2f} x {f['width']:.2f} x {f['height']:.2f} m")
        if out is not None:
            info(f"written to {out}")
