"""The exports of a tiled run: twin.json (every object in the contract's shape, plus a summary per cell), the
KMZ with one Folder and Region per cell, optional PLY files per cell, and a report that summarises instead of
drawing n x n pictures. Everything is written to a staging folder that replaces OUT as a whole; the finished
cells move along with it (``OUT/.cells``) so that a rerun can reuse them."""

from __future__ import annotations

import json
import os
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..export.formats import TwinFiles, write_twin
from ..export.twin_json import MatchSummary, ScanSummary, survey_date, twin_document
from ..io import observed
from ..io.asprs import NAMES, classes_doc
from ..io.outdir import staged_folder
from ..report.city import write_city_report
from ..stages import finish
from .batches import read_clouds
from .classified import FOLDER as CLASSIFIED
from .resume import WORK


def _cell_bounds(georef, cell) -> dict:
    corners = np.array([[cell.lo[0], cell.lo[1], 0.0], [cell.hi[0], cell.lo[1], 0.0], [cell.hi[0], cell.hi[1], 0.0],
                        [cell.lo[0], cell.hi[1], 0.0]])
    ll = georef.to_wgs84(corners)
    return {"north": float(ll[:, 1].max()), "south": float(ll[:, 1].min()), "east": float(ll[:, 0].max()),
            "west": float(ll[:, 0].min())}


@dataclass
class CityRun:
    """A tiled run as the export needs it: where it writes (``out``, the paths it may not hold, the cell store and
    the cells' keys), what it read (``sources``, the ``plan``, ``georef``), what the cells and the matching gave
    (``results``, ``objects``, the taxonomy ``tax``, ``outcomes``, ``stats``, the model cache ``models``), and how
    it ran (``catalogue``, ``params``, ``ply``, ``timing``, ``t_start``, ``progress``, cells ``reused``; the
    survey's ``date``). A city's twin.city.json has geometry templates (explicit geometry of 2,000 triangles a car
    is 500 MB for 5,200 cars); twin.city.jsonl, read a feature at a time, has the explicit geometry."""

    out: Path
    protect: list
    store: object
    keys: dict
    sources: list
    plan: object
    georef: object
    results: list
    objects: list
    tax: object
    outcomes: list
    stats: object
    models: object
    catalogue: object
    params: object
    ply: bool
    timing: dict
    t_start: float
    progress: object = None
    reused: int = 0
    date: str | None = None
    classified: dict | None = None


def _unmatched_clouds(run: CityRun, outcomes: list) -> list:
    """Each object's point sample (its local frame, as its shape's) for the objects without a model in
    ``outcomes``, read from their cells' files (:func:`~.batches.read_clouds`: each file opened once; the run
    holds no sample beyond these); None for the others."""
    where = [(str(run.store.path(r.name, r.key)), i) for r in run.results for i in range(len(r.objects))]
    return read_clouds([o.cloud for o in run.objects],
                       [w if res.match is None else None for w, res in zip(where, outcomes)])


def city_classes_doc(results: list, on: bool) -> dict:
    """twin.json's ``scan_classes`` for a city run: the ASPRS classes the kinds read that any cell's points carry
    (:attr:`~twinreg.city.cells.CellResult.codes`; a code a cell file gives that the kinds do not read is ignored),
    as :func:`~twinreg.io.asprs.classes_doc` says them for one scene.

    >>> from types import SimpleNamespace as R
    >>> city_classes_doc([R(codes=[2, 6]), R(codes=["../6", True, 99, 5.0]), R(codes=None)], True)
    {'used': True, 'codes': {'2': 'ground', '6': 'building'}}
    >>> city_classes_doc([R(codes=["6"])], True)["used"]  # a foreign cell file's codes name nothing
    False
    """
    codes = sorted({c for r in results for c in (r.codes or []) if type(c) is int and c in NAMES})
    return classes_doc(np.array(codes, dtype=np.uint8) if codes else None, on)


def export_city(run: CityRun) -> dict:
    """Write a tiled run's twin (see the module's text); returns twin.json's document."""
    t = time.perf_counter()
    run.outcomes, outs = finish([o.id for o in run.objects], [o.n_points for o in run.objects], run.outcomes,
                                [o.shape for o in run.objects], run.tax.labels, [o.offset for o in run.objects],
                                [o.level for o in run.objects], [o.spacing for o in run.objects],
                                lambda outcomes: _unmatched_clouds(run, outcomes), run.georef, run.models,
                                run.catalogue, run.params, run.timing, fork=True)
    run.timing["records"] = time.perf_counter() - t
    by_cell: dict = {}
    for item, o in zip(outs, run.objects):
        by_cell.setdefault(o.cell, []).append(item.doc)
    twin = _document(run, [item.doc for item in outs], by_cell)
    with staged_folder(Path(run.out), protect=run.protect, kind="twin") as stage:
        _write_files(run, stage, twin, outs, by_cell)
        run.timing["total"] = time.perf_counter() - run.t_start
        twin["timing_s"] = {k: round(v, 4) for k, v in run.timing.items()}
        (stage / "twin.json").write_text(json.dumps(twin, indent=2), encoding="utf-8")
        # the finished cells go with the twin (a rerun with the same inputs reuses them); splits are dropped
        run.store.prune({(r.name, run.keys[r.name]) for r in run.results})
        if run.store.folder.is_dir():
            os.replace(run.store.folder, stage / WORK)
    return twin


def _document(run: CityRun, docs: list[dict], by_cell: dict) -> dict:
    """twin.json's document (without its files' entries and timings): the scan, the objects, the taxonomy, the
    matching, the grid and a summary per cell."""
    sources, results, plan = run.sources, run.results, run.plan
    cells = []
    for r in results:
        own = by_cell.get(r.name, [])
        cells.append({"name": r.name, "bounds": [float(v) for v in (*r.lo, *r.hi)], "n_points": r.n_points,
                      "n_ground": r.n_ground, "n_outliers": r.n_outliers, "noise_m": round(r.noise, 4),
                      "n_objects": len(own), "n_matched": sum(1 for d in own if d["match"]),
                      "timing_s": {k: round(v, 3) for k, v in r.timing_s.items()}})
    lo = np.min([s.lo for s in sources], axis=0)
    hi = np.max([s.hi for s in sources], axis=0)
    names = [Path(s.path).name for s in sources]
    when, source, warnings = survey_date(run.date, [(s.date, s.date_source, s.date_warning) for s in sources])
    scan = ScanSummary(names[0] if len(names) == 1 else f"{len(names)} tiles ({names[0]} ...)",
                       sum(r.n_points for r in results), sum(r.n_outliers for r in results), sources[0].unit,
                       np.asarray(plan.offset), float(np.median([r.noise for r in results if r.n_points])),
                       np.vstack([lo, hi]), sources=[s.path for s in sources], survey_date=when,
                       survey_date_source=source, warnings=warnings,
                       scan_classes=city_classes_doc(results, run.params.open_world.scan_classes))
    grid = {"cell_m": plan.grid.size, "buffer_m": plan.grid.buffer, "read_margin_m": plan.grid.reach,
            "n_cells": plan.n_cells, "n_cells_reused": int(run.reused), "origin": [0.0, 0.0]}
    return twin_document(scan, run.georef, docs, run.tax, run.params,
                         MatchSummary(run.stats, run.catalogue.count(), worker_stages=True),
                         tail={"grid": grid, "cells": cells})


def _write_files(run: CityRun, stage: Path, twin: dict, placed: list, by_cell: dict) -> None:
    """Every file of the twin but twin.json into ``stage``: the twin's formats (:func:`~twinreg.export.formats.
    write_twin`; a KMZ folder and PLY file a cell) and the report; then the classified scan the workers wrote and
    the observation record. The records' formats are written on a thread here, not in a forked child: the child
    copied the pages of every record it read (Python's reference counts write to them), 35 kB an object, and at
    47,040 objects its 1.6 GB made the survey's peak (docs/PERFORMANCE.md); the thread costs the 97M-point city's
    formats 2 s more."""
    results, objects, georef, plan = run.results, run.objects, run.georef, run.plan
    t = time.perf_counter()
    rows: dict = {}
    for k, o in enumerate(objects):
        rows.setdefault(o.cell, []).append(k)
    for r in results:  # a kept cell's tiles are where this run's store keeps them, whatever its file says
        if r.scan_tiles:
            r.scan_tiles = dict(r.scan_tiles, folder=str(run.store.scan_folder() / f"{r.name}-{run.keys[r.name]}"))
    cells = [r for r in results if r.name in rows]
    files = TwinFiles(stage, twin["scene"], placed, georef, run.models, [(r.name, rows[r.name]) for r in cells],
                      [(r.name, r.scan_tiles) for r in results if r.scan_tiles], ply="groups" if run.ply else None,
                      regions={r.name: _cell_bounds(georef, plan.cells[r.name]) for r in cells}, templates=True,
                      seq=True)
    twin |= write_twin(files, beside=lambda: write_city_report(stage, twin, results, objects, run.outcomes, plan))
    run.timing["formats"] = time.perf_counter() - t
    if run.classified is not None:  # the cells' classified COPC files, written on the workers
        os.replace(run.store.folder / CLASSIFIED, stage / CLASSIFIED)
        twin["classified_scan"] = run.classified
    twin["observation"] = observed.write(stage / observed.FILE, [r.observed for r in results if r.observed],
                                         [o.shape.sections for o in objects])
