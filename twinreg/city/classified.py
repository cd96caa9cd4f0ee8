"""The classified scan of a tiled run (``--classified-scan``): one COPC file a cell, ``OUT/classified/<cell>.copc.laz``,
with the classes of a scene's scan.copc.laz (:mod:`twinreg.export.classified`).

An object's class (a model or none) is known only after the matching, so a cell's worker keeps its points with
their ground / other class and the number of the object they belong to (``.cells/labels``, kept with the cell for a
rerun), and after the matching one task a cell writes its file. A file holds its cell's core, except that the
points of a car-sized object go with the cell that owns it: every object is whole in one file, and a point's
source id is the ``k`` of its object's id ``<cell>-<k>`` (0: no object)."""

from __future__ import annotations

import os
import shutil
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..export.classified import CAR, GROUND, NO_MODEL, OTHER, write_classified

FOLDER = "classified"
PENDING = 0  # an object's points until its outcome is known


def cell_labels(is_ground: np.ndarray, own: np.ndarray, targets: list, owned: list) -> tuple:
    """(rows, classes, ids) of the points a cell's file holds: the core (``own``) without the car-sized objects
    (``targets``) of other cells, with every point of the cell's own (``owned``, in the order of their ids)."""
    take = own.copy()
    ids = np.zeros(len(own), dtype=np.uint16)
    for o in targets:
        take[o.indices] = False
    for k, o in enumerate(owned):
        take[o.indices] = True
        ids[o.indices] = min(k + 1, 65535)
    rows = np.flatnonzero(take)
    classes = np.where(is_ground[rows], GROUND, OTHER).astype(np.uint8)
    classes[ids[rows] > 0] = PENDING
    return rows, classes, ids[rows]


def save_labels(path: Path, points: np.ndarray, classes: np.ndarray, ids: np.ndarray) -> None:
    """Keep a cell's labelled points (metres, as millimetre integers from their minimum), temp file then
    rename."""
    path.parent.mkdir(parents=True, exist_ok=True)
    origin = points.min(0) if len(points) else np.zeros(3)
    mm = np.round((points - origin) * 1000.0).astype(np.int32) if len(points) else np.zeros((0, 3), np.int32)
    tmp = path.with_name(f".tmp-{path.name}")
    with open(tmp, "wb") as f:
        np.savez(f, origin=origin, mm=mm, classes=classes, ids=ids)
    os.replace(tmp, path)


@dataclass(frozen=True)
class CopcJob:
    """One cell's file: its ``labels``, the ``out`` path, the class of each of its objects (``k`` - 1 indexes
    ``classes``) and the run's ``georef`` (its CRS and units)."""

    labels: str
    out: str
    classes: tuple
    georef: object


def write_cell_copc(job: CopcJob) -> int:
    """Write one cell's classified COPC as a scene's is written (temp file then rename); returns its number of
    points (0: no file)."""
    with np.load(job.labels, allow_pickle=False) as z:
        origin, mm, classes, ids = z["origin"], z["mm"], z["classes"].copy(), z["ids"]
    if not len(mm):
        return 0
    lut = np.array([PENDING, *job.classes], dtype=np.uint8)
    mine = ids > 0
    classes[mine] = lut[np.minimum(ids[mine], len(lut) - 1)]
    out = Path(job.out)
    tmp = out.with_name(f".tmp-{out.name}")
    write_classified(tmp, origin + mm / 1000.0, classes, ids, job.georef)
    os.replace(tmp, out)
    return int(len(mm))


def write_classified_cells(eng, results, objects, outcomes, store, keys, georef, progress=None) -> dict:
    """Write every cell's file into ``store.folder / FOLDER`` (one task a cell on the workers); returns twin.json's
    ``classified_scan`` (the files, relative to OUT, and their points)."""
    folder = store.folder / FOLDER
    shutil.rmtree(folder, ignore_errors=True)
    folder.mkdir(parents=True)
    by_cell: dict = {}
    for o, res in zip(objects, outcomes):
        by_cell.setdefault(o.cell, {})[int(o.id.rsplit("-", 1)[1])] = CAR if res.match is not None else NO_MODEL
    jobs, names = [], []
    for r in results:
        labels = store.labels_path(r.name, keys[r.name])
        if not labels.is_file():
            continue
        got = by_cell.get(r.name, {})
        classes = tuple(got.get(k, NO_MODEL) for k in range(1, max(got, default=0) + 1))
        jobs.append(CopcJob(str(labels), str(folder / f"{r.name}.copc.laz"), classes, georef))
        names.append(r.name)
    if progress:
        progress("classified scan", 0, len(jobs))
    counts = eng.map(write_cell_copc, jobs, names)
    if progress:
        progress("classified scan", len(jobs), len(jobs))
    files = [(n, c) for n, c in zip(names, counts) if c]
    return {"files": [f"{FOLDER}/{n}.copc.laz" for n, _ in files], "n_points": int(sum(c for _, c in files)),
            "classes": {"ground": GROUND, "car_with_model": CAR, "car_sized_without_model": NO_MODEL,
                        "other": OTHER}}
