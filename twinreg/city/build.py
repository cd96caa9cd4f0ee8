"""build-twin on tiles: plan the grid, split the plain tiles once, run the cells on Dask (resumable), then the
taxonomy and the matching of all objects (spread over the workers by batches), then the exports.

The per-scene stages run unchanged inside each cell (:mod:`twinreg.city.cells`); this module only maps them over
the grid and gathers what they found.
"""

from __future__ import annotations

import shutil
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

import twinreg

from ..errors import CityError, ParameterError, SceneReadError
from ..geo.georef import CrsInfo, Georef, GeorefError, crs_info
from ..io.outdir import check_replaceable, claim, locked
from ..progress import say
from ..settings import DEFAULT, Settings
from ..stages import checked_params, locate, require_models, with_targets
from .cellfile import run_cell
from .cells import CellJob, SavedCell
from .classified import FOLDER, write_classified_cells
from .engine import Engine
from .export import CityRun, export_city
from .grid import Grid, cell_size_for
from .resume import CellStore, cell_key
from .sources import Source, open_sources, split_key, split_tile

#: a plain LAS/LAZ tile read by more cells than this is split once into them (else each cell reads it by chunks:
#: measured on 250 m LAZ tiles of 9.4M points, a cell's full read of a tile costs about half of splitting it once)
SPLIT_MIN_READERS = 2



@dataclass(frozen=True)
class SplitJob:
    source: Source
    grid: Grid
    folder: str


def run_split(job: SplitJob) -> dict:
    """Worker side: cut one plain LAS/LAZ tile into the cells it feeds (see :func:`~.sources.split_tile`)."""
    return split_tile(job.source, job.grid, job.folder)


@dataclass
class Plan:
    """The grid, its cells (name -> Cell, row by row) and the tiles feeding each cell."""

    grid: Grid
    cells: dict
    feeds: dict
    offset: tuple = (0.0, 0.0, 0.0)

    @property
    def n_cells(self) -> int:
        return len(self.cells)

    def estimate(self, name: str) -> float:
        """Points the cell reads, estimated from the tiles' headers (their densities times the overlap)."""
        c = self.cells[name]
        total = 0.0
        for s in self.feeds[name]:
            lo = np.maximum(np.asarray(s.lo[:2]), c.read_lo)
            hi = np.minimum(np.asarray(s.hi[:2]), c.read_hi)
            total += s.n_points * float(np.prod(np.clip(hi - lo, 0, None))) / s.area
        return total


def plan(sources: list[Source], cell: float | None = None, buffer: float = 10.0, margin: float = 0.0) -> Plan:
    """The processing grid over the tiles: ``cell`` metres (default: about
    :data:`~twinreg.city.grid.TARGET_POINTS` points a cell at the tiles' mean density), objects searched
    ``buffer`` metres wider, points read ``margin`` metres wider (the ground filter's reach)."""
    if buffer < 0:
        raise ParameterError(f"--buffer must be 0 or more (got {buffer:g}); the default is 10 m")
    least = max(2 * buffer, margin)
    if cell is not None and not cell > least:
        raise ParameterError(f"--cell must be more than {least:g} m (twice --buffer, and the ground filter's "
                             f"reach of {margin:g} m); got {cell:g}")
    size = cell or max(cell_size_for(sum(s.n_points for s in sources), sum(s.area for s in sources),
                                     buffer=buffer), 10.0 * np.ceil(least / 10.0 + 1))
    grid = Grid(float(size), float(buffer), float(margin))
    cells: dict = {}
    for s in sources:
        # an object's footprint centre lies inside the points' bounds: cells whose cores miss every tile own none
        for c in grid.cells_over(np.asarray(s.lo[:2]), np.asarray(s.hi[:2])):
            cells.setdefault((c.iy, c.ix), c)
    cells = {c.name: c for _, c in sorted(cells.items())}
    feeds = {}
    for name, c in cells.items():
        feeds[name] = [s for s in sources if (np.asarray(s.lo[:2]) <= c.read_hi).all()
                       and (np.asarray(s.hi[:2]) >= c.read_lo).all()]
    cells = {n: c for n, c in cells.items() if feeds[n]}
    # one local frame for the whole run, chosen as the reader chooses it for one file (a round number under the
    # minimum): the cells then compute exactly what the merged scene would
    lo = np.min([s.lo for s in sources], axis=0)
    offset = (float(np.floor(lo[0] / 100.0) * 100.0), float(np.floor(lo[1] / 100.0) * 100.0), 0.0)
    return Plan(grid, cells, {n: feeds[n] for n in cells}, offset)


def city_georef(georef, sources: list[Source]):
    """The georeference of a tiled run: the options' when given, else the CRS the headers state."""
    s = sources[0]
    if georef is not None and (georef.crs is not None or georef.lat is not None):
        if georef.crs and georef.crs_source == "--crs":
            return georef.with_crs(crs_info(georef.crs, "--crs", where=f"--crs {georef.crs}"))
        return georef
    if s.crs is None:
        raise GeorefError(f"{s.path}: the tiles state no CRS; georeference them with --crs EPSG:NNNN (their "
                          "projected CRS) or --lat/--lon (the WGS84 position of their origin)")

    info = crs_info(s.crs, "file header", where=s.path)
    base = georef or Georef(None, None, 0.0, (0.0, 0.0), None)  # nothing given, or only --vertical-crs
    return base.with_crs(CrsInfo(info.crs, info.name, s.scale, s.z_scale, "file header", info.vertical))


def _clean_work(store: CellStore) -> None:
    """Remove what killed runs left half-written in the work folder (temporary files and split folders)."""
    shutil.rmtree(store.folder / FOLDER, ignore_errors=True)  # a killed run's classified files: written again
    for folder in (store.folder, store.folder / "split", store.folder / "labels"):
        if folder.is_dir():
            for p in folder.glob(".tmp-*"):
                shutil.rmtree(p, ignore_errors=True) if p.is_dir() else p.unlink(missing_ok=True)


def build_city_twin(paths, catalogue, georef, out, unit: str = "auto", tol: float | None = None,
                    threshold: float | None = None, params: Settings = DEFAULT, cell: float | None = None,
                    buffer: float = 10.0, workers: int | None = None, scheduler: str | None = None,
                    restart: bool = False, ply: bool = False, progress=None, date: str | None = None,
                    classified: bool = False, min_confidence: float | None = None) -> dict:
    """Build the twin of tiles (files, folders, globs of LAS/LAZ/COPC) cell by cell on Dask; returns the twin JSON
    (also written to ``out/twin.json``). ``progress(stage, done, total)`` is called as work advances;
    ``classified``: also write the classified scan, a COPC file a cell (:mod:`twinreg.city.classified`);
    ``min_confidence``: the models' confidence floor (None: ``params.min_confidence``)."""
    t_start = time.perf_counter()
    timing: dict = {}
    params = checked_params(params, tol, threshold, min_confidence)
    if workers is not None and workers < 1:
        raise ParameterError(f"--workers must be 1 or more (got {workers})")
    crs = georef.crs if georef is not None and georef.crs_source == "--crs" else None
    sources = open_sources(paths, unit=unit, crs=crs, override_crs=bool(georef is not None and georef.override))
    georef = city_georef(georef, sources)
    p = plan(sources, cell, buffer, params.ground.reach)
    georef = locate(georef, np.min([s.lo for s in sources], axis=0), np.max([s.hi for s in sources], axis=0),
                    sources[0].path if len(sources) == 1 else f"{sources[0].path} and {len(sources) - 1} more tiles")
    if not p.cells:
        raise SceneReadError(f"{sources[0].path}: the tiles hold no points")
    out = Path(out)
    protect = [Path(s.path) for s in sources] + [catalogue.folder]
    check_replaceable(out, protect, kind="twin")
    require_models(catalogue)
    params = with_targets(catalogue, params)
    with locked(out, "build-twin"):
        return _locked_city(sources, georef, p, out, protect, catalogue, params, workers, scheduler, restart, ply,
                            progress, date, classified, t_start, timing)


def _locked_city(sources, georef, p, out, protect, catalogue, params, workers, scheduler, restart, ply, progress,
                 date, classified, t_start, timing) -> dict:
    created = not out.exists()
    claim(out, protect)
    store = CellStore(out)
    try:
        if restart:
            store.clear()
        _clean_work(store)
        keys = {n: cell_key(n, p.feeds[n], p.grid, params, twinreg.__version__, p.offset) for n in p.cells}
        todo = [n for n in p.cells if not store.has(n, keys[n], labels=classified)]
        timing["plan"] = time.perf_counter() - t_start
        with Engine(workers=workers, scheduler=scheduler) as eng:
            timing["kernels"] = eng.kernels_s
            _run_cells(eng, p, todo, keys, store, params, progress, timing, classified)
            # the objects' point samples stay in the cell files until a worker matching them reads them: this
            # process holds about 9 kB an object instead of 45 (the samples of a 1.4-billion-point survey are 3 GB)
            results = [store.load(n, keys[n], clouds=False) for n in p.cells]
            objects = [o for r in results for o in r.objects]
            samples = [(str(store.path(r.name, r.key)), k) for r in results for k in range(len(r.objects))]
            if not objects:
                raise SceneReadError(f"{sources[0].path}: no car-sized objects were found in the tiles; check "
                                     "--unit and that the scan covers parked cars")
            from .gather import classify_and_match

            tax, outcomes, stats, models = classify_and_match(eng, results, objects, catalogue, params, progress,
                                                              timing, samples)
            copc = None
            if classified:
                t = time.perf_counter()
                copc = write_classified_cells(eng, results, objects, outcomes, store, keys, georef, progress)
                timing["classified"] = time.perf_counter() - t
    except BaseException:
        # a folder this run created and in which no cell finished goes again: OUT is as it was
        if created and not any(store.folder.glob("*.npz")):
            shutil.rmtree(out, ignore_errors=True)
        raise

    t = time.perf_counter()
    say(progress, "export", 0, 1)
    run = CityRun(out=out, protect=protect, store=store, keys=keys, sources=sources, plan=p, georef=georef,
                  results=results, objects=objects, tax=tax, outcomes=outcomes, stats=stats, models=models,
                  catalogue=catalogue, params=params, ply=ply, timing=timing, t_start=t_start, progress=progress,
                  reused=p.n_cells - len(todo), date=date, classified=copc)
    twin = export_city(run)
    timing["export"] = time.perf_counter() - t
    say(progress, "export", 1, 1)
    return twin


def _run_cells(eng: Engine, p: Plan, todo: list[str], keys: dict, store: CellStore, params, progress, timing,
               classified: bool = False):
    """Split the plain tiles that feed many unfinished cells, then run those cells; each finished cell is stored
    at once. Failed cells raise :class:`CityError` after the others."""
    t = time.perf_counter()
    # a plain tile read by many cells is decompressed once and cut into them; one read by a few is read by each
    readers: dict = {}
    for n in todo:
        for s in p.feeds[n]:
            if not s.copc:
                readers.setdefault(s.path, [s, 0])[1] += 1
    many = {path: s for path, (s, k) in readers.items() if k > SPLIT_MIN_READERS}
    # splitting is one task per tile: worth it when there are tiles enough to keep every worker busy
    need = many if len(many) >= eng.n_workers else {}
    folders = {path: store.split_folder(split_key(s, p.grid)) for path, s in need.items()}
    # every split at once; each cell waits only for the splits of its own tiles (no barrier between the stages)
    splits = {path: eng.submit(run_split, SplitJob(s, p.grid, str(folders[path])), name=Path(path).name)
              for path, s in need.items()}
    if splits:
        n_split = [0]
        say(progress, "split tiles", 0, len(splits))

        def split_done(_future):
            n_split[0] += 1
            say(progress, "split tiles", n_split[0], len(splits))

        for f in splits.values():
            f.add_done_callback(split_done)
    t = time.perf_counter()
    # the largest cells first (points estimated from the tiles' densities): the workers finish together
    todo = sorted(todo, key=lambda n: -p.estimate(n))
    cell_jobs, deps = [], {}
    for n in todo:
        reads = tuple(str(folders[s.path]) for s in p.feeds[n] if s.path in folders)
        boxes = tuple(s for s in p.feeds[n] if s.path not in folders)
        labels = str(store.labels_path(n, keys[n])) if classified else None
        cell_jobs.append(CellJob(p.cells[n], reads, boxes, params, keys[n], p.offset, str(store.scan_folder()),
                                 labels, str(store.path(n, keys[n]))))
        deps[n] = [splits[s.path] for s in p.feeds[n] if s.path in splits]
    done = [p.n_cells - len(todo)]
    say(progress, "cells", done[0], p.n_cells)

    def cell_done(name, result):
        if not isinstance(result, SavedCell):  # (a worker writes its cell's file itself: nothing to keep here)
            store.save(result)
        done[0] += 1
        say(progress, "cells", done[0], p.n_cells)

    fails = eng.run(run_cell, cell_jobs, todo, on_result=cell_done, deps=deps)
    timing["cells"] = time.perf_counter() - t  # the splits included
    broken = [f"{Path(path).name} ({type(f.exception()).__name__}: {f.exception()})" for path, f in splits.items()
              if f.status == "error"]
    for f in splits.values():
        f.release()
    if broken:
        raise CityError("tiles failed to split: " + "; ".join(broken[:3]) + "; the finished cells are kept: fix "
                        "or remove the tiles and rerun")
    if fails:
        shown = "; ".join(f"{f.name} ({f.error})" for f in fails[:5]) + (" ..." if len(fails) > 5 else "")
        raise CityError(f"{len(fails)} of {p.n_cells} cells failed twice: {shown}; the {done[0]} finished cells are "
                        f"kept in {store.folder}: rerun the same command to compute only the missing ones")
