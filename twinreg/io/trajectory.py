"""A mobile survey's trajectory (issue 50): where the scanner was at each moment, read from what a survey delivers
beside its scan, and each point's scanner position from its GPS time.

Two formats, told apart by content, not by name:

- **CSV** with a header naming at least ``time``, ``x``, ``y``, ``z`` (``t``/``gps_time``, ``easting``/``northing``/
  ``height`` are also understood; ``roll``, ``pitch``, ``heading`` optional, degrees, the heading clockwise from grid
  north as navigation systems give it), in the scan's CRS and time base;
- **SBET** (Applanix's smoothed best estimate of trajectory): records of 17 little-endian doubles (136 bytes):
  time, latitude and longitude (radians, WGS84), ellipsoidal height, velocities, roll, pitch, platform heading
  (radians), wander angle, accelerations and angular rates; projected to the scan's CRS with pyproj.

A stranger's file is data: its size is checked before it is read (at most :data:`MAX_RECORDS` records), every
value must be finite, and times must not go back; one line names the file and the fix otherwise.
"""

from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import SceneReadError

#: the most trajectory records read (a day's drive at 200 Hz is 17M)
MAX_RECORDS = 20_000_000
#: bytes of one SBET record
SBET_RECORD = 17 * 8
#: how far (s) before the first or after the last record a point's time may lie and still be placed
TIME_SLACK = 0.5

_ALIASES = {"time": ("time", "t", "gps_time", "gpstime", "timestamp"), "x": ("x", "easting", "e"),
            "y": ("y", "northing", "n"), "z": ("z", "height", "h", "alt", "altitude"), "roll": ("roll",),
            "pitch": ("pitch",), "heading": ("heading", "yaw")}


@dataclass
class Trajectory:
    """``time`` (n,) s, increasing; ``xyz`` (n, 3) the scanner's reference point in the scan's CRS (m); ``rpy`` (n, 3)
    roll, pitch (rad) and heading (rad from +X counter-clockwise, the scene's convention), NaN where not given."""

    time: np.ndarray
    xyz: np.ndarray
    rpy: np.ndarray

    def positions(self, gps_time: np.ndarray, path: Path | str = "trajectory") -> np.ndarray:
        """(n, 3) the scanner's position at each point's ``gps_time`` (linear between records). A point more than
        :data:`TIME_SLACK` s outside the trajectory's span is an error: the trajectory is another drive's, or in
        another time base (GPS week seconds against adjusted standard time)."""
        t = np.asarray(gps_time, dtype=np.float64)
        if len(t) and (t.min() < self.time[0] - TIME_SLACK or t.max() > self.time[-1] + TIME_SLACK):
            raise SceneReadError(
                f"{path}: the scan's GPS times ({t.min():.1f}-{t.max():.1f} s) lie outside the trajectory's "
                f"({self.time[0]:.1f}-{self.time[-1]:.1f} s): give the trajectory of this drive, in the scan's time "
                "base (GPS week seconds or adjusted standard time, as the LAS header's global encoding says)")
        return np.column_stack([np.interp(t, self.time, self.xyz[:, k]) for k in range(3)])

    def headings(self, t: np.ndarray) -> np.ndarray:
        """(n,) the heading (rad from +X) at times ``t``, linear between records (unwrapped across +-pi)."""
        return np.interp(np.asarray(t, dtype=np.float64), self.time, np.unwrap(self.rpy[:, 2]))


def _checked(path: Path, time, xyz, rpy) -> Trajectory:
    time = np.asarray(time, dtype=np.float64)
    xyz = np.asarray(xyz, dtype=np.float64).reshape(-1, 3)
    if len(time) < 2:
        raise SceneReadError(f"{path}: a trajectory needs at least two records (found {len(time)})")
    if not (np.isfinite(time).all() and np.isfinite(xyz).all()):
        raise SceneReadError(f"{path}: a trajectory's times and positions must all be numbers (found NaN or "
                             "infinity): export it again")
    if np.any(np.diff(time) < 0):
        raise SceneReadError(f"{path}: the trajectory's times go back (record {int(np.argmax(np.diff(time) < 0)) + 2}"
                             "): give one drive's records in time order")
    return Trajectory(time, xyz, np.asarray(rpy, dtype=np.float64).reshape(-1, 3))


def _column(names: list[str], key: str) -> int | None:
    low = [n.strip().lower() for n in names]
    for alias in _ALIASES[key]:
        if alias in low:
            return low.index(alias)
    return None


def read_csv(path: Path) -> Trajectory:
    """A trajectory CSV (comma, semicolon or tab separated) with a header row (see the module's text)."""
    size = path.stat().st_size
    if size > MAX_RECORDS * 200:
        raise SceneReadError(f"{path}: {size / 1e9:.1f} GB is more than a trajectory of {MAX_RECORDS:,} records; "
                             "give one drive's trajectory")
    with open(path, newline="", encoding="utf-8", errors="replace") as fh:
        head = fh.readline(4097)  # a header, not a whole file without a newline
        if len(head) > 4096:
            raise SceneReadError(f"{path}: its first line is {len(head):,} characters: not a trajectory CSV header")
        dialect = max((",", ";", "\t"), key=head.count)
        names = next(csv.reader([head], delimiter=dialect))
        cols = {k: _column(names, k) for k in _ALIASES}
        missing = [k for k in ("time", "x", "y", "z") if cols[k] is None]
        if missing:
            raise SceneReadError(f"{path}: the trajectory's header names no {', '.join(missing)} column (found "
                                 f"{', '.join(n.strip() for n in names[:12])}): name them time, x, y, z")
        used = [c for c in cols.values() if c is not None]
        try:
            data = np.loadtxt(fh, delimiter=dialect, usecols=used, ndmin=2, max_rows=MAX_RECORDS + 1)
        except ValueError as exc:
            raise SceneReadError(f"{path}: a trajectory row is not numbers ({str(exc).splitlines()[0][:120]}): "
                                 "export it again as plain numbers") from exc
    if len(data) > MAX_RECORDS:
        raise SceneReadError(f"{path}: more than {MAX_RECORDS:,} records; give one drive's trajectory")
    at = {k: used.index(c) for k, c in cols.items() if c is not None}
    nan = np.full(len(data), np.nan)
    rpy = np.column_stack([np.radians(data[:, at["roll"]]) if "roll" in at else nan,
                           np.radians(data[:, at["pitch"]]) if "pitch" in at else nan,
                           np.radians(90.0 - data[:, at["heading"]]) if "heading" in at else nan])
    return _checked(path, data[:, at["time"]], data[:, [at["x"], at["y"], at["z"]]], rpy)


def read_sbet(path: Path, crs) -> Trajectory:
    """An SBET file, its WGS84 positions projected to ``crs`` (the scan's; required: an SBET has no grid of its
    own). Heights stay ellipsoidal: a scan in a national datum (NAP, NAVD88) differs by the geoid's height, which
    a scanner position's use here (which side of an object it saw) does not need."""
    size = path.stat().st_size
    if size % SBET_RECORD:
        raise SceneReadError(f"{path}: {size:,} bytes is not a whole number of SBET records ({SBET_RECORD} bytes "
                             "each): the file is cut short or not an SBET")
    n = size // SBET_RECORD
    if n > MAX_RECORDS:
        raise SceneReadError(f"{path}: {n:,} SBET records, more than {MAX_RECORDS:,}; give one drive's trajectory")
    if crs is None:
        raise SceneReadError(f"{path}: an SBET holds latitude and longitude; give the scan's CRS (--crs) to place "
                             "it")
    rec = np.fromfile(path, dtype="<f8", count=n * 17).reshape(n, 17)
    if not np.isfinite(rec[:, :4]).all() or np.abs(rec[:, 1]).max() > np.pi / 2 or np.abs(rec[:, 2]).max() > 2 * np.pi:
        raise SceneReadError(f"{path}: its latitudes and longitudes are not radians within the Earth's range: not "
                             "an SBET, or another layout of one")
    from pyproj import CRS, Transformer

    tr = Transformer.from_crs(CRS.from_epsg(4326), CRS.from_user_input(crs), always_xy=True)
    x, y = tr.transform(np.degrees(rec[:, 2]), np.degrees(rec[:, 1]))
    heading = np.pi / 2 - (rec[:, 9] - rec[:, 10])  # the platform's heading off true north less the wander angle
    return _checked(path, rec[:, 0], np.column_stack([x, y, rec[:, 3]]),
                    np.column_stack([rec[:, 7], rec[:, 8], heading]))


def read_trajectory(path, crs=None) -> Trajectory:
    """A trajectory file (CSV or SBET, by its content: an SBET's first record is 17 doubles with a latitude in
    radians; a CSV starts with a header of names)."""
    path = Path(path)
    if not path.is_file():
        raise SceneReadError(f"{path}: no such trajectory file")
    with open(path, "rb") as fh:
        start = fh.read(64)
    text = start.decode("ascii", errors="replace")
    if any(c.isalpha() for c in text.split("\n")[0][:64]) and "\ufffd" not in text:
        return read_csv(path)
    return read_sbet(path, crs)


def write_csv(path, traj: Trajectory) -> None:
    """Write ``traj`` as a trajectory CSV: time,
    x, y, z (m, 3 decimals), roll, pitch, heading (degrees; heading clockwise from grid north)."""
    rpy = np.degrees(np.nan_to_num(np.asarray(traj.rpy, dtype=np.float64)))
    nav = np.mod(90.0 - rpy[:, 2], 360.0)
    data = np.column_stack([traj.time, traj.xyz, rpy[:, 0], rpy[:, 1], nav])
    np.savetxt(path, data, delimiter=",", header="time,x,y,z,roll,pitch,heading", comments="",
               fmt=["%.6f", "%.3f", "%.3f", "%.3f", "%.4f", "%.4f", "%.4f"])
