"""The twins compare reads: each build-twin folder as an :class:`Epoch` (its objects as arrays, its survey date, its
frame and its observation record), checked as data from someone else (sizes first, JSON only, every value
typed), and put in survey-date order."""

from __future__ import annotations

import datetime
import math
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from cosco.levels import LEVELS

from ..errors import CompareError, GeorefError
from ..geo.georef import Georef
from ..geo.vertical import vertical_of
from ..io import observed
from ..io._files import MAX_TWIN_BYTES, read_json_doc

#: the largest object size (m) a twin may state: a building block is still under this
MAX_SIZE_M = 500.0
_CODE = re.compile(r"^[A-Za-z]{2,12}:[0-9]{1,7}$")
#: a kind as twin.json states it (a catalogue's category): anything else from a stranger's file reads unknown
_KIND = re.compile(r"[a-z][a-z0-9_]{0,39}")
_WKT = re.compile(r"^\s*(PROJCRS|PROJCS|COMPOUNDCRS|COMPD_CS|GEOGCRS|GEOGCS|BOUNDCRS|GEODCRS)\s*\[")


@dataclass
class Epoch:
    """One survey's twin: ``folder``, survey ``date`` (``YYYY-MM-DD`` or None), its ``georef``; per object (n):
    ``ids``, ``centre`` (n, 3) in the twin's coordinates, ``heading`` (rad), ``size`` (n, 3) of what was placed
    (the model's, else the measured box), ``measured`` (n, 3), ``models`` (name or None), ``confidence``
    (NaN: none), ``n_points``, ``lonlat`` (n, 2) as twin.json states them; the scan's ``noise`` (m) and
    ``spacing`` (m, mean point spacing of the area it saw); and
    its observation ``record``; ``vertical``: its heights' datum (None: unknown), and ``height`` how its heights
    were put in the comparison's datum (set by :func:`read_epochs`); ``kinds``: each object's kind (``unknown``
    when its twin.json gives none, or not a kind's word); ``levels``: each object's level of symmetry, its model's
    when a model is placed (``none`` when its twin.json gives none or another word)."""

    folder: Path
    date: str | None
    georef: Georef
    ids: list
    centre: np.ndarray
    heading: np.ndarray
    size: np.ndarray
    measured: np.ndarray
    models: list
    confidence: np.ndarray
    n_points: np.ndarray
    lonlat: np.ndarray
    noise: float
    spacing: float
    record: observed.Record
    n_scan_points: int = 0
    vertical: str | None = None
    height: dict | None = None
    kinds: list = field(default_factory=list)
    levels: list = field(default_factory=list)

    def __len__(self) -> int:
        return len(self.ids)

    def frame(self) -> str:
        """The coordinates' frame, in words."""
        g = self.georef
        if g.crs:
            return g.crs_name or g.crs
        return f"a local frame at {g.lat:.6f}, {g.lon:.6f} (anchor {g.anchor[0]:g}, {g.anchor[1]:g})"


def _number(v, what: str, folder: Path) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or abs(v) > 1e9:
        raise CompareError(f"{folder}: twin.json's {what} is not a finite number; rerun build-twin")
    return float(v)


def _georef(doc, folder: Path) -> Georef:
    g = doc.get("georef")
    if not isinstance(g, dict):
        raise CompareError(f"{folder}: twin.json has no georef; rerun build-twin")
    crs = g.get("crs")
    if crs is not None and not (isinstance(crs, str) and len(crs) < 20_000 and (_CODE.match(crs) or _WKT.match(crs))):
        raise CompareError(f"{folder}: twin.json's CRS is neither an authority code nor WKT; rerun build-twin")
    anchor = g.get("anchor") or [0.0, 0.0]
    if not isinstance(anchor, list) or len(anchor) != 2:
        raise CompareError(f"{folder}: twin.json's georef anchor is not two numbers; rerun build-twin")
    if crs is None and not (isinstance(g.get("lat"), (int, float)) and isinstance(g.get("lon"), (int, float))):
        raise CompareError(f"{folder}: twin.json's georef has neither a CRS nor a position; rerun build-twin")
    num = (lambda k, d=None: None if g.get(k, d) is None else _number(g.get(k, d), f"georef {k}", folder))
    name = g.get("crs_name")
    return Georef(num("lat"), num("lon"), num("alt", 0.0) or 0.0, tuple(_number(a, "anchor", folder) for a in anchor),
                  crs, num("crs_unit_m", 1.0) or 1.0, num("vertical_unit_m", 1.0) or 1.0,
                  name if isinstance(name, str) else None, None)


def _vertical(doc, folder: Path) -> str | None:
    v = doc["georef"].get("vertical_crs") if doc["georef"].get("vertical_source") else None
    if v is not None and not (isinstance(v, str) and (_CODE.match(v) or _WKT.match(v) or v.startswith("VERTCRS"))):
        raise CompareError(f"{folder}: twin.json's vertical_crs is not a CRS; rerun build-twin")
    return v


def _date(doc, folder: Path) -> str | None:
    d = doc.get("survey_date")
    if d is None:
        return None
    try:
        return datetime.date.fromisoformat(d).isoformat() if isinstance(d, str) and len(d) == 10 else _bad_date(folder)
    except ValueError:
        return _bad_date(folder)


def _bad_date(folder: Path):
    raise CompareError(f"{folder}: twin.json's survey_date is not a date (YYYY-MM-DD); rerun build-twin with --date")


def _vec(o: dict, key: str, names, folder: Path) -> list:
    v = o.get(key)
    if isinstance(v, dict):
        v = [v.get(n) for n in names]
    if not isinstance(v, list) or len(v) != len(names):
        raise CompareError(f"{folder}: an object's {key} in twin.json is malformed; rerun build-twin")
    return [_number(x, key, folder) for x in v]


def _size(o: dict, key: str, folder: Path) -> list:
    """An object's length, width and height: not negative and at most :data:`MAX_SIZE_M` metres."""
    v = _vec(o, key, ("length", "width", "height"), folder)
    if not all(0.0 <= x <= MAX_SIZE_M for x in v):
        raise CompareError(f"{folder}: object {o['id'][:40]!r} has a {key} of {v} m in twin.json, not the size of a "
                           f"city object (0-{MAX_SIZE_M:g} m); rerun build-twin")
    return v


def _objects(doc, folder: Path) -> dict:
    objs = doc.get("objects")
    if not isinstance(objs, list):
        raise CompareError(f"{folder}: twin.json lists no objects; rerun build-twin")
    cols = {"ids": [], "centre": [], "heading": [], "size": [], "measured": [], "models": [], "confidence": [],
            "n_points": [], "lonlat": [], "kinds": [], "levels": []}
    for o in objs:
        if not isinstance(o, dict) or not isinstance(o.get("id"), str):
            raise CompareError(f"{folder}: an object in twin.json has no id; rerun build-twin")
        m = o.get("match")
        name = m.get("name") if isinstance(m, dict) else None
        conf = m.get("confidence") if isinstance(m, dict) else None
        cols["ids"].append(o["id"][:200])
        cols["centre"].append(_vec(o, "centroid", "xyz", folder))
        cols["heading"].append(_number(o.get("heading_rad"), "heading_rad", folder))
        cols["size"].append(_size(o, "size", folder))
        cols["measured"].append(_size(o, "measured_size", folder))
        cols["models"].append(name[:200] if isinstance(name, str) else None)
        kind = o.get("kind")
        cols["kinds"].append(kind if isinstance(kind, str) and _KIND.fullmatch(kind) else "unknown")
        # a placed model's level says what its heading means; else the object's own
        sym = o.get("symmetry")
        level = m.get("level") if isinstance(m, dict) and m.get("level") in LEVELS else \
            sym.get("level") if isinstance(sym, dict) else None
        cols["levels"].append(level if level in LEVELS else "none")
        conf = _number(conf, "confidence", folder) if conf is not None else np.nan
        n = _number(o.get("n_points", 0), "n_points", folder)
        if not (np.isnan(conf) or 0.0 <= conf <= 1.0) or n < 0 or n != int(n):
            raise CompareError(f"{folder}: object {o['id'][:40]!r} in twin.json has a confidence outside 0-1 or a "
                               "point count that is not a count; rerun build-twin")
        cols["confidence"].append(conf)
        cols["n_points"].append(int(n))
        cols["lonlat"].append([_number(o.get("lon"), "lon", folder), _number(o.get("lat"), "lat", folder)])
    if len(set(cols["ids"])) != len(cols["ids"]):
        seen = set()
        twice = next(i for i in cols["ids"] if i in seen or seen.add(i))
        raise CompareError(f"{folder}: twin.json has two objects with the id {twice!r}; rerun build-twin")
    return cols


def _noise(doc, folder: Path) -> float:
    """The scan's noise (m): positive and under a metre."""
    v = _number(doc.get("noise_m", 0.02), "noise_m", folder)
    if not 0.0 < v < 1.0:
        raise CompareError(f"{folder}: twin.json's noise_m is {v:g} m, not a scanner's noise (0-1 m); rerun "
                           "build-twin")
    return v


def read_epoch(folder) -> Epoch:
    """A build-twin folder as an :class:`Epoch`; :class:`CompareError` naming the folder and the fix."""
    folder = Path(folder)
    path = folder / "twin.json"
    if not folder.is_dir() or not path.is_file() or path.is_symlink():
        raise CompareError(f"{folder}: not a twin folder (no twin.json); give folders written by "
                           "`twinreg build-twin`")
    doc = read_json_doc(path, MAX_TWIN_BYTES, CompareError, "rerun build-twin on its scan")
    if not isinstance(doc, dict) or "objects" not in doc or "georef" not in doc:
        raise CompareError(f"{folder}: its twin.json is not one build-twin writes; rerun build-twin")
    if not isinstance(doc.get("observation"), dict):
        raise CompareError(f"{folder}: written before `compare` existed (no observation record, {observed.FILE}); "
                           "rerun `twinreg build-twin` on its scan to write one")
    cols = _objects(doc, folder)
    try:
        record = observed.read(folder / observed.FILE, len(cols["ids"]))
    except observed.RecordError as exc:
        raise CompareError(f"{folder / observed.FILE}: {exc}; rerun build-twin on its scan") from exc
    n_scan = int(_number(doc.get("n_points", 0), "n_points", folder))
    seen = sum(int((r.code != observed.NONE).sum()) for r in record.rasters) * observed.PIXEL ** 2
    return Epoch(folder, _date(doc, folder), _georef(doc, folder), cols["ids"],
                 np.array(cols["centre"], dtype=np.float64).reshape(-1, 3),
                 np.array(cols["heading"], dtype=np.float64), np.array(cols["size"]).reshape(-1, 3),
                 np.array(cols["measured"]).reshape(-1, 3), cols["models"],
                 np.array(cols["confidence"], dtype=np.float64), np.array(cols["n_points"], dtype=np.int64),
                 np.array(cols["lonlat"], dtype=np.float64).reshape(-1, 2),
                 _noise(doc, folder), float(np.sqrt(seen / max(n_scan, 1))),
                 record, n_scan, _vertical(doc, folder), kinds=cols["kinds"], levels=cols["levels"])


def same_frame(a: Epoch, b: Epoch) -> bool:
    """Whether two epochs' coordinates are in one frame (the same horizontal CRS, or the same local anchor)."""
    ga, gb = a.georef, b.georef
    if bool(ga.crs) != bool(gb.crs):
        return False
    if ga.crs:
        if ga.crs == gb.crs:
            return True
        import pyproj

        def horizontal(crs):  # a compound CRS's horizontal part: heights are checked on their own
            c = pyproj.CRS.from_user_input(crs)
            return c.sub_crs_list[0] if c.is_compound and c.sub_crs_list else c

        try:
            return horizontal(ga.crs) == horizontal(gb.crs)
        except pyproj.exceptions.CRSError:
            return False
    return (np.allclose([ga.lat, ga.lon], [gb.lat, gb.lon], atol=1e-9) and abs(ga.alt - gb.alt) < 1e-6
            and np.allclose(ga.anchor, gb.anchor, atol=1e-6))


def read_epochs(folders, say=None) -> list[Epoch]:
    """The twins in survey-date order (the order given when any has no date, said through ``say``); checks that
    they are distinct, in one frame, and overlap."""
    if len(folders) < 2:
        raise CompareError("compare needs two or more twin folders")
    seen = {}
    for f in folders:
        key = Path(f).resolve()
        if key in seen:
            raise CompareError(f"{f}: given twice (the same twin as {seen[key]}); give twins of different surveys")
        seen[key] = f
    epochs = [read_epoch(f) for f in folders]
    _check_distinct(epochs)
    for e in epochs[1:]:
        far = _distance_km(epochs[0], e)
        if far > FAR_KM:
            raise CompareError(f"{e.folder}: lies {far:,.0f} km from {epochs[0].folder} (by their objects' "
                               "positions): they are surveys of different places; compare twins of the same place")
        if not same_frame(epochs[0], e):
            raise CompareError(f"{e.folder}: its coordinates are in {e.frame()}, those of {epochs[0].folder} in "
                               f"{epochs[0].frame()}; rebuild one twin in the other's CRS (--crs) to compare them")
    undated = [e for e in epochs if e.date is None]
    if undated:
        if say:
            say(f"{', '.join(str(e.folder) for e in undated)}: no survey date (rerun build-twin with --date "
                "YYYY-MM-DD); the epochs are taken in the order given")
    else:
        epochs = sorted(epochs, key=lambda e: e.date)
    for a, b in zip(epochs, epochs[1:]):
        _check_overlap(a, b)
    _one_datum(epochs, say)
    return epochs


def _one_datum(epochs: list[Epoch], say) -> None:
    """Put every epoch's heights in one datum: the first stated one in date order. An epoch in another stated
    datum is converted (``H + N_own - N_first``, both undulations at the area's centre, as the exports compute
    them; what varies across the area goes into the alignment's height offset); its ``height`` says how. A twin
    whose datum is unknown is said and compared as it is (a difference of datum goes into the height offset)."""
    stated = [e for e in epochs if e.vertical]
    if not stated:
        return
    ref = stated[0]
    lon, lat = (np.median(ref.lonlat, axis=0) if len(ref.lonlat) else _centre_lonlat(ref))
    for e in epochs:
        if not e.vertical:
            continue
        try:
            own, first = (vertical_of(x.vertical, "twin.json", str(x.folder)) for x in (e, ref))
        except GeorefError as exc:
            raise CompareError(f"{exc}; rerun build-twin") from exc
        shift = 0.0
        if e.vertical != ref.vertical:
            shift = float(own.undulation(lon, lat)[0] - first.undulation(lon, lat)[0])
            _shift_heights(e, shift)
        e.height = {"datum": e.vertical, "to": ref.vertical, "shift_m": round(shift, 4),
                    "accuracy_m": max(own.accuracy_m or 0.0, first.accuracy_m or 0.0) if shift else 0.0}
    unknown = [e for e in epochs if not e.vertical]
    if unknown and say:
        say(f"{', '.join(str(e.folder) for e in unknown)}: the heights' datum is unknown (the others' is "
            f"{ref.vertical}); compared as they are, a difference of datum goes into the height offset")
    converted = [e for e in epochs if e.height and e.height["shift_m"]]
    if converted and say:
        say("; ".join(f"{e.folder}: heights in {e.vertical}, converted to {ref.vertical} "
                      f"({e.height['shift_m']:+.3f} m)" for e in converted))


#: twins whose objects lie further apart than this (km) are not of one place, whatever their frames
FAR_KM = 50.0


def _distance_km(a: Epoch, b: Epoch) -> float:
    """The distance (km) between the medians of two epochs' objects' WGS84 positions, as their twin.json states
    them (0 when either has none)."""
    if not len(a.lonlat) or not len(b.lonlat):
        return 0.0
    from pyproj import Geod

    (lon1, lat1), (lon2, lat2) = np.median(a.lonlat, axis=0), np.median(b.lonlat, axis=0)
    return float(Geod(ellps="WGS84").inv(lon1, lat1, lon2, lat2)[2]) / 1000.0


def _centre_lonlat(e: Epoch) -> tuple[float, float]:
    r = e.record.rasters[0]
    c = (r.lo + r.hi) / 2
    ll = e.georef.to_wgs84(np.array([[c[0], c[1], 0.0]]))
    return float(ll[0, 0]), float(ll[0, 1])


def _shift_heights(e: Epoch, dz: float) -> None:
    """Add ``dz`` to every height of an epoch: its objects' centres and its record's ground."""
    e.centre = e.centre + [0.0, 0.0, dz]
    for r in e.record.rasters:
        r.z0 = r.z0 + dz


def _check_distinct(epochs: list[Epoch]) -> None:
    prints = {}
    for e in epochs:
        key = (len(e), e.n_scan_points, e.centre.round(4).tobytes())
        if key in prints:
            raise CompareError(f"{e.folder}: the same twin as {prints[key]} (the same scan's objects); give twins "
                               "of different surveys")
        prints[key] = e.folder


def _check_overlap(a: Epoch, b: Epoch) -> None:
    (alo, ahi), (blo, bhi) = a.record.bounds(), b.record.bounds()
    lo, hi = np.maximum(alo, blo), np.minimum(ahi, bhi)
    if np.any(hi - lo < 2.0):
        raise CompareError(f"{b.folder}: does not overlap {a.folder} (x {blo[0]:.1f}-{bhi[0]:.1f}, y {blo[1]:.1f}-"
                           f"{bhi[1]:.1f} against x {alo[0]:.1f}-{ahi[0]:.1f}, y {alo[1]:.1f}-{ahi[1]:.1f}); "
                           "compare twins of the same place")
