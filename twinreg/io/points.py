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
    path = Path(path)
    if not path.is_file():
        raise SceneReadError(f"{path}: no such file")
    suffix = path.suffix.lower()
    if suffix not in POINT_SUFFIXES:
        raise SceneReadError(f"{path}: unsupported point format '{suffix}'; use PLY, PCD, LAS, LAZ, XYZ/TXT or "
                             "KITTI .bin")
    if path.stat().st_size == 0:
        raise SceneReadError(f"{path}: the file is empty")
    crs, file_unit = None, None
    if suffix in (".las", ".laz"):
        pts, crs, file_unit = _read_las(path)
    elif suffix == ".bin":
        pts = _read_kitti(path)
    elif suffix in (".ply", ".pcd"):
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
