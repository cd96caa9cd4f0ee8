"""build_twin: the stages in order (read, ground, objects, sections, matrix, clustering, prefilter, registration,
export) with timings and progress; everything is written into a staging folder that replaces OUT as a whole."""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np

import cosco
from cosco.footprint import min_area_rectangle
from cosco.params import DEFAULT, CoscoParams

from .acceptance import scene_noise
from .catalogue.repository import Catalogue
from .detect import describe_detected, detect_file
from .errors import CatalogueError, SceneReadError
from .export.kmz import box_mesh, write_kmz
from .export.painter import HELPER_TIMEOUT_S, HelperError, Painter
from .export.report import plot_taxonomy, warm_up, write_report
from .export.twin_ply import cluster_color, write_twin_ply
from .georef import Georef, scene_georef
from .matching import ModelCache, match_objects
from .outdir import check_replaceable, staged_folder


def _say(progress, msg):
    if progress:
        progress(msg)


def _registered_sections(model_sections: cosco.Sections, reg: cosco.Registration) -> dict:
    """A model's sections moved onto the object's (for the report), when the turn keeps them in their planes."""
    c = np.cos(reg.rz)
    if abs(c) < 0.5:
        return {}
    lon = model_sections.longitudinal * [c, 1.0] + [reg.du, reg.tz]
    tra = model_sections.transverse * [c, 1.0] + [0.0, reg.tz]
    return {"lon": lon, "tra": tra}


def _checked_params(params: CoscoParams, tol: float | None, threshold: float | None) -> CoscoParams:
    """``params`` with the size tolerance and cluster threshold the user gave (both must be positive)."""
    from .errors import require_positive

    tol = require_positive("--tol", tol, f" (default {params.size_tol:g})")
    threshold = require_positive("--threshold", threshold, f" (default {params.cluster_threshold:g})")
    return params.with_(size_tol=params.size_tol if tol is None else tol,
                        cluster_threshold=params.cluster_threshold if threshold is None else threshold)


def build_twin(scene_path, catalogue: Catalogue, georef: Georef | None, out, unit: str = "auto",
               tol: float | None = None, params: CoscoParams = DEFAULT, progress=None,
               threshold: float | None = None) -> dict:
    """Detect, describe, cluster, match and export one scene. Returns the twin JSON (also written to OUT).

    georef : from :func:`~twinreg.georef.georef_from_options`, or None to use the CRS the file states. tol,
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
        return _build(scene_path, catalogue, georef, out, unit, params, progress, painter, t_start, timing)
    finally:
        if painter:
            painter.stop()


def _build(scene_path, catalogue, georef, out, unit, params, progress, painter, t_start, timing) -> dict:
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

    _say(progress, "dissimilarity matrix")
    t = time.perf_counter()
    matrix = cosco.dissimilarity_matrix([s.sections for s in shapes], params)
    timing["matrix"] = time.perf_counter() - t
    t = time.perf_counter()
    clusters = cosco.cluster(matrix, params)
    timing["clustering"] = time.perf_counter() - t

    with staged_folder(Path(out), protect=[scene_path, catalogue.folder]) as stage:
        names = [f"obj{k + 1}" for k in range(len(targets))]
        taxonomy = painter.submit(plot_taxonomy, stage, names, matrix, clusters.linkage, clusters.threshold) \
            if painter else None
        twin = _match_and_export(stage, scene_path, catalogue, georef, det, targets, shapes, matrix, clusters,
                                 params, progress, timing, t_start, painter, taxonomy)
    return twin


def _match_and_export(stage, scene_path, catalogue, georef, det, targets, shapes, matrix, clusters, params,
                      progress, timing, t_start, painter, taxonomy) -> dict:
    local = det.scene.local
    offset = det.scene.offset
    _say(progress, "prefilter and registration")
    noise = scene_noise(det.hag, det.is_ground)
    models = ModelCache(catalogue, params)
    results, stats = match_objects(shapes, catalogue, labels=clusters.labels, params=params,
                                   clouds=[local[o.indices] for o in targets], noise=noise, cache=models)
    timing["prefilter"] = stats["prefilter_s"]
    timing["model_prep"] = stats["model_prep_s"]
    timing["registration"] = stats["registration_s"]
    timing["verification"] = stats["verification_s"]

    _say(progress, "export")
    t = time.perf_counter()
    objects, ply_parts, kmz_objects, meshes, footprints, section_items = [], [], [], {}, [], []
    for k, (o, res) in enumerate(zip(targets, results)):
        oid = f"obj{k + 1}"
        shape, m = res.shape, res.match
        label = int(clusters.labels[k])
        rgb = cluster_color(label)
        if m is not None:
            # the twin carries each model decimated to Google Earth's 21,845 triangles (cached in the catalogue),
            # in the PLY as in the KMZ: the rows, meshes and sections the matcher already read
            row, (mv, mf) = models.row(m.model_id), models.mesh(m.model_id)
            msec = models.geometry(m.model_id).sections
            placed = mv @ m.transform[:3, :3].T + m.transform[:3, 3]
            heading = m.heading
            size = {"length": row.length, "width": row.width, "height": row.height}
            centre_local = m.centre
            mesh_key = f"model{m.model_id}"
            if mesh_key not in meshes:
                meshes[mesh_key] = (mv, mf, tuple(rgb / 255.0))
            match_doc = {"model_id": m.model_id, "name": m.name, "make": row.make, "model": row.model,
                         "rmse_m": round(m.rmse, 4), "rz": round(m.rz, 6), "tz": round(m.tz, 4), "du": round(m.du, 4),
                         "n_candidates": m.n_candidates, "n_trials": m.n_trials, "runner_up": m.runner_up,
                         "verification": m.verdict.as_dict() if m.verdict is not None else None}
            reg = cosco.Registration(m.rmse, m.rz, m.tz, m.du)
            section_items.append({"title": f"{oid}: {m.name} ({m.rmse * 100:.1f} cm)",
                                  "object": {"lon": shape.sections.longitudinal, "tra": shape.sections.transverse},
                                  "model": _registered_sections(msec, reg)})
        else:
            s = shape.size
            bv, bf = box_mesh(s.length, s.width, s.height)
            c, sn = np.cos(shape.heading), np.sin(shape.heading)
            rot = np.array([[c, -sn, 0], [sn, c, 0], [0, 0, 1.0]])
            base = shape.frame.to_scene(np.array([[0.0, 0.0, 0.0]]))[0]
            placed = bv @ rot.T + base
            heading = shape.heading
            size = s.as_dict()
            centre_local = shape.centroid
            mesh_key = f"box_{oid}"
            meshes[mesh_key] = (bv, bf, (0.9, 0.2, 0.2))
            match_doc = None
            section_items.append({"title": f"{oid}: no match ({res.reason})",
                                  "object": {"lon": shape.sections.longitudinal, "tra": shape.sections.transverse}})
        ply_parts.append((placed, mf if m is not None else bf, label))
        centre_scene = np.asarray(centre_local) + offset
        lon, lat, h = georef.to_wgs84(centre_scene[None])[0]
        bearing = georef.bearing(centre_scene, heading)
        doc = {"id": oid, "n_points": int(o.n_points), "centroid": [float(v) for v in centre_scene],
               "heading_rad": float(heading), "size": {k2: round(float(v), 3) for k2, v in size.items()},
               "measured_size": shape.size.as_dict(),
               "symmetry": {"found": bool(shape.symmetry.found), "pcr": round(float(shape.symmetry.pcr), 4)},
               "cluster": label, "match": match_doc, "lat": float(lat), "lon": float(lon),
               "bearing_deg": round(bearing, 3)}
        if match_doc is None:
            doc["reason"] = res.reason
            if res.rejected:
                doc["rejected_model"] = res.rejected
        objects.append(doc)
        description = (f"{match_doc['name']} ({match_doc['make'] or ''} {match_doc['model'] or ''}), RMSE "
                       f"{match_doc['rmse_m'] * 100:.1f} cm" if match_doc else f"unmatched: {res.reason}")
        kmz_objects.append({"id": oid, "lon": lon, "lat": lat, "alt": 0.0, "bearing": bearing, "mesh": mesh_key,
                            "description": description,
                            "data": {"model": match_doc["name"] if match_doc else "none",
                                     "make": (match_doc or {}).get("make") or "",
                                     "length_m": f"{size['length']:.2f}", "width_m": f"{size['width']:.2f}",
                                     "height_m": f"{size['height']:.2f}",
                                     "rmse_m": f"{match_doc['rmse_m']:.4f}" if match_doc else "",
                                     "cluster": label}})
        corners = placed[:, :2]
        rect = min_area_rectangle(corners)
        ctr = np.asarray(centre_local)[:2]
        footprints.append({"corners": rect.corners(), "color": rgb / 255.0, "centre": ctr,
                           "front": ctr + 1.5 * np.array([np.cos(heading), np.sin(heading)]),
                           "label": oid[3:] + ("" if m else "?")})

    twin = {
        "scene": scene_path.name, "n_points": int(len(det.scene.points)), "n_outliers": det.scene.n_outliers,
        "unit": det.scene.unit,
        "georef": georef.to_json() | {"scan_centre": georef.centre_of(det.scene.points)},
        "offset": [float(v) for v in offset], "noise_m": round(noise, 4),
        "objects": objects,
        "dissimilarity": [[round(float(v), 5) for v in row] for row in matrix],
        "clustering": {"threshold_m": clusters.threshold, "n_clusters": clusters.n_clusters},
        "matching": {"tol_m": params.size_tol, "catalogue_models": catalogue.count(), "n_trials": stats["n_trials"],
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
    write_twin_ply(stage / "twin.ply", ply_parts, offset, georef.to_json(), scene_path.name)
    write_kmz(stage / "twin.kmz", f"twinreg: {scene_path.name}", kmz_objects, meshes)
    try:
        if painter is None:
            raise HelperError("no helper process")
        deadline = time.monotonic() + HELPER_TIMEOUT_S
        painter.result(taxonomy, timeout=max(deadline - time.monotonic(), 0.0))
        painter.result(report, timeout=max(deadline - time.monotonic(), 0.0))
    except HelperError:  # the helper is a speed-up only: stop it and draw here if it is missing, stuck or failed
        if painter is not None:
            painter.stop()
        plot_taxonomy(stage, [o["id"] for o in objects], matrix, clusters.linkage, clusters.threshold)
        write_report(*report_args)
    timing["export"] = time.perf_counter() - t
    timing["total"] = time.perf_counter() - t_start
    twin["timing_s"] = {k: round(v, 4) for k, v in timing.items()}
    (stage / "twin.json").write_text(json.dumps(twin, indent=2), encoding="utf-8")
    return twin
