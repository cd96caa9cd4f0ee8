"""Scene commands: detect, build-twin and demo."""

from __future__ import annotations

from datetime import datetime
from pathlib import Path
from typing import Annotated, Optional

import typer

from ..detect import detect_file, detection_json, write_detection
from ..io.outdir import check_replaceable
from ..settings import DEFAULT
from ._common import (
    Command,
    JsonOpt,
    LibraryOpt,
    PointsUnitOpt,
    RunProgress,
    command_app,
    detail,
    err_console,
    handled,
    info,
    open_catalogue,
    print_json,
)

app = command_app()


@app.command("detect", cls=Command)
@handled
def detect(
    scene: Annotated[Path, typer.Argument(help="Scene points: PLY, PCD, LAS, LAZ, XYZ/TXT or KITTI .bin.")],
    unit: PointsUnitOpt = "auto",
    out: Annotated[Optional[Path], typer.Option("--out", help="Write one PLY per object and topview.png here.")] = None,
    all_objects: Annotated[bool, typer.Option("--all", help="List every object, not only car-sized ones.")] = False,
    json_: JsonOpt = False,
):
    """Ground removal and connectivity-based object detection."""
    if out is not None:
        check_replaceable(out, protect=[scene], kind="detection")
    with err_console.status(f"reading {scene.name}") as status:
        det = detect_file(scene, unit=unit, progress=lambda stage, *_: status.update(f"{scene.name}: {stage} done"))
    doc = detection_json(det, all_objects)
    if det.scene.n_dropped:
        info(f"warning: {det.scene.n_dropped} points with NaN or infinite coordinates were dropped")
    if det.scene.n_outliers:
        info(f"warning: {det.scene.n_outliers} points far from the rest of the scan were ignored (outliers)")
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


# build-twin's options
MinConfidenceOpt = Annotated[Optional[float], typer.Option(
    "--min-confidence", help=f"Below this confidence no model is claimed: match null, candidates listed [default: "
                             f"{DEFAULT.min_confidence}].", show_default=False)]
LatOpt = Annotated[Optional[float], typer.Option(help="WGS84 latitude of the anchor point.")]
LonOpt = Annotated[Optional[float], typer.Option(help="WGS84 longitude of the anchor point.")]
AltOpt = Annotated[float, typer.Option(help="Ellipsoidal height (m) of the anchor.")]
AnchorOpt = Annotated[Optional[tuple[float, float]], typer.Option(help="Scene X Y at --lat/--lon (default 0 0).")]
CrsOpt = Annotated[Optional[str], typer.Option(
    help="The scene's projected CRS, e.g. EPSG:2157 [default: the CRS a LAS/LAZ header states; a different one "
         "only with --override-crs].", show_default=False)]
OverrideCrsOpt = Annotated[bool, typer.Option(
    "--override-crs", help="--crs replaces the CRS the file's header states (the header is wrong).")]
VerticalCrsOpt = Annotated[Optional[str], typer.Option(
    "--vertical-crs", help="The datum of the scan's heights (and of --alt), e.g. EPSG:5709 (NAP), EPSG:5703 "
                           "(NAVD88) [default: a compound CRS's in the header; else unknown, taken as "
                           "ellipsoidal].", show_default=False)]
TolOpt = Annotated[Optional[float], typer.Option(
    help=f"Size tolerance (m) of the catalogue prefilter: the window is then exactly +-TOL (default: "
         f"{DEFAULT.matching.size_tol} m, models up to {DEFAULT.matching.size_spacing_k} point spacings longer and "
         "wider "
         "too).")]
ThresholdOpt = Annotated[Optional[float], typer.Option(
    help=f"Cluster threshold (m) [default: {DEFAULT.taxonomy.threshold}].")]
OutOpt = Annotated[Optional[Path], typer.Option(help="Output folder (default exports/<scene name>).")]
CellOpt = Annotated[Optional[float], typer.Option(
    help="Tiled runs: cell side (m) [default: about 6M points a cell at the tiles' density].",
    show_default=False)]
BufferOpt = Annotated[Optional[float], typer.Option(
    help="Tiled runs: metres read around each cell [default: 10].", show_default=False)]
WorkersOpt = Annotated[Optional[int], typer.Option(
    help="Tiled runs: Dask worker processes of the embedded cluster [default: the cores].", show_default=False)]
SchedulerOpt = Annotated[Optional[str], typer.Option(
    help="Tiled runs: an existing Dask scheduler, tcp://HOST:PORT (inputs, catalogue and OUT at the same "
         "paths on its workers).", show_default=False)]
RestartOpt = Annotated[bool, typer.Option("--restart", help="Tiled runs: ignore the cells a previous run finished.")]
DateOpt = Annotated[Optional[datetime], typer.Option(
    "--date", formats=["%Y-%m-%d"], help="The survey's date, YYYY-MM-DD [default: the LAS/LAZ header's "
                                         "creation date]; written to twin.json as survey_date.",
    show_default=False)]
CityjsonTemplatesOpt = Annotated[bool, typer.Option(
    "--cityjson-templates", help="A scene's twin.city.json with one geometry template per model (smaller; for "
                                 "tools that read templates) instead of explicit geometry (opens everywhere). A "
                                 "city's always has templates, and twin.city.jsonl the explicit geometry.")
]
ClassifiedScanOpt = Annotated[bool, typer.Option(
    "--classified-scan", help="Tiled runs: also write the scan with each point's class and object as COPC, "
                              "classified/<cell>.copc.laz (for QGIS, PDAL, Potree; about 3 bytes a point). "
                              "A scene always writes scan.copc.laz.")]
ScanClassesOpt = Annotated[bool, typer.Option(
    "--scan-classes/--no-scan-classes", help="Read a classified scan's ASPRS classes (vegetation 3-5, building 6, "
                                             "bridge 17) for the objects' kinds; twin.json's scan_classes says "
                                             "whether they were used.")]
TrajectoryOpt = Annotated[Optional[Path], typer.Option(
    "--trajectory", help="A mobile survey's trajectory (CSV of time, x, y, z[, roll, pitch, heading] in the scan's "
                         "CRS, or an SBET): each point's scanner position from its GPS time, so that what the "
                         "scanners could not see (behind a parked car, a van's far side) is unknown, not absent. One "
                         "LAS/LAZ scene with GPS times.", show_default=False)]
PlyOpt = Annotated[Optional[bool], typer.Option(
    "--ply/--no-ply", help="Write the placed models as PLY [default: twin.ply for one scene; none for tiles, "
                           "--ply writes ply/<cell>.ply].", show_default=False)]


@app.command("build-twin", cls=Command)
@handled
def build_twin_cmd(
    paths: Annotated[list[Path], typer.Argument(metavar="PATH",
        help="Scene points (PLY, PCD, LAS, LAZ, XYZ/TXT, KITTI .bin), or LAS/LAZ/COPC tiles: files, a folder or a "
             "quoted glob.", show_default=False)],
    lat: LatOpt = None,
    lon: LonOpt = None,
    alt: AltOpt = 0.0,
    anchor: AnchorOpt = None,
    crs: CrsOpt = None,
    override_crs: OverrideCrsOpt = False,
    vertical_crs: VerticalCrsOpt = None,
    unit: PointsUnitOpt = "auto",
    tol: TolOpt = None,
    threshold: ThresholdOpt = None,
    out: OutOpt = None,
    cell: CellOpt = None,
    buffer: BufferOpt = None,
    workers: WorkersOpt = None,
    scheduler: SchedulerOpt = None,
    restart: RestartOpt = False,
    date: DateOpt = None,
    cityjson_templates: CityjsonTemplatesOpt = False,
    classified_scan: ClassifiedScanOpt = False,
    ply: PlyOpt = None,
    min_confidence: MinConfidenceOpt = None,
    scan_classes: ScanClassesOpt = True,
    trajectory: TrajectoryOpt = None,
    library: LibraryOpt = None,
    json_: JsonOpt = False,
):
    """The whole pipeline: detect, sections, cluster, prefilter, register, export PLY/KMZ/JSON/report; on tiles,
    cell by cell on Dask (resumable)."""
    from ..geo.georef import georef_from_options
    from ..pipeline import RunSettings, build

    georef = georef_from_options(lat=lat, lon=lon, alt=alt, anchor=anchor, crs=crs, required=False,
                                 vertical_crs=vertical_crs, override_crs=override_crs)
    cat = open_catalogue(library, create=False)
    first = paths[0]
    out = out or Path("exports") / (first.stem if first.suffix else first.name or "twin")
    settings = RunSettings(unit=unit, tol=tol, threshold=threshold, cell=cell, buffer=buffer, workers=workers,
                           scheduler=scheduler, restart=restart, ply=ply,
                           date=date.date().isoformat() if date else None, cityjson_templates=cityjson_templates,
                           classified_scan=classified_scan, min_confidence=min_confidence,
                           scan_classes=scan_classes, trajectory=trajectory)
    had_twin = (out / "twin.json").is_file()
    with RunProgress(first.name) as bars:
        twin = build(paths, cat, georef, out, settings, progress=bars.update)
    from ..export.summary import object_lines, twin_summary, warnings_of

    for line in warnings_of(twin):
        info(line)
    if json_:
        print_json(twin)
        return
    for line in object_lines(twin):
        detail(line)
    scan_bytes = sum(p.stat().st_size for p in paths if p.is_file()) or None
    for line in twin_summary(twin, out, scan_bytes):
        info(line)
    if had_twin:
        info(f"note: {out} held a twin before this run; it was replaced (give another --out to keep both)")


@app.command("demo", cls=Command)
@handled
def demo(
    out: Annotated[Path, typer.Option(help="Output folder.")] = Path("exports/demo"),
    seed: Annotated[int, typer.Option(help="Seed of the simulated scan (the demo is deterministic).")] = 0,
    json_: JsonOpt = False,
):
    """Build a demo library and a simulated airborne scan, run build-twin on them, print what came out."""
    from rich.table import Table

    from ..sim.demo import run_demo
    from ._common import out_console

    with err_console.status("demo") as status:
        summary = run_demo(out, seed=seed, progress=lambda stage, *_: status.update(stage))
    if json_:
        print_json(summary)
        return
    t = Table(title=f"twinreg demo (seed {seed}): {summary['n_correct']}/{len(summary['objects'])} cars matched to "
                    f"their model, {summary['n_points']:,} points", header_style="bold")
    for col in ("obj", "matched", "truth", "bearing", "L x W x H m", "pos cm", "head deg", "RMSE cm"):
        t.add_column(col, justify="left" if col in ("obj", "matched", "truth") else "right", no_wrap=True)
    short = lambda n: (n or "-").replace("demo_", "")  # noqa: E731
    for r in summary["objects"]:
        s = r["size"]
        t.add_row(r["object"], short(r["matched"]) + ("" if r["correct"] else " (x)"), short(r["truth"]),
                  f"{r['bearing_deg']:.1f}", f"{s['length']:.2f} {s['width']:.2f} {s['height']:.2f}",
                  f"{r['position_error_m'] * 100:.1f}", f"{r['heading_error_deg']:.1f}",
                  f"{r['rmse_m'] * 100:.1f}" if r["rmse_m"] is not None else "-")
    out_console.print(t)
    f = summary["files"]
    out_console.print(f"Google Earth: {f['twin_kmz']}\nPLY: {f['twin_ply']}\nJSON: {f['twin_json']}\n"
                      f"report: {f['report']}\nscan: {f['scan']}   catalogue: {f['library']}\n"
                      f"done in {summary['timing_s']['total']:.1f} s "
                      f"(build-twin {summary['timing_s']['build_twin']:.1f} s)", highlight=False)
    out_console.print(f"3D: twinreg view {out / 'twin'}", highlight=False)


@app.command("view", cls=Command)
@handled
def view(
    folder: Annotated[Path, typer.Argument(help="A twin folder (the OUT of build-twin) or a comparison (of compare).")],
    port: Annotated[int, typer.Option("--port", min=0, max=65535, help="Port on 127.0.0.1 (0: a free one).")] = 8765,
    no_open: Annotated[bool, typer.Option("--no-open", help="Print the URL only; do not open a browser.")] = False,
):
    """Serve a twin folder (or the epochs of a comparison) on 127.0.0.1 and open the offline 3D viewer (Ctrl-C
    stops it)."""
    import time
    import webbrowser

    from ..viewer import serve

    server, url = serve(folder, port)
    print(url, flush=True)
    info(f"serving {folder} at {url} (Ctrl-C to stop)")
    if not no_open:
        webbrowser.open(url)
    try:
        while True:
            time.sleep(3600)
    except KeyboardInterrupt:
        server.shutdown()
