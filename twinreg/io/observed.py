"""Where a survey saw anything: the observation record each build-twin run writes as ``observed.npz`` in its
folder, read back by ``compare`` to tell ``left`` (the later survey saw the ground where a car stood) from
``unobserved`` (no returns there).

The record is a set of square rasters (one for a scene, one per cell for a city run) of :data:`PIXEL` metre
pixels in the twin's coordinates. Pixel ``[i, j]`` of a raster whose corner is ``lo`` covers
``[lo_x + i p, lo_x + (i + 1) p) x [lo_y + j p, lo_y + (j + 1) p)``. Two arrays per raster:

- ``code`` (uint8): :data:`NONE` (255) where no point fell; else the highest return's height above the ground in
  decimetres (0-126), plus :data:`GROUND` (128) when a ground return fell in the pixel;
- ``ground`` (float32): the mean height of the pixel's ground returns above the raster's ``z0`` (NaN: none).

Beside them the objects' COSCO sections (twin.json's order), so that compare can tell whether two epochs' objects
are the same vehicle without the scans. The file is read with ``allow_pickle=False`` and its sizes are checked
first: a twin from someone else is data.
"""

from __future__ import annotations

import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from cosco.sections import Sections

from ..errors import RecordError
from .npz import member_shapes, nbytes

FILE = "observed.npz"
FORMAT = "twinreg-observed/1"
PIXEL = 0.5
NONE = 255
GROUND = 128
#: the largest record read back (bytes on disk), the largest raster side (pixels), what its arrays may take once
#: read (bytes: 100M pixels, about 25 km2 at 0.5 m) and the most section points an object may have
MAX_BYTES = 2 * 1024 ** 3
MAX_SIDE = 20_000
MAX_ARRAY_BYTES = 512 * 1024 ** 2
MAX_SECTION_POINTS = 4096


@dataclass
class Raster:
    """One raster of the record: its corner ``lo`` (2,), ``code`` (n, m) uint8, ``ground`` (n, m) float32 above
    ``z0``."""

    lo: np.ndarray
    code: np.ndarray
    ground: np.ndarray
    z0: float

    @property
    def hi(self) -> np.ndarray:
        return self.lo + np.array(self.code.shape) * PIXEL


def raster(points: np.ndarray, hag: np.ndarray, is_ground: np.ndarray, lo, hi) -> Raster:
    """The raster of ``[lo, hi)`` from (n, 3) scene points with their heights above ground and ground flags (points
    outside are ignored)."""
    lo = np.floor(np.asarray(lo, dtype=np.float64)[:2] / PIXEL) * PIXEL
    hi = np.asarray(hi, dtype=np.float64)[:2]
    shape = np.maximum(np.ceil((hi - lo) / PIXEL).astype(np.int64), 1)
    # column by column: the same numbers as on (n, 2) arrays, without their slow row-wise passes
    i = np.floor((points[:, 0] - lo[0]) / PIXEL).astype(np.int64)
    j = np.floor((points[:, 1] - lo[1]) / PIXEL).astype(np.int64)
    inside = (i >= 0) & (i < shape[0]) & (j >= 0) & (j < shape[1])
    h, g, z = hag, np.asarray(is_ground, dtype=bool), points[:, 2]
    if not inside.all():
        i, j, h, g, z = i[inside], j[inside], h[inside], g[inside], z[inside]
    flat = i * shape[1] + j
    del i, j
    n = int(shape[0] * shape[1])
    top = np.full(n, -1.0)
    np.maximum.at(top, flat, np.where(g, 0.0, np.clip(h, 0.0, 12.6)))
    seen_ground = np.bincount(flat[g], minlength=n) > 0
    code = np.where(top < 0, NONE, np.round(np.maximum(top, 0.0) * 10) + np.where(seen_ground, GROUND, 0))
    z0 = float(np.floor(np.median(z[g]))) if g.any() else 0.0
    total = np.bincount(flat[g], weights=z[g] - z0, minlength=n)
    ground = np.where(seen_ground, total / np.maximum(np.bincount(flat[g], minlength=n), 1), np.nan)
    return Raster(lo, code.astype(np.uint8).reshape(shape), ground.astype(np.float32).reshape(shape), z0)


def heights(code: np.ndarray) -> np.ndarray:
    """Height above ground (m) of the highest return of each pixel, NaN where none."""
    return np.where(code == NONE, np.nan, (code & 127) / 10.0)


def _pack_sections(sections: list[Sections]) -> dict:
    lon = [np.asarray(s.longitudinal, dtype=np.float32).reshape(-1, 2) for s in sections]
    tra = [np.asarray(s.transverse, dtype=np.float32).reshape(-1, 2) for s in sections]
    return {"sec_lon": np.vstack(lon) if lon else np.zeros((0, 2), np.float32),
            "sec_lon_n": np.array([len(a) for a in lon], dtype=np.int64),
            "sec_tra": np.vstack(tra) if tra else np.zeros((0, 2), np.float32),
            "sec_tra_n": np.array([len(a) for a in tra], dtype=np.int64),
            "sec_res": np.array([s.res for s in sections], dtype=np.float64)}


def write(path: Path, rasters: list[Raster], sections: list[Sections]) -> dict:
    """Write the record to ``path`` (a staging folder's file); returns twin.json's ``observation`` entry."""
    arrays = {"format": np.frombuffer(FORMAT.encode(), dtype=np.uint8), "pixel": np.array(PIXEL),
              "lo": np.array([r.lo for r in rasters], dtype=np.float64).reshape(-1, 2),
              "z0": np.array([r.z0 for r in rasters], dtype=np.float64)}
    for k, r in enumerate(rasters):
        arrays[f"code{k}"] = r.code
        arrays[f"ground{k}"] = r.ground
    arrays |= _pack_sections(sections)
    with open(path, "wb") as fh:
        np.savez_compressed(fh, **arrays)
    seen = sum(int((r.code != NONE).sum()) for r in rasters)
    return {"file": FILE, "format": FORMAT, "pixel_m": PIXEL, "rasters": len(rasters),
            "area_seen_m2": round(seen * PIXEL * PIXEL, 1)}


@dataclass
class Record:
    """An observation record read back: its rasters (a regular grid of equal squares for a city, one for a
    scene) and the objects' sections."""

    rasters: list[Raster]
    sections: list[Sections]

    def lookup(self, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(code (n,) uint8, ground z (n,) float64) at (n, 2) points: :data:`NONE` and NaN outside every raster.
        Each point is sent to its raster through the rasters' grid (a city's cells), then read there."""
        xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
        code = np.full(len(xy), NONE, dtype=np.uint8)
        ground = np.full(len(xy), np.nan)
        which = self._raster_of(xy)
        order = np.argsort(which, kind="stable")
        bounds = np.searchsorted(which[order], np.arange(len(self.rasters) + 1))
        for k, r in enumerate(self.rasters):
            rows = order[bounds[k]:bounds[k + 1]]
            if not len(rows):
                continue
            ij = np.floor((xy[rows] - r.lo) / PIXEL).astype(np.int64)
            ok = np.all((ij >= 0) & (ij < r.code.shape), axis=1)
            rows, ij = rows[ok], ij[ok]
            code[rows] = r.code[ij[:, 0], ij[:, 1]]
            ground[rows] = r.ground[ij[:, 0], ij[:, 1]] + r.z0
        return code, ground

    def _raster_of(self, xy: np.ndarray) -> np.ndarray:
        """(n,) the index of the raster each point may lie in (len(rasters) for none)."""
        n = len(self.rasters)
        if n == 1:
            return np.zeros(len(xy), dtype=np.int64)
        grid = self._grid()
        if grid is None:  # rasters of different sizes: each point tried against each
            which = np.full(len(xy), n, dtype=np.int64)
            for k, r in enumerate(self.rasters):
                inside = np.all((xy >= r.lo) & (xy < r.hi), axis=1) & (which == n)
                which[inside] = k
            return which
        lo, size, table = grid
        ij = np.floor((xy - lo) / size).astype(np.int64)
        ok = np.all((ij >= 0) & (ij < table.shape), axis=1)
        which = np.full(len(xy), n, dtype=np.int64)
        which[ok] = table[ij[ok, 0], ij[ok, 1]]
        return which

    def _grid(self):
        """(origin, cell size, table of raster indices) when the rasters are equal squares on one grid."""
        if getattr(self, "_grid_cache", None) is not None:
            return self._grid_cache or None
        shapes = {r.code.shape for r in self.rasters}
        los = np.array([r.lo for r in self.rasters])
        result = False
        if len(shapes) == 1:
            size = np.array(next(iter(shapes)), dtype=np.float64) * PIXEL
            lo = los.min(0)
            idx = np.round((los - lo) / size).astype(np.int64)
            if np.allclose(idx * size + lo, los, atol=1e-6) and idx.max() < 100_000:
                table = np.full(idx.max(0) + 1, len(self.rasters), dtype=np.int64)
                table[idx[:, 0], idx[:, 1]] = np.arange(len(self.rasters))
                result = (lo, size, table)
        self._grid_cache = result
        return result or None

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """(lo (2,), hi (2,)) of the pixels with returns (the rasters' own extent when none has any)."""
        los, his = [], []
        for r in self.rasters:
            seen = r.code != NONE
            if seen.any():
                i, j = np.flatnonzero(seen.any(1)), np.flatnonzero(seen.any(0))
                los.append(r.lo + np.array([i[0], j[0]]) * PIXEL)
                his.append(r.lo + np.array([i[-1] + 1, j[-1] + 1]) * PIXEL)
        if not los:
            los, his = [r.lo for r in self.rasters], [r.hi for r in self.rasters]
        return np.min(los, axis=0), np.max(his, axis=0)


def _unpack_sections(z, n_objects: int) -> list[Sections]:
    lon, tra = z["sec_lon"], z["sec_tra"]
    nl, nt, res = z["sec_lon_n"].astype(np.int64), z["sec_tra_n"].astype(np.int64), z["sec_res"]
    if not (len(nl) == len(nt) == len(res) == n_objects) or nl.sum() != len(lon) or nt.sum() != len(tra) \
            or (nl < 0).any() or (nt < 0).any() or lon.ndim != 2 or tra.ndim != 2:
        raise RecordError(f"its sections do not match the twin's {n_objects} objects")
    if not (np.isfinite(lon).all() and np.isfinite(tra).all() and np.all((res > 0) & (res < 1))):
        raise RecordError("its sections hold values that are not finite")
    ol, ot = np.concatenate([[0], np.cumsum(nl)]), np.concatenate([[0], np.cumsum(nt)])
    return [Sections(lon[ol[k]:ol[k + 1]].astype(np.float64), tra[ot[k]:ot[k + 1]].astype(np.float64),
                     float(res[k])) for k in range(n_objects)]


def _check_array(z, key, dtype, ndim):
    a = z[key]
    if a.dtype != dtype or a.ndim != ndim or (ndim == 2 and max(a.shape) > MAX_SIDE):
        raise RecordError(f"its {key} is not a {dtype} array of {ndim} dimensions")
    return a


def _check_shapes(zf: zipfile.ZipFile, n_objects: int) -> None:
    """Refuse a record from its members' headers alone, before any array is decompressed: unknown members, wrong
    types or dimensions, sections longer than :data:`MAX_SECTION_POINTS` an object, or arrays that would take more
    than :data:`MAX_ARRAY_BYTES`."""
    try:
        shapes = member_shapes(zf)
    except ValueError as exc:
        raise RecordError(str(exc)) from exc
    fixed = {"format": ("u1", 1), "pixel": ("f8", 0), "lo": ("f8", 2), "z0": ("f8", 1), "sec_lon": ("f4", 2),
             "sec_tra": ("f4", 2), "sec_lon_n": ("i8", 1), "sec_tra_n": ("i8", 1), "sec_res": ("f8", 1)}
    missing = [k for k in fixed if k not in shapes]
    if missing:
        raise RecordError(f"it has no {missing[0]} array")
    n_rasters = shapes["lo"][1][0]
    for k in range(n_rasters):
        fixed[f"code{k}"], fixed[f"ground{k}"] = ("u1", 2), ("f4", 2)
    for name, (dtype, shape) in shapes.items():
        want = fixed.get(name)
        if want is None:
            raise RecordError(f"it holds an array it should not ({name[:40]!r})")
        if dtype != np.dtype(want[0]) or len(shape) != want[1]:
            raise RecordError(f"its {name} is not a {want[0]} array of {want[1]} dimensions")
        if name.startswith(("code", "ground")) and max(shape) > MAX_SIDE:
            raise RecordError(f"its {name} is {shape[0]} x {shape[1]} pixels (at most {MAX_SIDE} a side)")
    if shapes["lo"][1][1:] != (2,) or len(shapes) != len(fixed):
        raise RecordError("its rasters are not described consistently")
    for key in ("sec_lon", "sec_tra"):
        if shapes[key][1][0] > MAX_SECTION_POINTS * max(n_objects, 1) or shapes[key][1][1:] != (2,):
            raise RecordError(f"its {key} sections hold more points than {n_objects} objects have")
    total = nbytes(shapes)
    if total > MAX_ARRAY_BYTES:
        raise RecordError(f"its arrays would take {total / 1024 ** 2:,.0f} MB (at most {MAX_ARRAY_BYTES >> 20} MB)")


def read(path: Path, n_objects: int) -> Record:
    """The record at ``path`` for a twin of ``n_objects`` objects; :class:`RecordError` if it is not one. Its
    members' sizes are checked from their headers before any is read (:func:`_check_shapes`)."""
    path = Path(path)
    if path.is_symlink() or not path.is_file():
        raise RecordError("it is missing or a link")
    if path.stat().st_size > MAX_BYTES:
        raise RecordError(f"it is larger than {MAX_BYTES >> 30} GB")
    try:
        with zipfile.ZipFile(path) as zf:
            _check_shapes(zf, n_objects)
        with np.load(path, allow_pickle=False) as z:
            if "format" not in z.files or z["format"].tobytes() != FORMAT.encode():
                raise RecordError("it is not a twinreg observation record")
            lo, z0 = _check_array(z, "lo", np.float64, 2), z["z0"]
            if float(z["pixel"]) != PIXEL or len(z0) != len(lo) or not np.isfinite(lo).all() \
                    or not np.isfinite(z0).all():
                raise RecordError("its rasters are not described consistently")
            rasters = []
            for k in range(len(lo)):
                code = _check_array(z, f"code{k}", np.uint8, 2)
                ground = _check_array(z, f"ground{k}", np.float32, 2)
                if code.shape != ground.shape:
                    raise RecordError(f"its raster {k} has two shapes")
                rasters.append(Raster(lo[k], code, ground, float(z0[k])))
            return Record(rasters, _unpack_sections(z, n_objects))
    except RecordError:
        raise
    except (OSError, ValueError, KeyError, TypeError, EOFError, zipfile.BadZipFile) as exc:
        raise RecordError(f"it cannot be read ({type(exc).__name__})") from exc
