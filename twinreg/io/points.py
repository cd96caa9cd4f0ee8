"""Point readers: PLY, PCD, LAS, LAZ, XYZ/TXT/CSV and KITTI ``.bin``, always to float64.

Large projected coordinates stay exact: LAS/LAZ integers are scaled in float64, text is parsed in float64, and a
:class:`PointSet` carries a local offset (a round number near the minimum) for code that needs small numbers.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import SceneReadError
from ._files import checked_input

UNIT_SCALES = {"m": 1.0, "cm": 0.01, "mm": 0.001, "ft": 0.3048, "us-ft": 1200.0 / 3937.0, "in": 0.0254}
POINT_SUFFIXES = {".ply", ".pcd", ".las", ".laz", ".xyz", ".txt", ".csv", ".pts", ".bin"}


@dataclass
class PointSet:
    """Points of a scene or object.

    points : (n, 3) float64 metres in the file's frame (after unit scaling). offset : (3,) float64, a round local
    origin; ``points - offset`` is small. unit : the unit applied. crs : WKT or EPSG string found in the file, or
    None. n_dropped : non-finite points removed.
    """

    path: Path
    points: np.ndarray
    offset: np.ndarray
    unit: str
    crs: str | None = None
    n_dropped: int = 0

    @property
    def local(self) -> np.ndarray:
        return self.points - self.offset


def _read_text(path: Path) -> np.ndarray:
    with open(path, "r", errors="replace") as fh:
        sample = fh.read(4096)
    delimiter = "," if sample.count(",") > sample.count(" ") and "," in sample else None
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            data = np.loadtxt(path, delimiter=delimiter, comments=("#", "//"), ndmin=2, usecols=(0, 1, 2))
    except (ValueError, IndexError) as exc:
        # a header line (x,y,z) is common: try once more without it
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                data = np.loadtxt(path, delimiter=delimiter, comments=("#", "//"), ndmin=2, usecols=(0, 1, 2),
                                  skiprows=1)
        except (ValueError, IndexError):
            raise SceneReadError(f"{path}: not a text point file with x y z columns ({exc})") from exc
    return data


def _read_kitti(path: Path) -> np.ndarray:
    raw = np.fromfile(path, dtype="<f4")
    if raw.size == 0 or raw.size % 4:
        raise SceneReadError(f"{path}: a KITTI .bin holds float32 x y z r records; this file's size "
                             f"({path.stat().st_size} bytes) is not a multiple of 16 (truncated?)")
    return raw.reshape(-1, 4)[:, :3].astype(np.float64)


def _read_las(path: Path):
    import laspy

    try:
        las = laspy.read(str(path))
    except Exception as exc:
        raise SceneReadError(f"{path}: not a readable LAS/LAZ file ({type(exc).__name__}: {exc})") from exc
    pts = np.column_stack([np.asarray(las.x, dtype=np.float64), np.asarray(las.y, dtype=np.float64),
                           np.asarray(las.z, dtype=np.float64)])
    crs, unit_factor = None, None
    try:
        c = las.header.parse_crs()
        if c is not None:
            crs = c.to_string()
            unit_factor = float(c.axis_info[0].unit_conversion_factor)
    except Exception:  # a broken or absent CRS record is not fatal
        pass
    return pts, crs, unit_factor


_PLY_TYPES = {"char": "i1", "uchar": "u1", "short": "i2", "ushort": "u2", "int": "i4", "uint": "u4",
              "float": "f4", "double": "f8", "int8": "i1", "uint8": "u1", "int16": "i2", "uint16": "u2",
              "int32": "i4", "uint32": "u4", "float32": "f4", "float64": "f8"}


def _read_ply(path: Path) -> np.ndarray | None:
    """x, y, z of a PLY's vertex element with numpy (binary or ASCII); None for a layout it does not handle
    (list properties before the vertices), which then goes to open3d."""
    with open(path, "rb") as fh:
        if fh.readline().strip() != b"ply":
            raise SceneReadError(f"{path}: not a PLY file (no 'ply' magic)")
        fmt, elements, current = None, [], None
        while True:
            line = fh.readline()
            if not line:
                raise SceneReadError(f"{path}: PLY header has no end_header (truncated?)")
            words = line.decode("ascii", "replace").split()
            if not words:
                continue
            if words[0] == "format":
                fmt = words[1]
            elif words[0] == "element":
                current = [words[1], int(words[2]), []]
                elements.append(current)
            elif words[0] == "property" and current is not None:
                if words[1] == "list":
                    current[2].append((words[-1], None))
                else:
                    current[2].append((words[2], _PLY_TYPES.get(words[1])))
            elif words[0] == "end_header":
                break
        if not elements or elements[0][0] != "vertex" or any(t is None for _, t in elements[0][2]):
            return None
        _, count, props = elements[0]
        names = [n for n, _ in props]
        if not {"x", "y", "z"} <= set(names):
            raise SceneReadError(f"{path}: PLY vertices have no x, y, z properties")
        if fmt == "ascii":
            data = np.loadtxt(fh, max_rows=count, ndmin=2, usecols=[names.index(c) for c in "xyz"])
            return data.astype(np.float64)
        endian = "<" if fmt == "binary_little_endian" else ">"
        dtype = np.dtype([(n, endian + t) for n, t in props])
        raw = fh.read(count * dtype.itemsize)
        if len(raw) < count * dtype.itemsize:
            raise SceneReadError(f"{path}: PLY holds fewer vertices than its header says (truncated?)")
        rec = np.frombuffer(raw, dtype=dtype, count=count)
        return np.column_stack([rec["x"], rec["y"], rec["z"]]).astype(np.float64)


def _read_o3d(path: Path) -> np.ndarray:
    import open3d as o3d

    pcd = o3d.io.read_point_cloud(str(path))
    pts = np.asarray(pcd.points, dtype=np.float64)
    if len(pts) == 0 and path.suffix.lower() == ".ply":
        # a PLY mesh or a layout open3d does not read: try trimesh, which keeps float64 vertices
        import trimesh

        try:
            obj = trimesh.load(str(path), process=False)
            pts = np.asarray(getattr(obj, "vertices", np.zeros((0, 3))), dtype=np.float64)
        except Exception as exc:
            raise SceneReadError(f"{path}: not a readable PLY ({exc})") from exc
    return pts


def read_points(path, unit: str = "auto") -> PointSet:
    """Read a point file to a :class:`PointSet`.

    unit : ``auto`` (metres, or the LAS CRS's linear unit when one is stated) or one of m, cm, mm, ft, us-ft, in.
    Raises :class:`SceneReadError` with one line naming the file for a missing, unreadable, truncated or empty file.
    """
    path, suffix = checked_input(path, POINT_SUFFIXES, "point", "PLY, PCD, LAS, LAZ, XYZ/TXT or KITTI .bin",
                                 SceneReadError)
    crs, file_unit = None, None
    if suffix in (".las", ".laz"):
        pts, crs, file_unit = _read_las(path)
    elif suffix == ".bin":
        pts = _read_kitti(path)
    elif suffix == ".ply":
        pts = _read_ply(path)
        if pts is None:
            pts = _read_o3d(path)
    elif suffix == ".pcd":
        pts = _read_o3d(path)
    else:
        pts = _read_text(path)
    pts = np.asarray(pts, dtype=np.float64).reshape(-1, 3)
    finite = np.isfinite(pts).all(1)
    dropped = int((~finite).sum())
    pts = pts[finite]
    if len(pts) == 0:
        raise SceneReadError(f"{path}: no valid points")
    unit = unit.lower()
    if unit == "auto":
        if file_unit and abs(file_unit - 1.0) > 1e-9:
            scale = file_unit
            unit = next((k for k, v in UNIT_SCALES.items() if abs(v - file_unit) < 1e-9), f"{file_unit:g} m")
        else:
            scale, unit = 1.0, "m"
    elif unit in UNIT_SCALES:
        scale = UNIT_SCALES[unit]
    else:
        raise SceneReadError(f"{path}: unknown --unit '{unit}'; use auto, {', '.join(UNIT_SCALES)}")
    if scale != 1.0:
        pts = pts * scale
    offset = np.floor(pts.min(0) / 100.0) * 100.0
    offset[2] = 0.0
    return PointSet(path=path, points=pts, offset=offset, unit=unit, crs=crs, n_dropped=dropped)
