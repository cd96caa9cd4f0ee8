"""build_twin: the stages in order (read, ground, objects, sections, matrix, clustering, prefilter, registration,
export) with timings and progress; everything is written into a staging folder that replaces OUT as a whole."""

from __future__ import annotations

import json
import time
from dataclasses import dataclass
from pathlib import Path

from cosco.arrays import point_spacing
from cosco.kernels import enable, preload, settle

from . import KERNEL_MODULES
from .catalogue.repository import Catalogue
from .city.build import build_city_twin
from .city.sources import is_tiled
from .detect import described, detect_file, objects_seen
from .errors import ParameterError, SceneReadError
from .export.classified import scan_classes, write_classified
from .export.formats import TwinFiles, write_twin
from .export.sections import section_item
from .export.tiles3d import scan_sample
from .export.twin_json import MatchSummary, ScanSummary, survey_date, twin_document, viewpoints_doc
from .geo.georef import Georef, scene_georef
from .io import observed
from .io.asprs import classes_doc
from .io.outdir import check_replaceable, locked, staged_folder
from .io.points import check_point_file
from .matching.acceptance import scene_noise
from .matching.match import Evidence, ModelCache, match_objects
from .matching.prober import Prober
from .process.helpers import HELPER_TIMEOUT_S, Forked, Painter, Pending
from .progress import say
from .report.scene import plot_object_sections, plot_taxonomy, write_report
from .settings import DEFAULT, Settings
from .stages import (
    checked_params,
    finish,
    locate,
    require_models,
    taxonomy,
    with_targets,
)


@dataclass(frozen=True)
class RunSettings:
    """The options of a build-twin run (the command's, in one object): the unit, the size tolerance and cluster
    threshold (None: the defaults), the tiled run's cell, buffer, workers, scheduler and restart, and whether to
    write PLY (None: twin.ply for one scene, none for tiles); the survey's date (``YYYY-MM-DD``; None: the
    LAS/LAZ headers'); a scene's CityJSON with geometry templates instead of explicit geometry (a city's has
    templates, and explicit geometry in its CityJSONSeq); a tiled run's classified scan (a scene always has
    scan.copc.laz); the models' confidence floor (None: the parameters'); whether the kinds read a classified
    scan's ASPRS classes (``--no-scan-classes``: not)."""

    unit: str = "auto"
    tol: float | None = None
    threshold: float | None = None
    cell: float | None = None
    buffer: float | None = None
    workers: int | None = None
    scheduler: str | None = None
    restart: bool = False
    ply: bool | None = None
    date: str | None = None
    cityjson_templates: bool = False
    classified_scan: bool = False
    min_confidence: float | None = None
    scan_classes: bool = True
    trajectory: Path | None = None

    def tiled(self, paths) -> bool:
        """Whether ``paths`` run cell by cell (several paths, a folder, a glob, a COPC or a large LAS/LAZ, or any
        tiled option given)."""
        explicit = any(v is not None for v in (self.cell, self.buffer, self.workers, self.scheduler))
        return is_tiled(paths, explicit=explicit or self.restart or bool(self.ply))


def build(paths, catalogue: Catalogue, georef: Georef | None, out, settings: RunSettings = RunSettings(),
          progress=None) -> dict:
    """build-twin: one scene (:func:`build_twin`) or tiles cell by cell on Dask
    (:func:`twinreg.city.build.build_city_twin`), as :meth:`RunSettings.tiled` decides. ``progress(stage, done,
    total)`` is called as work advances (``done`` and ``total`` None for a scene's stage messages)."""
    paths = [Path(p) for p in paths]
    s = settings
    params = DEFAULT if s.scan_classes else DEFAULT.with_(open_world={"scan_classes": False})
    if s.tiled(paths):
        if s.trajectory is not None:
            raise ParameterError(f"{s.trajectory}: --trajectory is read with one scene file; a tiled run (several "
                                 "files, a folder, a COPC or a large LAS/LAZ) does not read it yet: run the drive's "
                                 "file alone")
        return build_city_twin(paths, catalogue, georef, out, unit=s.unit, tol=s.tol, threshold=s.threshold,
                               cell=s.cell, buffer=10.0 if s.buffer is None else s.buffer, workers=s.workers,
                               scheduler=s.scheduler, restart=s.restart, ply=bool(s.ply), progress=progress,
                               date=s.date, classified=s.classified_scan, min_confidence=s.min_confidence,
                               params=params)
    return build_twin(paths[0], catalogue, georef, out, unit=s.unit, tol=s.tol, threshold=s.threshold,
                      params=params, progress=progress, ply=s.ply is not False, date=s.date,
                      templates=s.cityjson_templates, min_confidence=s.min_confidence, trajectory=s.trajectory)


def build_twin(scene_path, catalogue: Catalogue, georef: Georef | None, out, unit: str = "auto",
               tol: float | None = None, params: Settings = DEFAULT, progress=None,
               threshold: float | None = None, ply: bool = True, date: str | None = None,
               templates: bool = False, min_confidence: float | None = None, trajectory=None) -> dict:
    """Detect, describe, cluster, match and export one scene. Returns the twin JSON (also written to OUT;
    ``ply=False`` leaves out twin.ply; ``date``: the survey's date, ``YYYY-MM-DD``, else the LAS/LAZ header's;
    ``templates``: CityJSON with geometry templates).

    georef : from :func:`~twinreg.geo.georef.georef_from_options`, or None to use the CRS the file states. tol,
    threshold : the size tolerance and cluster threshold (m), ``params.matching.size_tol`` and
    ``params.taxonomy.threshold`` when None. progress : :mod:`twinreg.progress`'s ``progress(stage, done, total)``, a
    message as each stage starts and counts as the objects of the matching are done. trajectory : a mobile
    survey's trajectory file (:mod:`twinreg.io.trajectory`): what its scanners could not see is unknown, not absent.
    """
    t_start = time.perf_counter()
    timing = {}
    params = checked_params(params, tol, threshold, min_confidence)
    scene_path = Path(scene_path)

    check_point_file(scene_path)
    inputs = [scene_path, catalogue.folder] + ([Path(trajectory)] if trajectory is not None else [])
    check_replaceable(Path(out), protect=inputs, kind="twin")
    with locked(Path(out), "build-twin"):
        return _locked_build(scene_path, catalogue, georef, out, unit, params, progress, t_start, timing, ply, date,
                             templates, trajectory)


def _locked_build(scene_path, catalogue, georef, out, unit, params, progress, t_start, timing, ply, date,
                  templates, trajectory=None) -> dict:
    require_models(catalogue)
    params = with_targets(catalogue, params)

    prober = Prober.start()  # open3d loads in a helper while this process detects and registers
    painter = Painter.start()  # the pictures (SVG: no import to warm), the fused shapes' half
    try:
        return _build(scene_path, catalogue, georef, out, unit, params, progress, painter, t_start, timing, ply,
                      date, templates, prober, trajectory)
    finally:
        if painter:
            painter.stop()
        if prober:
            prober.stop()


def _build(scene_path, catalogue, georef, out, unit, params, progress, painter, t_start, timing,
           ply=True, date=None, templates=False, prober=None, trajectory=None) -> dict:
    say(progress, "reading and detecting")
    given = georef is not None and georef.crs_source == "--crs"
    located = {}

    def placed(scene):  # a scan that the CRS puts elsewhere on Earth is refused before its detection
        located["georef"] = locate(scene_georef(georef, scene), scene.points.min(0), scene.points.max(0),
                                   str(scene_path))
        if scene.from_ground and len(scene.points) >= params.jit_preload_points:
            # a street seen from the ground: clutter of a thousand components, whose joins enable the kernels
            # (many, below); numba loads on a thread meanwhile, the detection goes on with the references
            preload(*KERNEL_MODULES, later=DETECTED)

    def many(n_components: int) -> None:  # a street's clutter: the kernels pay from its joins on (cosco.kernels)
        if n_components >= params.jit_min_components:
            timing["kernels"] = enable(*KERNEL_MODULES, later=DETECTED)

    det = detect_file(scene_path, unit=unit, params=params, crs=georef.crs if given else None,
                      override_crs=given and georef.override, on_read=placed, trajectory=trajectory,
                      on_components=many)
    georef = located["georef"]
    settle()  # a preload done before the forks to come, whether or not the kernels are enabled
    timing.update(det.timing_s)
    timing["objects"] -= timing.get("kernels", 0.0)  # loaded during the detection: counted once, as the kernels
    targets = det.objects
    if not targets:
        what = "objects" if params.segment.targets == "all" else "car-sized objects"
        raise SceneReadError(f"{scene_path}: no {what} were found; check --unit (the scene's unit) and that the "
                             "scan covers what the catalogue holds")
    if len(targets) >= params.jit_min_objects:  # the compiled kernels pay for numba's import (cosco.kernels)
        if prober:  # and the distances here pay for open3d's import (the fused shapes load it here anyway)
            prober.answer_here()
        timing["kernels"] = timing.get("kernels", 0.0) + enable(*KERNEL_MODULES, later=DETECTED)
    say(progress, f"sections of {len(targets)} objects")
    t = time.perf_counter()
    shapes, clouds, levels = described(det, params, split=True)
    timing["sections"] = time.perf_counter() - t


    spacing = [point_spacing(c) for c in clouds]
    clusters = taxonomy(shapes, params, timing, progress, spacing=spacing)
    with staged_folder(Path(out), protect=[scene_path, catalogue.folder], kind="twin") as stage:
        try:
            names = [f"obj{k + 1}" for k in range(len(targets))]
            pictures = Pending(painter, plot_taxonomy, stage, names, clusters.matrix, clusters.linkage,
                               clusters.threshold) if clusters.method == "full" else None
            run = SceneRun(stage=stage, scene_path=scene_path, catalogue=catalogue, georef=georef, det=det,
                           targets=targets, shapes=shapes, clusters=clusters, params=params, progress=progress,
                           timing=timing, t_start=t_start, painter=painter, taxonomy=pictures, ply=ply, date=date,
                           templates=templates, prober=prober, levels=levels, clouds=clouds,
                           spacing=spacing, trajectory=trajectory)
            twin = _match_and_export(run)
        except BaseException:
            for helper in (painter, prober):  # a helper may be writing into the stage: stopped before it goes
                if helper:
                    helper.stop()
            raise
    return twin


#: a scene of at most this many objects writes its records' formats (CityJSON, GeoJSON, GeoPackage, sections.json)
#: in a forked child, on the other core (on a thread they share this process's lock: KITTI 000000's main process
#: 5.56 -> 4.55 CPU-s); above it on a thread, as a city does: the child copies the pages of every record it reads
#: (about 35 kB an object, docs/PERFORMANCE.md, "The survey's resume under 4 GiB")
RECORDS_FORK_MAX_OBJECTS = 5000
#: kernels a scene no longer calls once its ground and components are found, where it enables its kernels (in the
#: segmentation's joins, or after the detection), and a city's tile reader (box_rows): not loaded then (about
#: 0.1 s of a sweep's 0.6 here); ``cosco.kernels.fast`` loads one on its first call if a path still asks for it
DETECTED = ("cosco.ground.", "cosco.segment.components.", "cosco.arrays._box_rows_fast")

#: how long the scan's files (the classified COPC, the observation record) may take in their forked child, beyond
#: HELPER_TIMEOUT_S, before this process writes them itself (s a point; about 1 us a point is usual)
SCAN_FILES_S_PER_POINT = 5e-6


@dataclass
class SceneRun:
    """One scene's run once its objects are described: where it writes (``stage``), what it read (``scene_path``,
    the detection ``det``, its ``targets`` and their ``shapes``, the taxonomy ``clusters``), with what
    (``catalogue``, ``georef``, ``params``), and how it runs (``progress``, ``timing``, ``t_start``, the picture
    helper ``painter`` and its ``taxonomy`` job, ``ply``, the distance helper ``prober``); each object's
    ``levels`` of symmetry, points (``clouds``, the detection's, read once) and point ``spacing``."""

    stage: Path
    scene_path: Path
    catalogue: Catalogue
    georef: Georef
    det: object
    targets: list
    shapes: list
    clusters: object
    params: Settings
    progress: object
    timing: dict
    t_start: float
    painter: object
    taxonomy: object
    ply: bool = True
    date: str | None = None
    templates: bool = False
    prober: object = None
    levels: list | None = None
    clouds: list | None = None
    spacing: list | None = None
    trajectory: Path | None = None


def _match_and_export(run: SceneRun) -> dict:
    stage, scene_path, catalogue, georef, det = run.stage, run.scene_path, run.catalogue, run.georef, run.det
    targets, shapes, clusters, params, progress = run.targets, run.shapes, run.clusters, run.params, run.progress
    timing, t_start, painter, taxonomy, ply = run.timing, run.t_start, run.painter, run.taxonomy, run.ply
    local = det.scene.local
    offset = det.scene.offset
    say(progress, "prefilter and registration")
    noise = scene_noise(det.hag, det.is_ground)
    models = ModelCache(catalogue, params, prober=run.prober)
    # a scene of many objects (a sweep) matches half its clusters in a child forked for them (the same outcomes)
    results, stats = match_objects(shapes, catalogue, labels=clusters.labels, params=params,
                                   evidence=Evidence(run.clouds, noise, seen=objects_seen(det, targets, params)),
                                   cache=models, split=True,
                                   done=(lambda k, n: say(progress, "matching", k, n)) if progress else None)
    timing["prefilter"] = stats.prefilter_s
    timing["model_prep"] = stats.model_prep_s
    timing["registration"] = stats.registration_s
    timing["verification"] = stats.verification_s

    say(progress, "export")
    t = time.perf_counter()
    results, placed = finish([f"obj{k + 1}" for k in range(len(targets))], [o.n_points for o in targets], results,
                             shapes, clusters.labels, [offset] * len(targets), run.levels, run.spacing,
                             lambda outcomes: run.clouds, georef, models, catalogue, params, timing, progress)
    objects = [p.doc for p in placed]

    sc = det.scene
    when, source, warnings = survey_date(run.date, [(sc.survey_date, sc.survey_date_source, sc.survey_date_warning)])
    scan = ScanSummary(scene_path.name, len(sc.points), sc.n_outliers, sc.unit, offset, noise, sc.points,
                       survey_date=when, survey_date_source=source, warnings=warnings,
                       scan_classes=classes_doc(sc.classes, params.open_world.scan_classes),
                       viewpoints=viewpoints_doc(sc, run.trajectory))
    twin = twin_document(scan, georef, objects, clusters, params, MatchSummary(stats, catalogue.count()))
    sections = [section_item(p) for p in placed]
    # the pictures are drawn by the helper process, the sections' picture and the KMZ by the distance helper (done
    # with its queries), while this one writes the other files
    helper = run.prober.helper if run.prober else None
    section_pic = Pending(helper, plot_object_sections, sections, stage / "sections.svg") if helper else None
    report_args = (stage, twin | {"timing_s": {"total": time.perf_counter() - t_start}},
                   {"scene_local": local, "is_ground": det.is_ground, "footprints": [p.footprint() for p in placed],
                    "hag": det.hag, "title": f"{scene_path.name}: {len(objects)} objects"},
                   None if section_pic else sections)
    report = Pending(painter, write_report, *report_args)
    rows, colours = scan_sample(det.scene.points, det.hag, det.is_ground)
    files = TwinFiles(stage, scene_path.name, placed, georef, models, [("scene", list(range(len(placed))))],
                      [("scene", det.scene.points[rows], colours)], ply="twin" if ply else None,
                      templates=run.templates, helper=run.prober.helper if run.prober else None,
                      fork=len(placed) <= RECORDS_FORK_MAX_OBJECTS)

    def scan_files():  # the classified scan and the observation record, while the formats are written
        classes, ids = scan_classes(len(det.scene.points), det.is_ground, targets,
                                    [o["match"] is not None for o in objects])
        write_classified(stage / "scan.copc.laz", det.scene.points, classes, ids, georef)
        return {"observation": observed.write(stage / observed.FILE, [observed.raster(
            det.scene.points, det.hag, det.is_ground, det.scene.points.min(0), det.scene.points.max(0) + 1e-6)],
            [s.sections for s in shapes])}

    # in a child forked before the formats' thread starts (it inherits the scan rather than being sent it), on the
    # other core while this process writes the formats; here when it cannot fork, fails or dies
    scans = Forked(scan_files)
    try:
        twin |= write_twin(files, beside=lambda: scans.wait(
            timeout=HELPER_TIMEOUT_S + SCAN_FILES_S_PER_POINT * len(det.scene.points)))
    finally:
        scans.stop()
    # each job done there or, when its helper is missing, stuck or failed, here (the pictures within one deadline)
    deadline = time.monotonic() + HELPER_TIMEOUT_S
    for job in (taxonomy, report, section_pic):
        if job is not None:
            job.wait(timeout=max(deadline - time.monotonic(), 0.0))
    timing["export"] = time.perf_counter() - t
    timing["total"] = time.perf_counter() - t_start
    twin["timing_s"] = {k: round(v, 4) for k, v in timing.items()}
    (stage / "twin.json").write_text(json.dumps(twin, indent=2), encoding="utf-8")
    return twin
