"""Point readers: PLY, PCD, LAS, LAZ, XYZ/TXT/CSV, KITTI ``.bin`` and nuScenes ``.pcd.bin``, always to float64.

Large projected coordinates stay exact: LAS/LAZ integers are scaled in float64, text is parsed in float64, and a
:class:`PointSet` carries a local offset (a round number near the minimum) for code that needs small numbers.
"""

from __future__ import annotations

import datetime
import struct
import warnings
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from ..errors import SceneReadError
from ..geo.georef import crs_info
from ..o3d import load
from ._files import checked_input

#: the largest coordinate (file units times the unit) a survey's point may have: projected and ECEF coordinates
#: stay under 1e7 m; beyond this a value is a corrupt record, not a position
MAX_COORD = 1e8
#: the largest LAS header offset accepted (file units)
MAX_LAS_OFFSET = 1e9

UNIT_SCALES = {"m": 1.0, "cm": 0.01, "mm": 0.001, "ft": 0.3048, "us-ft": 1200.0 / 3937.0, "in": 0.0254}
POINT_SUFFIXES = {".ply", ".pcd", ".las", ".laz", ".xyz", ".txt", ".csv", ".pts", ".bin"}


@dataclass
class PointSet:
    """Points of a scene or object.

    points : (n, 3) float64 metres in the file's frame (file coordinates times ``scale``, z times ``z_scale``).
    offset : (3,) float64, a round local origin; ``points - offset`` is small. unit : the horizontal unit applied.
    crs_info : the projected CRS of the coordinates (``--crs``, else the LAS/LAZ header's), or None. n_dropped :
    non-finite points removed. survey_date : the LAS/LAZ header's creation date (ISO ``YYYY-MM-DD``), or None.
    origins : (n, 3) each point's scanner position (same frame as ``points``), from a mobile survey's trajectory.
    sweep : a vehicle-mounted sweep in its sensor's frame (a KITTI .bin, a nuScenes .pcd.bin): seen from the ground,
    each object from one side, not from the air.
    """

    path: Path
    points: np.ndarray
    offset: np.ndarray
    unit: str
    crs_info: object = None
    n_dropped: int = 0
    scale: float = 1.0
    z_scale: float = 1.0
    n_outliers: int = 0
    survey_date: str | None = None
    survey_date_source: str | None = None
    survey_date_warning: str | None = None
    classes: np.ndarray | None = None  # (n,) uint8 ASPRS classes, when the file has any beyond 0 and 1
    origins: np.ndarray | None = None  # (n, 3) each point's scanner position (a mobile survey's trajectory), or None
    sweep: bool = False  # a vehicle-mounted sweep in its sensor's frame (KITTI .bin, nuScenes .pcd.bin)

    def without(self, drop: np.ndarray) -> "PointSet":
        """The same scene without the points of the (n,) mask ``drop`` (counted as outliers)."""
        return replace(self.subset(~drop), n_outliers=self.n_outliers + int(drop.sum()))

    def subset(self, keep: np.ndarray) -> "PointSet":
        """The same scene with only the points of the (n,) mask ``keep`` (and their classes)."""
        return replace(self, points=self.points[keep], classes=None if self.classes is None else self.classes[keep],
                       origins=None if self.origins is None else self.origins[keep])

    @property
    def from_ground(self) -> bool:
        """Whether the scan was made from the ground (a vehicle's sweep, or a survey with its scanners' positions):
        each object seen from one side, a wall seen standing."""
        return self.sweep or self.origins is not None

    @property
    def crs(self) -> str | None:
        return self.crs_info.crs if self.crs_info is not None else None

    @property
    def local(self) -> np.ndarray:
        return self.points - self.offset

    @property
    def dropped_note(self) -> str | None:
        """One line saying how many rows were dropped for want of finite x, y, z (None when none were)."""
        if not self.n_dropped:
            return None
        total = len(self.points) + self.n_dropped
        return (f"{self.path}: {self.n_dropped:,} of {total:,} rows have no finite x, y, z (NaN or infinite) and "
                f"were dropped; {len(self.points):,} points kept")


#: the longest line of a text point file (bytes): x y z and a few more columns; a longer one is not a point record
MAX_TEXT_LINE = 4096


def text_lines(path: Path, max_line: int = MAX_TEXT_LINE) -> int:
    """The number of lines of a text point file, read in 16 MB pieces (nothing kept); :class:`SceneReadError` when a
    line is longer than ``max_line`` bytes (a 40 MB one-line file is refused after reading 16 MB, not parsed)."""
    lines, run = 0, 0
    with open(path, "rb") as fh:
        while True:
            chunk = fh.read(16 << 20)
            if not chunk:
                break
            ends = np.flatnonzero(np.frombuffer(chunk, dtype=np.uint8) == 10)
            longest = max(run + (int(ends[0]) if len(ends) else len(chunk)),
                          int(np.diff(ends).max()) if len(ends) > 1 else 0)
            if longest > max_line:
                raise SceneReadError(f"{path}: a line of more than {max_line:,} bytes; a text point file holds x y z "
                                     "(and a few more columns) per line: check the file's format")
            run = len(chunk) - 1 - int(ends[-1]) if len(ends) else run + len(chunk)
            lines += len(ends)
    return lines + (run > 0)


def point_count_bound(path) -> int:
    """The most points a point file can give, from its header or its lines alone (none are parsed): LAS/LAZ and PLY
    headers, a KITTI .bin's size, a PCD's POINTS, a text file's lines (:func:`text_lines`)."""
    path, suffix = check_point_file(path)
    if suffix in (".las", ".laz"):
        import laspy

        try:
            with laspy.open(str(path)) as reader:
                return int(reader.header.point_count)
        except Exception as exc:
            raise SceneReadError(f"{path}: not a readable LAS/LAZ file ({type(exc).__name__}: {exc})") from exc
    if suffix == ".bin":
        return path.stat().st_size // (4 * bin_fields(path))
    if suffix in (".ply", ".pcd"):
        with open(path, "rb") as fh:
            head = fh.read(65536)
        for line in head.split(b"\n"):
            words = line.split()
            if suffix == ".ply" and len(words) == 3 and words[:2] == [b"element", b"vertex"] and words[2].isdigit():
                return int(words[2])
            if suffix == ".pcd" and len(words) == 2 and words[0] == b"POINTS" and words[1].isdigit():
                return int(words[1])
        return path.stat().st_size // 12
    return text_lines(path)


def _read_text(path: Path) -> np.ndarray:
    text_lines(path)  # no parser sees a line longer than a point record
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


def bin_fields(path: Path) -> int:
    """The float32 values a point of a binary sweep holds: 5 for a nuScenes ``.pcd.bin`` (x y z intensity ring),
    4 for a KITTI ``.bin`` (x y z reflectance).

    >>> bin_fields(Path("n015__LIDAR_TOP__1532402927647951.pcd.bin")), bin_fields(Path("000008.bin"))
    (5, 4)
    """
    return 5 if path.name.lower().endswith(".pcd.bin") else 4


def _read_kitti(path: Path) -> np.ndarray:
    n = bin_fields(path)
    raw = np.fromfile(path, dtype="<f4")
    if raw.size == 0 or raw.size % n:
        what = "a nuScenes .pcd.bin holds float32 x y z intensity ring" if n == 5 else \
            "a KITTI .bin holds float32 x y z r"
        raise SceneReadError(f"{path}: {what} records; this file's size ({path.stat().st_size} bytes) is not a "
                             f"multiple of {4 * n} (truncated?)")
    return raw.reshape(-1, n)[:, :3].astype(np.float64)


def check_las_header(path: Path, header) -> None:
    """:class:`SceneReadError` for a LAS/LAZ header whose scale factors are not positive (zero loses every
    coordinate, a negative one mirrors the scene) or whose offsets are beyond :data:`MAX_LAS_OFFSET`."""
    scales = np.asarray(header.scales, dtype=np.float64)
    offsets = np.asarray(header.offsets, dtype=np.float64)
    if not (np.isfinite(scales).all() and (scales > 0).all()):
        raise SceneReadError(f"{path}: the LAS header's scale factors {scales.tolist()} must be positive (zero loses "
                             "the coordinates, a negative one mirrors the scene); rewrite the file with correct "
                             "scales (e.g. pdal translate or las2las)")
    if not (np.isfinite(offsets).all() and (np.abs(offsets) <= MAX_LAS_OFFSET).all()):
        raise SceneReadError(f"{path}: the LAS header's offsets {offsets.tolist()} are not coordinates on Earth; "
                             "rewrite the file with correct offsets (e.g. pdal translate or las2las)")


def most_points(path: Path, header) -> int | None:
    """The most points a LAS/LAZ file of this size can hold, from its header alone: an uncompressed file stores
    every record in full; a LAZ file of fixed-size chunks stores at least each chunk's first point in full (None
    for LAZ with variable chunks, which have no such bound)."""
    room = Path(path).stat().st_size - int(header.offset_to_point_data)
    size = int(header.point_format.size)
    if not header.are_points_compressed:
        return max(room, 0) // size
    laszip = next((v for v in header.vlrs if getattr(v, "user_id", "") == "laszip encoded"), None)
    data = getattr(laszip, "record_data", b"") or b""
    if len(data) < 16:
        return None
    (chunk,) = struct.unpack_from("<I", data, 12)
    if chunk == 0 or chunk == 0xFFFFFFFF:
        return None
    return max(room, 0) // size * chunk


def check_point_count(path: Path, header) -> None:
    """:class:`SceneReadError` when a LAS/LAZ header claims more points than the file can hold (a damaged or
    planted header; nothing is allocated for it)."""
    most = most_points(path, header)
    n = int(header.point_count)
    if most is not None and n > most:
        raise SceneReadError(f"{path}: the header says {n:,} points but the file's {Path(path).stat().st_size:,} "
                             f"bytes hold at most {most:,}; the file is truncated or damaged: copy or export it "
                             "again")


def header_date(header) -> str | None:
    """A LAS/LAZ header's creation date as ``YYYY-MM-DD`` (the survey's, by the specification), or None."""
    try:
        d = header.creation_date
    except Exception:  # a day of year the calendar does not have
        return None
    return d.isoformat() if d is not None else None


#: where GPS time starts; "adjusted standard GPS time" (a LAS header's global encoding bit 0) is GPS seconds minus
#: 1e9 (leap seconds, 18 in 2026, cannot move a median across a day but at midnight: ignored)
GPS_EPOCH = __import__("datetime").datetime(1980, 1, 6)
#: sources of a survey date, best first
DATE_SOURCES = ("--date", "GPS time", "file header creation date")


def las_survey_date(path: Path, header, gps_time=None) -> tuple[str | None, str | None, str | None]:
    """(date ``YYYY-MM-DD``, its source, a warning or None) of a LAS/LAZ file's survey: from its points' GPS times
    when the header says they are adjusted standard GPS time (the acquisition itself), else the header's creation
    date, with a warning when that date is within a month before the file was written (it is then likely the day
    the file was made, not the flight)."""
    try:
        standard = int(header.global_encoding.gps_time_type) == 1
    except Exception:
        standard = False
    if standard and gps_time is not None and len(gps_time):
        t = np.asarray(gps_time, dtype=np.float64)
        t = t[np.isfinite(t)]
        if len(t):
            day = (GPS_EPOCH + datetime.timedelta(seconds=float(np.median(t)) + 1e9)).date()
            if datetime.date(1990, 1, 1) <= day <= datetime.date.today() + datetime.timedelta(days=1):
                return day.isoformat(), "GPS time", None
    created = header_date(header)
    if created is None:
        return None, None, None
    written = datetime.date.fromtimestamp(Path(path).stat().st_mtime)
    warning = None
    if 0 <= (written - datetime.date.fromisoformat(created)).days <= 31:
        warning = (f"{Path(path).name}: the survey date {created} is the header's creation date, within a month "
                   f"of the day the file was written ({written.isoformat()}); it may be the day the file was made, "
                   "not the flight: give the survey's date with --date YYYY-MM-DD")
    return created, "file header creation date", warning


def _read_las(path: Path):
    """(points (n, 3) in file units, the header's CRS or None, the error parsing it or None, the survey date,
    the points' ASPRS classes or None when every point is 0 (never classified) or 1 (unclassified), their GPS times
    or None when the point format has none)."""
    import laspy

    try:
        with laspy.open(str(path)) as reader:
            check_las_header(path, reader.header)
            check_point_count(path, reader.header)
            las = reader.read()
    except SceneReadError:
        raise
    except Exception as exc:
        raise SceneReadError(f"{path}: not a readable LAS/LAZ file ({type(exc).__name__}: {exc})") from exc
    if len(las.points) < las.header.point_count:
        raise SceneReadError(f"{path}: holds {len(las.points):,} of the {las.header.point_count:,} points its header "
                             "says; the file is truncated or damaged: copy or export it again")
    pts = np.column_stack([np.asarray(las.x, dtype=np.float64), np.asarray(las.y, dtype=np.float64),
                           np.asarray(las.z, dtype=np.float64)])
    has_gps = "gps_time" in las.point_format.dimension_names
    gps = np.asarray(las.gps_time, dtype=np.float64) if has_gps else None
    date = las_survey_date(path, las.header, gps)
    classes = np.asarray(las.classification, dtype=np.uint8)
    classes = classes if (classes > 1).any() else None
    try:
        return pts, las.header.parse_crs(), None, date, classes, gps
    except Exception as exc:  # a CRS record is there but broken: the caller decides (error unless told the unit)
        return pts, None, exc, date, classes, gps


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
                count = int(words[2]) if len(words) == 3 and words[2].isdigit() else -1
                if count < 0 or count > path.stat().st_size:
                    shown = " ".join(words[2:])[:40]
                    raise SceneReadError(f"{path}: the PLY header says the element '{words[1][:40]}' has "
                                         f"{shown} records, which the file cannot hold; the file is damaged, export "
                                         "it again")
                current = [words[1], count, []]
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
    o3d = load()

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


def crs_and_units(path: Path, unit: str, crs, header_crs, header_error, override: bool = False):
    """(CrsInfo or None, unit name, horizontal scale, vertical scale) for a file, or SceneReadError. A ``crs``
    (``--crs``) that differs from the one the header states is refused unless ``override`` (``--override-crs``)."""
    info = None
    if crs:
        info = crs_info(crs, "--crs", where=f"--crs {crs}")
        if header_crs is not None and not override and not same_crs(info.crs, header_crs):
            stated = crs_info(header_crs, "file header", where=f"{path}", error=SceneReadError)
            raise SceneReadError(f"{path}: --crs {crs} ({info.name}) differs from the CRS the file's header states "
                                 f"({stated.name}, {stated.crs}); drop --crs to use the header's, or add "
                                 "--override-crs if the header is wrong")
    elif header_crs is not None:
        info = crs_info(header_crs, "file header", where=f"{path}", error=SceneReadError)
    elif header_error is not None and unit == "auto":
        raise SceneReadError(f"{path}: the CRS record in the header cannot be parsed "
                             f"({str(header_error).splitlines()[0]}); pass --crs EPSG:NNNN (the file's CRS) and "
                             "--unit if its coordinates are not in that CRS's unit")
    if unit == "auto":
        if info is None:
            return None, "m", 1.0, 1.0
        name = next((k for k, v in UNIT_SCALES.items() if abs(v - info.unit_m) < 1e-9), f"{info.unit_m:g} m")
        return info, name, info.unit_m, info.vertical_unit_m
    if unit not in UNIT_SCALES:
        raise SceneReadError(f"{path}: unknown --unit '{unit}'; use auto, {', '.join(UNIT_SCALES)}")
    scale = UNIT_SCALES[unit]
    if info is not None and abs(info.unit_m - scale) > 1e-9:
        raise SceneReadError(f"{path}: --unit {unit} disagrees with the unit of the CRS {info.name} "
                             f"({info.unit_m:g} m, from the {info.source}); drop --unit, or pass the right --crs")
    return info, unit, scale, (info.vertical_unit_m if info is not None else scale)


def same_crs(a, b) -> bool:
    """Whether two CRSs (pyproj input, or None for none stated) are the same, axis order aside."""
    if a is None or b is None:
        return a is None and b is None
    if a == b:
        return True
    from pyproj import CRS

    return CRS.from_user_input(a).equals(CRS.from_user_input(b), ignore_axis_order=True)


def check_point_file(path) -> tuple[Path, str]:
    """``(path, lower-case suffix)`` of an existing, non-empty point file of a format :func:`read_points` reads, or
    :class:`SceneReadError` naming the file and the fix (before anything else of a run is looked at)."""
    return checked_input(path, POINT_SUFFIXES, "point", "PLY, PCD, LAS, LAZ, XYZ/TXT, KITTI .bin or nuScenes .pcd.bin",
                         SceneReadError)


def read_points(path, unit: str = "auto", crs: str | None = None, override_crs: bool = False,
                trajectory=None) -> PointSet:
    """Read a point file to a :class:`PointSet`.

    unit : ``auto`` (the CRS's units when one is known, else metres) or one of m, cm, mm, ft, us-ft, in.
    crs : the file's projected CRS (``--crs``), overriding the one a LAS/LAZ header states. Horizontal and vertical
    units come from the CRS (the vertical part of a compound CRS, else the horizontal unit); a ``crs`` that differs
    from the header's is refused unless ``override_crs``.
    trajectory : a mobile survey's trajectory file (:mod:`twinreg.io.trajectory`): each point's scanner position
    from its GPS time (``origins``); a LAS/LAZ with GPS times only.
    Raises :class:`SceneReadError` with one line naming the file for a missing, unreadable, truncated or empty file,
    a geographic CRS, or a CRS record that cannot be parsed (unless ``--unit`` or ``--crs`` say what it meant).
    """
    path, suffix = check_point_file(path)
    header_crs = header_error = None
    date = (None, None, None)
    classes = gps = None
    if suffix in (".las", ".laz"):
        pts, header_crs, header_error, date, classes, gps = _read_las(path)
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
    classes = classes[finite] if classes is not None else None
    if len(pts) == 0:
        raise SceneReadError(f"{path}: no valid points")
    info, unit, scale, z_scale = crs_and_units(path, unit.lower(), crs, header_crs, header_error, override_crs)
    if scale != 1.0 or z_scale != 1.0:
        pts = pts * np.array([scale, scale, z_scale])
    far = np.abs(pts).max(1) > MAX_COORD
    if far.any():
        raise SceneReadError(f"{path}: {int(far.sum())} point(s) lie beyond {MAX_COORD:.0e} m (e.g. "
                             f"{pts[np.argmax(far)].tolist()}): corrupt records, not positions; remove them (e.g. "
                             "pdal translate with a range filter) and run again")
    origins = None
    if trajectory is not None:
        origins = _origins(path, trajectory, None if gps is None else gps[finite], info) * [scale, scale, z_scale]
    offset = np.floor(pts.min(0) / 100.0) * 100.0
    offset[2] = 0.0
    return PointSet(path=path, points=pts, offset=offset, unit=unit, crs_info=info, n_dropped=dropped, scale=scale,
                    z_scale=z_scale, survey_date=date[0], survey_date_source=date[1], survey_date_warning=date[2],
                    classes=classes, origins=origins, sweep=suffix == ".bin")


def _origins(path: Path, trajectory, gps, info) -> np.ndarray:
    """Each point's scanner position (file units, as the points before their unit's scale) from its GPS time and
    the ``trajectory`` file (in the scan's CRS and time base)."""
    from .trajectory import read_trajectory

    if gps is None or (len(gps) > 1 and np.ptp(gps) == 0):  # format 6 and up always have the field: all alike is none
        raise SceneReadError(f"{path}: its points carry no GPS time, so --trajectory cannot place their scanner; "
                             "give the LAS/LAZ as the survey delivered it (point format 1, 3 or 6-10), or leave "
                             "--trajectory out")
    traj = read_trajectory(trajectory, crs=info.crs if info is not None else None)
    return traj.positions(gps, trajectory)
