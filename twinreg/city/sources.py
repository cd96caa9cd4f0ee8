"""The input tiles of a city run: LAS/LAZ/COPC files named one by one, as a folder or as a glob; their headers
(bounds, point counts, CRS and unit) read without the points; and the two ways a worker reads the points of a
cell: COPC by bounds (octree nodes), plain LAS/LAZ by chunks (bounded memory), split once per tile into the cells
it feeds.
"""

from __future__ import annotations

import contextlib
import glob
import hashlib
import json
import math
import os
import re
import shutil
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from cosco.arrays import box_rows

from ..errors import CityError, SceneReadError
from ..io._files import checked_input
from ..io.points import check_las_header, check_point_count, crs_and_units, las_survey_date, same_crs
from .grid import TARGET_POINTS, Grid, in_box

TILE_SUFFIXES = (".las", ".laz")
#: points read at a time from a plain LAS/LAZ file
CHUNK_POINTS = 2_000_000


@dataclass(frozen=True)
class Source:
    """One input tile, from its header. ``lo, hi`` (3,) metres (file coordinates times the unit's scale);
    ``copc``: the file is a COPC (read by bounds)."""

    path: str
    n_points: int  # in the header
    lo: tuple
    hi: tuple
    copc: bool
    crs: str | None  # the header's, as given
    crs_name: str | None  # its name, for messages
    unit: str  # of the coordinates
    scale: float  # m per horizontal unit
    z_scale: float  # m per vertical unit
    size: int  # bytes
    mtime_ns: int  # the file's change time
    date: str | None = None
    date_source: str | None = None
    date_warning: str | None = None

    @property
    def area(self) -> float:
        return max(float(self.hi[0] - self.lo[0]) * float(self.hi[1] - self.lo[1]), 1.0)

    def key(self) -> str:
        """What identifies this input for resuming: its path, size, modification time and unit."""
        return f"{self.path}|{self.size}|{self.mtime_ns}|{self.scale}|{self.z_scale}|{self.crs}"


def expand_paths(paths) -> list[Path]:
    """Files named, files of named folders (``*.las``, ``*.laz``, any case) and glob matches, sorted, once each;
    a name that matches nothing raises :class:`SceneReadError`."""
    found: list[Path] = []
    for p in paths:
        s = str(p)
        if any(ch in s for ch in "*?["):
            hits = sorted(Path(h) for h in glob.glob(s, recursive=True) if Path(h).is_file())
            if not hits:
                raise SceneReadError(f"{s}: the pattern matches no file; check the path (quote it so the shell "
                                     "does not expand it)")
            found += hits
        elif Path(s).is_dir():
            hits = sorted(f for f in Path(s).iterdir() if f.is_file() and f.suffix.lower() in TILE_SUFFIXES)
            if not hits:
                raise SceneReadError(f"{s}: the folder holds no .las or .laz file; pass the tiles' folder")
            found += hits
        elif Path(s).is_file():
            found.append(Path(s))
        else:
            raise SceneReadError(f"{s}: no such file or folder")
    seen, out = set(), []
    for f in found:
        r = f.resolve()
        if r not in seen:
            seen.add(r)
            out.append(f)
    return out


def _is_copc(header) -> bool:
    return any(getattr(v, "user_id", "") == "copc" and getattr(v, "record_id", 0) == 1 for v in header.vlrs)


def is_tiled(paths, explicit: bool = False) -> bool:
    """Whether build-twin should run cell by cell: several paths, a folder, a glob, one of the tiling options
    (``explicit``), a COPC file, or one LAS/LAZ file holding more than a cell's worth of points."""
    paths = [str(p) for p in paths]
    if explicit or len(paths) != 1 or Path(paths[0]).is_dir() or any(ch in paths[0] for ch in "*?["):
        return True
    if Path(paths[0]).suffix.lower() not in (".las", ".laz") or not Path(paths[0]).is_file():
        return False
    try:
        import laspy

        with laspy.open(paths[0]) as reader:
            return _is_copc(reader.header) or reader.header.point_count > TARGET_POINTS
    except Exception:  # the per-scene reader reports a broken file with its own message
        return False


def _first_gps_times(reader, header, n: int = 10_000):
    """The GPS times of a tile's first ``n`` points (the survey's date), or None: none stored, or those points do
    not decompress (a tile damaged there fails its own cells later, not the run's start)."""
    if "gps_time" not in header.point_format.dimension_names or not header.point_count:
        return None
    try:
        return np.asarray(reader.read_points(min(int(header.point_count), n)).gps_time)
    except Exception:
        return None


def read_source(path: Path, unit: str = "auto", crs: str | None = None, override_crs: bool = False) -> Source:
    """The header of one LAS/LAZ/COPC tile as a :class:`Source` (checked: its point count against its size, a COPC
    hierarchy walked; at most 10,000 points read, for their GPS times)."""
    import laspy


    path, _ = checked_input(path, set(TILE_SUFFIXES), "tile", "LAS, LAZ or COPC (.copc.laz)", SceneReadError)
    try:
        with laspy.open(str(path)) as reader:
            header = reader.header
            check_las_header(path, header)
            check_point_count(path, header)
            copc = _is_copc(header)
            if copc and not any(getattr(v, "user_id", "") == "copc" and getattr(v, "record_id", 0) == 1000
                                for v in (header.evlrs or [])):
                # laspy reads a truncated COPC as an empty one: refuse it here rather than lose its points
                raise SceneReadError(f"{path}: a COPC file without its octree hierarchy (truncated?); copy or "
                                     "download it again")
            if copc:
                from ..io.copc import check_copc

                check_copc(path, int(header.point_count), SceneReadError)
            gps = _first_gps_times(reader, header)
    except SceneReadError:
        raise
    except Exception as exc:
        raise SceneReadError(f"{path}: not a readable LAS/LAZ file ({type(exc).__name__}: {exc})") from exc
    header_crs = header_error = None
    try:
        header_crs = header.parse_crs()
    except Exception as exc:
        header_error = exc
    info, unit_name, scale, z_scale = crs_and_units(path, unit.lower(), crs, header_crs, header_error, override_crs)
    mins, maxs = np.asarray(header.mins, dtype=np.float64), np.asarray(header.maxs, dtype=np.float64)
    s = np.array([scale, scale, z_scale])
    st = path.stat()
    return Source(path=str(path.resolve()), n_points=int(header.point_count), lo=tuple(mins * s), hi=tuple(maxs * s),
                  copc=copc, crs=info.crs if info else None, crs_name=info.name if info else None,
                  unit=unit_name, scale=scale, z_scale=z_scale, size=st.st_size, mtime_ns=st.st_mtime_ns,
                  **dict(zip(("date", "date_source", "date_warning"), las_survey_date(path, header, gps))))


def open_sources(paths, unit: str = "auto", crs: str | None = None, override_crs: bool = False) -> list[Source]:
    """Headers of every tile; tiles whose CRS or unit disagree are refused with one line naming two of them."""
    files = expand_paths(paths)
    bad = [f for f in files if f.suffix.lower() not in TILE_SUFFIXES]
    if bad:
        raise SceneReadError(f"{bad[0]}: a tiled run reads LAS, LAZ or COPC files; pass this file on its own to "
                             "build-twin, or convert it to LAZ")
    sources = [read_source(f, unit, crs, override_crs) for f in files]
    first = sources[0]
    for s in sources[1:]:
        if not same_crs(first.crs, s.crs):
            raise SceneReadError(f"{s.path}: its CRS ({s.crs_name or 'none stated'}) differs from that of "
                                 f"{first.path} ({first.crs_name or 'none stated'}); tiles of one run must share "
                                 "one CRS (reproject them, or pass --crs if the headers are wrong)")
        if abs(s.scale - first.scale) > 1e-12 or abs(s.z_scale - first.z_scale) > 1e-12:
            raise SceneReadError(f"{s.path}: its unit ({s.unit}) differs from that of {first.path} ({first.unit}); "
                                 "tiles of one run must share one unit")
    return sources


def _xyz(points, source: Source) -> np.ndarray:
    return np.column_stack([np.asarray(points.x, dtype=np.float64) * source.scale,
                            np.asarray(points.y, dtype=np.float64) * source.scale,
                            np.asarray(points.z, dtype=np.float64) * source.z_scale])


def _chunks(source: Source):
    """The (n, 3) float64 metre points of a plain LAS/LAZ file and their (n,) uint8 ASPRS classes, ``CHUNK_POINTS``
    at a time."""
    import laspy

    try:
        with laspy.open(source.path) as reader:
            for chunk in reader.chunk_iterator(CHUNK_POINTS):
                yield _xyz(chunk, source), _classes(chunk)
    except Exception as exc:
        raise SceneReadError(f"{source.path}: reading failed ({type(exc).__name__}: {exc}); is the file complete?") \
            from exc


def _classes(points) -> np.ndarray:
    """(n,) uint8 ASPRS classes of a laspy point record."""
    return np.asarray(points.classification, dtype=np.uint8)


def _raw_chunks(source: Source):
    """A plain LAS/LAZ file's points ``CHUNK_POINTS`` at a time, for splitting: their x and y in metres ((n,)
    float64 each, as :func:`_xyz` gives them), their integer coordinates ((n, 3) int32 X, Y, Z), their ASPRS classes
    ((n,) uint8), the header's scales and offsets."""
    import laspy

    try:
        with laspy.open(source.path) as reader:
            h = reader.header
            for chunk in reader.chunk_iterator(CHUNK_POINTS):
                ints = np.empty((len(chunk), 3), dtype=np.int32)
                for k, name in enumerate("XYZ"):
                    ints[:, k] = chunk[name]
                yield (np.asarray(chunk.x, dtype=np.float64) * source.scale,
                       np.asarray(chunk.y, dtype=np.float64) * source.scale, ints, _classes(chunk), h.scales,
                       h.offsets)
    except Exception as exc:
        raise SceneReadError(f"{source.path}: reading failed ({type(exc).__name__}: {exc}); is the file complete?") \
            from exc


def read_box(source: Source, lo, hi, classes: bool = False):
    """The points of one tile inside the closed box ``[lo, hi]`` (2-vectors, metres): a COPC file by bounds (only
    the octree nodes that meet the box are decompressed), a plain LAS/LAZ file by chunks; with ``classes``, the pair
    (points, their (n,) uint8 ASPRS classes)."""
    lo, hi = np.asarray(lo, dtype=np.float64)[:2], np.asarray(hi, dtype=np.float64)[:2]
    if source.copc:
        import laspy

        # laspy issue 370: 2-D bounds miss points on some files; pass 3-D bounds spanning the file's z range
        zlo, zhi = source.lo[2] / source.z_scale - 1.0, source.hi[2] / source.z_scale + 1.0
        bounds = laspy.copc.Bounds(mins=np.array([lo[0] / source.scale, lo[1] / source.scale, zlo]),
                                   maxs=np.array([hi[0] / source.scale, hi[1] / source.scale, zhi]))
        try:
            with laspy.CopcReader.open(source.path) as reader:
                got = reader.query(bounds=bounds)
                pts, codes = _xyz(got, source), _classes(got)
                del got
        except Exception as exc:
            raise SceneReadError(f"{source.path}: reading the COPC file failed ({type(exc).__name__}: {exc})") \
                from exc
        inside = in_box(pts[:, :2], lo, hi)
        return (pts[inside], codes[inside]) if classes else pts[inside]
    parts, codes = [], []
    for pts, c in _chunks(source):
        inside = in_box(pts[:, :2], lo, hi)
        parts.append(pts[inside])
        codes.append(c[inside])
    pts = np.vstack(parts) if parts else np.zeros((0, 3))
    return (pts, np.concatenate(codes) if codes else np.zeros(0, np.uint8)) if classes else pts


#: how a split keeps its points: the file's own integer coordinates, ``(n, 3)`` int32 X, Y, Z in ``<cell>.i32`` (half
#: the bytes of float64 metres) and their ASPRS classes, ``(n,)`` uint8 in ``<cell>.cls``; ``split.json`` holds the
#: header's scales and offsets and the unit's scales
SPLIT_FORMAT = "i32"
SPLIT_CLASSES = "cls"
#: the split document's format: a split of an earlier format (points without their classes) is made again
SPLIT_DOC_FORMAT = "i32+cls"


def split_key(source: Source, grid: Grid) -> str:
    """The hash naming a tile's split for one grid (changes when the file, the grid or the split's format
    changes)."""
    text = json.dumps([source.key(), grid.size, grid.buffer, grid.margin, SPLIT_DOC_FORMAT])
    return hashlib.sha256(text.encode()).hexdigest()[:16]


#: a cell's name in a split document (grid.Cell.name)
_CELL_NAME = re.compile(r"c-?\d+_-?\d+")


def split_doc(folder) -> dict | None:
    """A split folder's ``split.json``, checked as data: its format, every cell named as cells are, each count a
    non-negative integer whose file holds exactly that many points, three finite scales, offsets and units. None
    when the folder is missing, damaged or foreign (an OUT from someone else): the tile is then split again."""
    folder = Path(folder)
    p = folder / "split.json"
    try:
        if folder.is_symlink() or p.is_symlink() or not p.is_file() or p.stat().st_size > 2 ** 20:
            return None
        doc = json.loads(p.read_text(encoding="utf-8"))
        if (not isinstance(doc, dict) or doc.get("format") != SPLIT_DOC_FORMAT
                or not isinstance(doc.get("cells"), dict)):
            return None
        cells = doc["cells"]
        for name, n in cells.items():
            if not _CELL_NAME.fullmatch(str(name)) or type(n) is not int or n < 0:
                return None
            for suffix, size in ((SPLIT_FORMAT, 12), (SPLIT_CLASSES, 1)):
                f = folder / f"{name}.{suffix}"
                if f.is_symlink() or not f.is_file() or f.stat().st_size != size * n:
                    return None
        for key in ("scales", "offsets", "units") if cells else ():
            v = doc.get(key)
            if not (isinstance(v, list) and len(v) == 3
                    and all(type(x) in (int, float) and math.isfinite(x) for x in v)):
                return None
    except (OSError, ValueError):
        return None
    return doc


def split_tile(source: Source, grid: Grid, folder) -> dict:
    """Stream a plain LAS/LAZ tile once and write, for every cell its points feed (core and buffer), those points
    as the file's integer coordinates (:data:`SPLIT_FORMAT`) to ``folder/<cell>.i32`` and their ASPRS classes to
    ``folder/<cell>.cls``; returns ``{cell name: n}``.
    The folder appears complete (written under a temporary name, then renamed) or not at all, so a killed split is
    redone; a folder whose document does not check (:func:`split_doc`) is removed and the tile split again."""
    folder = Path(folder)
    doc = split_doc(folder)
    if doc is not None:
        return doc["cells"]
    if folder.is_symlink():
        folder.unlink()
    elif folder.exists():
        shutil.rmtree(folder)
    folder.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(dir=folder.parent, prefix=f".tmp-{folder.name}-"))
    counts: dict[str, int] = {}
    handles: dict[str, object] = {}
    cells = grid.cells_over(np.asarray(source.lo[:2]) - grid.reach, np.asarray(source.hi[:2]) + grid.reach)
    scaling = None
    try:
        with contextlib.ExitStack() as files:  # every cell's two files closed before the document is written
            boxes = np.array([[*c.read_lo, *c.read_hi] for c in cells], dtype=np.float64).reshape(-1, 4)
            for x, y, ints, codes, scales, offsets in _raw_chunks(source):
                if scaling is None:  # one header: the same for every chunk
                    scaling = {"scales": [float(v) for v in scales], "offsets": [float(v) for v in offsets],
                               "units": [float(source.scale), float(source.scale), float(source.z_scale)]}
                found = box_rows(x, y, boxes)  # each cell's rows, in order (compiled: every cell in two passes)
                for c, inside in zip(cells, found):
                    if not len(inside):
                        continue
                    if c.name not in handles:
                        handles[c.name] = tuple(files.enter_context(open(tmp / f"{c.name}.{suffix}", "wb"))
                                                for suffix in (SPLIT_FORMAT, SPLIT_CLASSES))
                    handles[c.name][0].write(np.ascontiguousarray(ints[inside], dtype=np.int32).tobytes())
                    handles[c.name][1].write(np.ascontiguousarray(codes[inside], dtype=np.uint8).tobytes())
                    counts[c.name] = counts.get(c.name, 0) + len(inside)
        (tmp / "split.json").write_text(json.dumps({"source": source.path, "cells": counts,
                                                    "format": SPLIT_DOC_FORMAT, **(scaling or {})}),
                                        encoding="utf-8")
        os.replace(tmp, folder)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return counts


def read_splits(folders, cell_name: str, extra=(), classes: bool = False):
    """The points split tiles gave one cell, followed by the ``extra`` (n, 3) arrays: (n, 3) float64 metres, each
    file's integers scaled into one array (laspy's arithmetic, ``(X * scale + offset) * unit``: the same metres as
    reading the tile, bit for bit). With ``classes``, the pair (points, their (n,) uint8 ASPRS classes), ``extra``
    then being (points, classes) pairs."""
    parts = []
    for folder in folders:
        doc = split_doc(folder)
        if doc is None:
            raise CityError(f"{folder}: a tile's split is damaged or missing; rerun the same command (the tile is "
                            "split again)")
        if cell_name in doc["cells"]:
            parts.append((Path(folder) / f"{cell_name}.{SPLIT_FORMAT}", doc["cells"][cell_name], doc))
    extra = list(extra) if classes else [(e, None) for e in extra]
    out = np.empty((sum(n for _, n, _ in parts) + sum(len(e) for e, _ in extra), 3))
    codes = np.empty(len(out), dtype=np.uint8) if classes else None
    at = 0
    for f, n, doc in parts:
        ints = np.fromfile(f, dtype=np.int32, count=3 * n).reshape(n, 3)
        for k in range(3):  # a column at a time (a row of three is too short a loop); times 1.0 changes nothing
            col = out[at:at + n, k]
            np.multiply(ints[:, k], doc["scales"][k], out=col)
            col += doc["offsets"][k]
            if doc["units"][k] != 1.0:
                col *= doc["units"][k]
        del ints
        if classes:
            codes[at:at + n] = np.fromfile(f.with_suffix(f".{SPLIT_CLASSES}"), dtype=np.uint8, count=n)
        at += n
    for e, c in extra:
        out[at:at + len(e)] = e
        if classes:
            codes[at:at + len(e)] = c
        at += len(e)
    return (out, codes) if classes else out
