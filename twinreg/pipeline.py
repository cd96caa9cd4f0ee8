"""build_twin: the stages in order (read, ground, objects, sections, matrix, clustering, prefilter, registration,
export) with timings and progress; everything is written into a staging folder that replaces OUT as a whole."""

from __future__ import annotations

import json
import time
from pathlib import Path

import cosco
from cosco.params import DEFAULT, CoscoParams

from .catalogue.repository import Catalogue
from .detect import describe_detected, detect_file, object_points
from .errors import CatalogueError, HelperError, SceneReadError
from .export.formats import write_formats
from .export.kmz import write_kmz
from .export.objects import object_output
from .export.tiles3d import scan_sample
from .export.twin_ply import write_twin_ply
from .geo.georef import Georef, scene_georef
from .io.outdir import check_replaceable, staged_folder
from .matching.acceptance import scene_noise
from .matching.match import ModelCache, match_objects
from .report.painter import HELPER_TIMEOUT_S, Painter
from .report.scene import plot_taxonomy, warm_up, write_report


def _say(progress, msg):
    if progress:
        progress(msg)


def _checked_params(params: CoscoParams, tol: float | None, threshold: float | None) -> CoscoParams:
    """``params`` with the size tolerance and cluster threshold the user gave (both must be positive)."""
    from .errors import require_positive

    tol = require_positive("--tol", tol, f" (default {params.size_tol:g})")
    threshold = require_positive("--threshold", threshold, f" (default {params.cluster_threshold:g})")
    # a tolerance given by the user is the window, as in the paper: it no longer grows with the point spacing
    return params.with_(size_tol=params.size_tol if tol is None else tol,
                        size_spacing_k=params.size_spacing_k if tol is None else 0.0,
                        cluster_threshold=params.cluster_threshold if threshold is None else threshold)


def build_twin(scene_path, catalogue: Catalogue, georef: Georef | None, out, unit: str = "auto",
               tol: float | None = None, params: CoscoParams = DEFAULT, progress=None,
               threshold: float | None = None, ply: bool = True) -> dict:
    """Detect, describe, cluster, match and export one scene. Returns the twin JSON (also written to OUT;
    ``ply=False`` leaves out twin.ply).

    georef : from :func:`~twinreg.geo.georef.georef_from_options`, or None to use the CRS the file states. tol,
    threshold : the size tolerance and cluster threshold (m), ``params.size_tol`` and ``params.cluster_threshold``
    when None.
    """
    t_start = time.perf_counter()
    timing = {}
    params = _checked_params(params, tol, threshold)
    scene_path = Path(scene_path)
    check_replaceable(Path(out), protect=[scene_path, catalogue.folder])
    if catalogue.count() == 0:
        raise CatalogueError(f"the catalogue in {catalogue.folder} is empty; add models with "
                             "`twinreg add-model MESH` or `twinreg import-models DIR`")
    painter = Painter.start(warm=warm_up)
    try:
        return _build(scene_path, catalogue, georef, out, unit, params, progress, painter, t_start, timing, ply)
    finally:
        if painter:
            painter.stop()


def _build(scene_path, catalogue, georef, out, unit, params, progress, painter, t_start, timing,
           ply=True) -> dict:
    _say(progress, "reading and detecting")
    det = detect_file(scene_path, unit=unit, params=params,
                      crs=georef.crs if georef is not None and georef.crs_source == "--crs" else None)
    georef = scene_georef(georef, det.scene)
    timing.update(det.timing_s)
    targets = det.objects
    if not targets:
        raise SceneReadError(f"{scene_path}: no car-sized objects were found; check --unit (the scene's unit) and "
                             "that the scan covers parked cars")
    _say(progress, f"sections of {len(targets)} objects")
    t = time.perf_counter()
    shapes = describe_detected(det, params)
    timing["sections"] = time.perf_counter() - t

    clusters = classify(shapes, params, timing, progress)
    with staged_folder(Path(out), protect=[scene_path, catalogue.folder]) as stage:
        try:
            names = [f"obj{k + 1}" for k in range(len(targets))]
            taxonomy = painter.submit(plot_taxonomy, stage, names, clusters.matrix, clusters.linkage,
                                      clusters.threshold) if painter and clusters.method == "full" else None
            twin = _match_and_export(stage, scene_path, catalogue, georef, det, targets, shapes, clusters,
                                     params, progress, timing, t_start, painter, taxonomy, ply)
        except BaseException:
            if painter:  # the helper may be drawing into the stage: stopped before the stage is deleted
                painter.stop()
            raise
    return twin


def classify(shapes, params: CoscoParams, timing: dict, progress=None, distances_of=None):
    """The objects' :class:`~cosco.taxonomy.Taxonomy`: the paper's matrix and dendrogram up to
    ``params.taxonomy_full_max`` objects (timed as "matrix" and "clustering"), the sparse graph beyond (timed as
    "matrix": its comparisons and its components)."""
    from cosco.taxonomy import Taxonomy, taxonomy

    t = time.perf_counter()
    if len(shapes) > params.taxonomy_full_max or distances_of is not None:
        _say(progress, f"taxonomy of {len(shapes)} objects")
        tax = taxonomy(shapes, params, distances_of=distances_of)
        timing["matrix"] = time.perf_counter() - t
        timing["clustering"] = 0.0
        return tax
    _say(progress, "dissimilarity matrix")
    matrix = cosco.dissimilarity_matrix([s.sections for s in shapes], params)
    timing["matrix"] = time.perf_counter() - t
    t = time.perf_counter()
    c = cosco.cluster(matrix, params)
    timing["clustering"] = time.perf_counter() - t
    return Taxonomy(c.labels, "full", c.threshold, matrix=matrix, linkage=c.linkage)


def taxonomy_json(tax) -> dict:
    """twin.json's ``dissimilarity`` (the matrix, or None past ``taxonomy_full_max`` objects, when
    ``dissimilarity_pairs`` lists the compared pairs as [i, j, metres]) and ``clustering``."""
    doc = {"clustering": {"threshold_m": tax.threshold, "n_clusters": tax.n_clusters, "method": tax.method,
                          "n_comparisons": tax.n_comparisons}}
    if tax.method == "full":
        doc["dissimilarity"] = [[round(float(v), 5) for v in row] for row in tax.matrix]
    else:
        doc["dissimilarity"] = None
        doc["dissimilarity_pairs"] = [[int(i), int(j), round(float(d), 5)] for (i, j), d in
                                      zip(tax.pairs, tax.distances)]
    return doc


def _match_and_export(stage, scene_path, catalogue, georef, det, targets, shapes, clusters, params,
                      progress, timing, t_start, painter, taxonomy, ply=True) -> dict:
    local = det.scene.local
    offset = det.scene.offset
    _say(progress, "prefilter and registration")
    noise = scene_noise(det.hag, det.is_ground)
    models = ModelCache(catalogue, params)
    results, stats = match_objects(shapes, catalogue, labels=clusters.labels, params=params,
                                   clouds=[object_points(det, o) for o in targets], noise=noise, cache=models)
    timing["prefilter"] = stats["prefilter_s"]
    timing["model_prep"] = stats["model_prep_s"]
    timing["registration"] = stats["registration_s"]
    timing["verification"] = stats["verification_s"]

    _say(progress, "export")
    t = time.perf_counter()
    objects, ply_parts, kmz_objects, meshes, footprints, section_items, outs = [], [], [], {}, [], [], []
    for k, (o, res) in enumerate(zip(targets, results)):
        label = int(clusters.labels[k])
        out = object_output(f"obj{k + 1}", o.n_points, res, label, offset, georef, models)
        objects.append(out.doc)
        kmz_objects.append(out.kmz)
        meshes.setdefault(out.mesh_key, out.mesh)
        ply_parts.append((out.placed, out.faces, label))
        footprints.append(out.footprint)
        section_items.append(out.sections)
        outs.append(out)

    twin = {
        "scene": scene_path.name, "n_points": int(len(det.scene.points)), "n_outliers": det.scene.n_outliers,
        "unit": det.scene.unit,
        "georef": georef.to_json() | {"scan_centre": georef.centre_of(det.scene.points)},
        "offset": [float(v) for v in offset], "noise_m": round(noise, 4),
        "objects": objects,
        **taxonomy_json(clusters),
        "matching": {"tol_m": params.size_tol, "tol_spacing_k": params.size_spacing_k,
                     "catalogue_models": catalogue.count(), "n_trials": stats["n_trials"],
                     "n_pairs_without_prefilter": stats["n_pairs_without_prefilter"],
                     "n_trials_saved_by_clusters": stats["n_trials_saved_by_clusters"],
                     "registration_ms_per_trial": round(1000 * stats["registration_s"] / max(stats["n_trials"], 1),
                                                        3)},
        "timing_s": {},
    }
    report_args = (stage, twin | {"timing_s": {"total": time.perf_counter() - t_start}},
                   {"scene_local": local, "is_ground": det.is_ground, "footprints": footprints, "hag": det.hag,
                    "title": f"{scene_path.name}: {len(objects)} objects"}, section_items)
    # the pictures are drawn by the helper process (already warm) while this one writes the PLY and KMZ
    report = painter.submit(write_report, *report_args) if painter else None
    if ply:
        write_twin_ply(stage / "twin.ply", ply_parts, offset, georef.to_json(), scene_path.name)
    write_kmz(stage / "twin.kmz", f"twinreg: {scene_path.name}", kmz_objects, meshes)
    rows, colours = scan_sample(det.scene.points, det.hag, det.is_ground)
    twin["tiles"] = write_formats(stage, outs, [offset] * len(outs), georef, [("scene", list(range(len(outs))))],
                                  [("scene", det.scene.points[rows], colours)], f"twinreg: {scene_path.name}", models)
    try:
        if painter is None:
            raise HelperError("no helper process")
        deadline = time.monotonic() + HELPER_TIMEOUT_S
        if taxonomy is not None:
            painter.result(taxonomy, timeout=max(deadline - time.monotonic(), 0.0))
        painter.result(report, timeout=max(deadline - time.monotonic(), 0.0))
    except HelperError:  # the helper is a speed-up only: stop it and draw here if it is missing, stuck or failed
        if painter is not None:
            painter.stop()
        if clusters.method == "full":
            plot_taxonomy(stage, [o["id"] for o in objects], clusters.matrix, clusters.linkage, clusters.threshold)
        write_report(*report_args)
    timing["export"] = time.perf_counter() - t
    timing["total"] = time.perf_counter() - t_start
    twin["timing_s"] = {k: round(v, 4) for k, v in timing.items()}
    (stage / "twin.json").write_text(json.dumps(twin, indent=2), encoding="utf-8")
    return twin
