"""One cell of a city run, as one task on a worker: read the cell's points (with its buffer) from the tiles,
ground, detection and COSCO description (the per-scene stages, unchanged), and keep the objects the cell owns.

A worker gets a :class:`CellJob` (paths and bounds, never points) and returns a :class:`CellResult`: the owned
objects' shapes, a sample of their points for the match verification, and the cell's summary.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from cosco.arrays import point_spacing
from cosco.footprint import min_area_rectangle

from ..detect import describe_detected, detect_points, object_ground, object_levels, object_points
from ..export.scan_tiles import cell_scan_folder, write_cell_scan
from ..export.tiles3d import scan_sample
from ..io.asprs import read_codes
from ..io.observed import raster
from ..io.points import PointSet
from ..matching.acceptance import sample_cloud, scene_noise
from ..memory import release_freed_memory
from ..settings import DEFAULT, Settings
from .classified import cell_labels, save_labels
from .grid import Cell
from .sources import read_box, read_splits


@dataclass(frozen=True)
class CellJob:
    """What a worker needs for one cell: the cell, and for each tile that feeds it either the folder of its split
    (plain LAS/LAZ cut once into cells) or the tile itself (COPC, or a run of one cell), read by bounds; and the
    run's local frame (``offset``, the same for every cell, as a reader would choose for all the tiles merged),
    so that every grid the stages cut lies where it would on the whole scene; ``scan_dir``: where the worker writes
    the cell's scan tiles (every point of its core, :mod:`twinreg.export.scan_tiles`), None for none;
    ``labels``: where it keeps its labelled points for the classified scan (:mod:`twinreg.city.classified`), None
    for none; ``result_path``: where the worker writes the finished cell's file itself (:mod:`twinreg.city.cellfile`:
    the main process neither receives nor writes the objects), None to return them."""

    cell: Cell
    splits: tuple = ()
    boxes: tuple = ()
    params: Settings = DEFAULT
    key: str = ""
    offset: tuple = (0.0, 0.0, 0.0)
    scan_dir: str | None = None
    labels: str | None = None
    result_path: str | None = None


@dataclass
class CellObject:
    """An object the cell owns: ``id`` (cell name and index, the same from run to run), its shape and a sample of
    its points (at most ``matching.accept_max_points``, scene-local: add ``offset``), its point ``spacing`` (m), the
    ground under it and its ``level`` of symmetry (:mod:`cosco.levels`)."""

    id: str
    cell: str
    offset: np.ndarray
    n_points: int
    shape: object
    cloud: np.ndarray
    spacing: float
    ground_z: float
    level: str = "none"


@dataclass
class CellResult:
    """A finished cell: counts over its core, the scan noise measured on its ground, its objects, its timings,
    where its core's scan saw anything (``observed``, a :class:`~twinreg.io.observed.Raster`: the report's map
    and the twin's observation record) and its scan for the 3D tiles: ``scan_tiles``, where the worker wrote every
    point of its core as tiles (:func:`~twinreg.export.scan_tiles.write_cell_scan`)."""

    name: str
    key: str
    lo: tuple
    hi: tuple
    n_read: int = 0  # points read with the margin
    n_points: int = 0  # points of the core
    n_ground: int = 0  # ground points of the core
    n_outliers: int = 0  # far outliers set aside
    noise: float = 0.0  # m, range noise on the ground
    n_segments: int = 0  # segments the core owns
    objects: list = field(default_factory=list)
    timing_s: dict = field(default_factory=dict)
    observed: object = None
    scan_tiles: dict | None = None
    codes: list = field(default_factory=list)  # the ASPRS classes the kinds read that the cell's points carry


@dataclass(frozen=True)
class SavedCell:
    """What a worker returns for a cell it wrote to its ``result_path`` itself: its name, key and object count."""

    name: str
    key: str
    n_objects: int


def read_cell(job: CellJob) -> tuple[np.ndarray, np.ndarray]:
    """The (n, 3) float64 metre points of the cell's buffered square, from every tile that feeds it, and their (n,)
    uint8 ASPRS classes."""
    boxes = [read_box(src, job.cell.read_lo, job.cell.read_hi, classes=True) for src in job.boxes]
    return read_splits(job.splits, job.cell.name, boxes, classes=True)


def process_cell(job: CellJob, *ready) -> CellResult:
    """Read, ground, detection and description of one cell; the objects whose footprint centre lies in the
    cell's half-open core (see :mod:`twinreg.city.grid`). ``ready``: the results of the tile splits it reads
    (the engine passes them so that the cell starts as soon as its own tiles are split). A city's workers run it
    through :func:`twinreg.city.cellfile.run_cell`, which writes the cell's file where ``job.result_path`` says."""
    try:
        return _process_cell(job)
    finally:  # the worker keeps what it frees while it works on a cell (twinreg.memory), not between cells
        release_freed_memory()


def _process_cell(job: CellJob) -> CellResult:
    cell, params = job.cell, job.params
    out = CellResult(cell.name, job.key, cell.lo, cell.hi)
    t0 = time.perf_counter()
    pts, codes = read_cell(job)
    pts = [pts]  # held in a list, so that the scene alone holds the points (and lets go of the margin)
    out.n_read = len(pts[0])
    out.codes = read_codes(codes)
    # a scan classed beyond 0 (never) and 1 (unclassified) gives its objects' class shares, as a scene's reader does
    classes = codes if params.open_world.scan_classes and (codes > 1).any() else None
    out.timing_s["read"] = time.perf_counter() - t0
    if out.n_read < 100:
        return _empty_cell(job, out)
    offset = np.asarray(job.offset, dtype=np.float64)
    # the ground from everything read (the filter's reach), the objects from the core and its buffer
    det = detect_points(PointSet(path=Path(cell.name), points=pts.pop(), offset=offset, unit="m", classes=classes),
                        params, keep=lambda p: cell.searches(p[:, :2]))
    del classes, codes
    out.timing_s.update(det.timing_s)
    pts = det.scene.points
    own = cell.owns(pts[:, :2])
    out.n_points = int(own.sum())
    out.n_ground = int((det.is_ground & own).sum())
    out.n_outliers = int(det.scene.n_outliers)
    out.noise = scene_noise(det.hag, det.is_ground)
    t = time.perf_counter()
    out.observed = raster(pts, det.hag, det.is_ground, cell.lo, cell.hi)
    if job.scan_dir:  # every point of the core, as level-of-detail tiles written here on the worker
        _write_scan(job, out, det, own)
    out.timing_s["scan_tiles"] = time.perf_counter() - t  # with the observation raster
    t = time.perf_counter()
    owned = _owned_objects(det, cell, out)
    _describe_owned(job, out, det, owned, offset)
    out.timing_s["sections"] = time.perf_counter() - t
    if job.labels:
        t = time.perf_counter()
        rows, classes, ids = cell_labels(det.is_ground, own, [o for o in det.segmentation.objects if o.target], owned)
        save_labels(Path(job.labels), pts[rows], classes, ids)
        out.timing_s["labels"] = time.perf_counter() - t
    return out


def _empty_cell(job: CellJob, out: CellResult) -> CellResult:
    """A cell of under 100 points: no objects; its empty scan folder and labels say it is done."""
    if job.scan_dir:  # an empty cell has no tiles: its empty folder says it is done
        cell_scan_folder(Path(job.scan_dir), job.cell.name, job.key).mkdir(parents=True, exist_ok=True)
    if job.labels:
        save_labels(Path(job.labels), np.zeros((0, 3)), np.zeros(0, np.uint8), np.zeros(0, np.uint16))
    return out


def _write_scan(job: CellJob, out: CellResult, det, own: np.ndarray) -> None:
    """The core's points as level-of-detail scan tiles, written on the worker."""
    pts = det.scene.points
    rows, colours = scan_sample(pts, det.hag, det.is_ground, np.flatnonzero(own))
    if len(rows):
        out.scan_tiles = write_cell_scan(Path(job.scan_dir), job.cell.name, job.key, pts[rows], colours)
    else:
        cell_scan_folder(Path(job.scan_dir), job.cell.name, job.key).mkdir(parents=True, exist_ok=True)


def _owned_objects(det, cell, out: CellResult) -> list:
    """The target objects whose footprint centre the cell owns, ordered by that centre (counting every owned
    segment in ``out``)."""
    pts = det.scene.points
    owned, centres = [], []
    for o in det.segmentation.objects:
        p = pts[o.indices, :2]
        centre = min_area_rectangle(p).centre if len(p) >= 3 else p.mean(0)
        if cell.owns(centre[None])[0]:
            out.n_segments += 1
            if o.target:
                owned.append(o)
                centres.append(centre)
    order = sorted(range(len(owned)), key=lambda k: (round(float(centres[k][0]), 2), round(float(centres[k][1]), 2)))
    return [owned[k] for k in order]


def _describe_owned(job: CellJob, out: CellResult, det, owned: list, offset: np.ndarray) -> None:
    """Each owned object described (sections, level of symmetry, a sample of its points) into ``out``."""
    params, cell = job.params, job.cell
    clouds = [object_points(det, o) for o in owned]
    shapes = describe_detected(det, params, objects=owned, clouds=clouds)
    levels = object_levels(clouds, shapes, params)
    for k, (o, shape, level, cloud) in enumerate(zip(owned, shapes, levels, clouds)):
        out.objects.append(CellObject(
            id=f"{cell.name}-{k + 1}", cell=cell.name, offset=offset, n_points=int(o.n_points), shape=shape,
            cloud=sample_cloud(cloud, params.matching.accept_max_points),
            spacing=float(point_spacing(cloud)), ground_z=object_ground(det, o), level=level))
