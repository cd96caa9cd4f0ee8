"""The stages a scene and a city both run, one copy: the run's parameters checked (:func:`checked_params`), the
catalogue checked (:func:`require_models`), the scan placed on Earth (:func:`locate`), the objects' taxonomy
(:func:`classify`), every object placed (:func:`place`). The per-scene pipeline
(:mod:`twinreg.pipeline`) runs them on one scene; the city engine (:mod:`twinreg.city`) maps them over cells and
batches; the simulator's accuracy runs use them too. Nothing here imports the pipeline or the city engine."""

from __future__ import annotations

import time

import cosco
from cosco.params import CoscoParams

from .errors import CatalogueError


def _say(progress, msg):
    if progress:
        progress(msg)


def checked_params(params: CoscoParams, tol: float | None, threshold: float | None) -> CoscoParams:
    """``params`` with the size tolerance and cluster threshold the user gave (both must be positive)."""
    from .errors import require_positive

    tol = require_positive("--tol", tol, f" (default {params.size_tol:g})")
    threshold = require_positive("--threshold", threshold, f" (default {params.cluster_threshold:g})")
    # a tolerance given by the user is the window, as in the paper: it no longer grows with the point spacing
    return params.with_(size_tol=params.size_tol if tol is None else tol,
                        size_spacing_k=params.size_spacing_k if tol is None else 0.0,
                        cluster_threshold=params.cluster_threshold if threshold is None else threshold)


def require_models(catalogue) -> None:
    """:class:`CatalogueError` naming the folder and the fix when the catalogue a run matches against is missing
    (the folder, or its database) or holds no model."""
    folder = catalogue.folder
    if not folder.exists():
        raise CatalogueError(f"{folder}: no catalogue there (the folder does not exist); pass --library with the "
                             "folder that holds catalogue.sqlite, or add models to a new one with `twinreg "
                             f"--library {folder} add-model MESH`")
    if not catalogue.exists:
        raise CatalogueError(f"{folder}: the folder holds no catalogue (no catalogue.sqlite); pass --library with "
                             "the folder that holds one, or add models with `twinreg add-model MESH`")
    if catalogue.count() == 0:
        raise CatalogueError(f"the catalogue in {folder} is empty; add models with `twinreg add-model MESH` or "
                             "`twinreg import-models DIR`")


def locate(georef, lo, hi, where: str):
    """The georeference of a scan whose footprint is ``lo``-``hi`` (scene metres): refused when its CRS puts it
    outside that CRS's area of use (:func:`~twinreg.geo.georef.check_area`, one line naming ``where``), else with
    the CRS's code and the reference system identified where the scan is."""
    import numpy as np

    from .geo.georef import check_area

    check_area(georef, lo, hi, where)
    centre = georef.centre_of(np.array([np.asarray(lo, dtype=np.float64)[:3], np.asarray(hi, dtype=np.float64)[:3]]))
    return georef.identified(centre["lon"], centre["lat"])


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


def place(ids: list[str], n_points: list[int], outcomes: list, labels, offsets: list, georef, models) -> list:
    """Place every object: its :class:`~twinreg.export.objects.PlacedObject` (the mesh at its pose, where it is
    on Earth, its twin.json record) from its matching outcome, its taxonomy label and ``offsets`` (each (3,), its
    local frame to the scene frame). Every object's lat/lon and bearing come from two vectorised transformations
    (one per object took 8 s at 5,000 objects)."""
    import numpy as np

    from .export.objects import place_object, pose
    from .export.twin_json import object_record

    poses = [pose(res) for res in outcomes]
    centres = np.array([c + np.asarray(off) for (c, _), off in zip(poses, offsets)]).reshape(-1, 3)
    lonlat, bearings = georef.placements(centres, [h for _, h in poses])
    placed = []
    for k, (oid, n, res, label, off) in enumerate(zip(ids, n_points, outcomes, labels, offsets)):
        p = place_object(oid, n, res, int(label), np.asarray(off),
                         (float(lonlat[k, 0]), float(lonlat[k, 1]), float(bearings[k])), models)
        p.doc = object_record(p, georef)
        placed.append(p)
    return placed
