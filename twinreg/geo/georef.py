"""Georeferencing scene coordinates with pyproj.

Two ways, as in the contract:

- ``--lat/--lon [--alt] [--anchor X Y]``: the scene is a local east/north/up tangent plane whose point (X, Y, 0)
  sits at (lat, lon, alt) on the WGS84 ellipsoid. Scene points go east/north/up -> ECEF -> geodetic, exactly.
- ``--crs EPSG:NNNN`` (or the CRS a LAS/LAZ header states): the file's coordinates are in that projected CRS;
  every point is converted by pyproj. The scene frame is metric (file coordinates times the CRS's unit, e.g.
  0.3048 for international feet, 1200/3937 for US survey feet), so positions are divided by that unit again
  before pyproj sees them: pyproj always gets the CRS's own units.

Headings: a scene direction (rad, counter-clockwise from +X) becomes a bearing (degrees clockwise from true north)
by converting the point and a point one metre ahead and taking the geodesic azimuth between them, so grid
convergence is accounted for.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, replace

import numpy as np

from ..errors import GeorefError
from .earth import enu_axes
from .vertical import UNKNOWN, vertical_of


@dataclass(frozen=True)
class CrsInfo:
    """A projected CRS as the scene uses it: ``crs`` (an authority code when PROJ knows one, else WKT),
    metres per horizontal and per vertical unit (the vertical one from a compound CRS's vertical part, else equal
    to the horizontal one), where it came from, and a compound CRS's vertical part (``vertical``, as PROJ
    writes it; None for a projected CRS alone)."""

    crs: str
    name: str
    unit_m: float
    vertical_unit_m: float
    source: str
    vertical: str | None = None


def crs_info(user_input, source: str, where: str = "--crs", error=GeorefError) -> CrsInfo:
    """Parse a CRS and read its units; a geographic, geocentric or unparseable CRS raises ``error`` with one line
    naming ``where`` and the fix.

    >>> c = crs_info("EPSG:2994", "--crs")
    >>> c.crs, c.unit_m, c.vertical_unit_m
    ('EPSG:2994', 0.3048, 0.3048)
    >>> round(crs_info("EPSG:2994+6360", "--crs").vertical_unit_m, 9)
    0.30480061
    """
    from pyproj import CRS
    from pyproj.exceptions import CRSError

    try:
        c = CRS.from_user_input(user_input)
    except CRSError as exc:
        raise error(f"{where}: the CRS cannot be parsed ({str(exc).splitlines()[0]}); pass --crs EPSG:NNNN (and "
                    "--unit if the coordinates are not in its unit)") from exc
    if c.is_geographic or c.is_geocentric or not c.is_projected:
        raise error(f"{where}: the CRS {c.name} is not projected (its coordinates are degrees or geocentric); "
                    "reproject the scan to a projected CRS in metres or feet (e.g. UTM) first, or georeference "
                    "local coordinates with --lat/--lon")
    horizontal = c.sub_crs_list[0] if c.is_compound else c
    vertical = c.sub_crs_list[1] if c.is_compound and len(c.sub_crs_list) > 1 else None
    unit = float(horizontal.axis_info[0].unit_conversion_factor)
    v_unit = float(vertical.axis_info[0].unit_conversion_factor) if vertical is not None and vertical.axis_info \
        else unit
    auth = c.to_authority(min_confidence=90)
    code = f"{auth[0]}:{auth[1]}" if auth else c.to_wkt()
    return CrsInfo(code, c.name, unit, v_unit, source, vertical.to_wkt() if vertical is not None else None)


@functools.lru_cache(maxsize=16)
def transformer(source: str, target: str):
    """A pyproj Transformer (always x/y order), made once per pair of CRSs: making one costs milliseconds, which
    a city of thousands of objects would pay for each."""
    from pyproj import Transformer

    return Transformer.from_crs(source, target, always_xy=True)


#: a CRS written as an EPSG code (``EPSG:28992``), not as WKT
_EPSG_CODE = __import__("re").compile(r"^EPSG:[0-9]+$", __import__("re").IGNORECASE)


@dataclass
class Georef:
    """Scene -> WGS84. Build with :func:`georef_from_options`, then :func:`scene_georef` once the scene is read.

    ``crs_unit_m`` / ``vertical_unit_m``: metres per CRS unit (scene coordinates are metric; pyproj gets scene
    coordinates divided by these)."""

    lat: float | None
    lon: float | None
    alt: float
    anchor: tuple[float, float]
    crs: str | None
    crs_unit_m: float = 1.0
    vertical_unit_m: float = 1.0
    crs_name: str | None = None
    crs_source: str | None = None
    vertical: object = None
    override: bool = False
    crs_code: str | None = None
    reference_code: str | None = None

    @property
    def heights(self):
        """The scan's vertical datum (:class:`~twinreg.geo.vertical.Vertical`; unknown when none was stated)."""
        return self.vertical if self.vertical is not None else UNKNOWN

    def to_json(self) -> dict:
        doc = {"lat": self.lat, "lon": self.lon, "alt": self.alt, "anchor": [float(a) for a in self.anchor],
               "crs": self.crs}
        if self.crs:
            doc.update(crs_name=self.crs_name, crs_source=self.crs_source, crs_unit_m=self.crs_unit_m,
                       vertical_unit_m=self.vertical_unit_m)
            if self.crs_code or self.reference_code:
                doc.update(crs_code=self.crs_code, reference_system=ogc_url(self.reference))
        return doc | self.heights.to_json()

    @property
    def reference(self) -> str | None:
        """The authority code of the CRS the files' coordinates and heights are in, as the formats name it: the
        compound code when the heights' datum is stated and registered (:meth:`identified`), else the horizontal
        CRS's code; a CRS given as an EPSG code when it was not identified; None for a local frame or a WKT without
        one.

        >>> g = Georef(None, None, 0.0, (0.0, 0.0), "EPSG:28992", crs_code="EPSG:28992", reference_code="EPSG:7415")
        >>> g.reference, Georef(None, None, 0.0, (0.0, 0.0), "EPSG:2157").reference
        ('EPSG:7415', 'EPSG:2157')
        """
        code = self.reference_code or self.crs_code
        if code is None and self.crs and _EPSG_CODE.match(self.crs):
            code = self.crs
        return code

    def to_crs_units(self, points) -> np.ndarray:
        """(n, 3) scene points (metres) in the CRS's own units (x, y divided by :attr:`crs_unit_m`, z by
        :attr:`vertical_unit_m`): the coordinates GIS tools expect in files that state the CRS; a local frame's
        metres are returned as they are.

        >>> Georef(None, None, 0.0, (0.0, 0.0), "EPSG:2994", 0.3048, 0.3048).to_crs_units([[0.3048, 0.6096, 3.048]])
        array([[ 1.,  2., 10.]])
        """
        pts = np.atleast_2d(np.asarray(points, dtype=np.float64))
        if not self.crs:
            return pts.copy()
        return pts / np.array([self.crs_unit_m, self.crs_unit_m, self.vertical_unit_m])

    def identified(self, lon: float, lat: float) -> "Georef":
        """This georeference with its CRS's authority code (a header's WKT often has none PROJ can name: it is
        looked for among the projected CRSs used at ``lon``, ``lat``) and the code of the CRS the heights are in
        (the compound CRS of the horizontal one and a stated vertical datum, when EPSG registers one: RD New +
        NAP is EPSG:7415)."""
        if not self.crs:
            return self
        code = authority_code(self.crs, round(lon, 2), round(lat, 2))
        reference = code
        v = self.heights
        if code and v.known and v.crs and ":" in v.crs and not _is_compound(self.crs):
            reference = compound_code(code, v.crs) or code
        return replace(self, crs_code=code, reference_code=reference)

    def with_crs(self, info: CrsInfo) -> "Georef":
        vertical = self.vertical
        if info.vertical is not None and (vertical is None or vertical.source != "--vertical-crs"):
            vertical = vertical_of(info.vertical, "file header" if info.source != "--crs" else "--crs",
                                   f"the CRS {info.name}")
        return replace(self, lat=None, lon=None, anchor=(0.0, 0.0), crs=info.crs, crs_unit_m=info.unit_m,
                       vertical_unit_m=info.vertical_unit_m, crs_name=info.name, crs_source=info.source,
                       vertical=vertical)

    def _ltp(self):
        to_ecef = transformer("EPSG:4979", "EPSG:4978")
        to_geo = transformer("EPSG:4978", "EPSG:4979")
        # --alt is the anchor's height in the scan's vertical datum
        alt = self.alt + float(self.heights.undulation(self.lon, self.lat)[0])
        x0, y0, z0 = to_ecef.transform(self.lon, self.lat, alt)

        return np.array([x0, y0, z0]), enu_axes(self.lat, self.lon), to_geo

    def to_wgs84(self, points) -> np.ndarray:
        """(n, 3) scene points -> (n, 3) longitude, latitude (degrees), ellipsoidal height (m): the scan's heights
        plus the geoid undulation of its vertical datum (:mod:`twinreg.geo.vertical`)."""
        pts = np.atleast_2d(np.asarray(points, dtype=np.float64))
        if self.crs:
            t = transformer(self.crs, "EPSG:4326")
            lon, lat = t.transform(pts[:, 0] / self.crs_unit_m, pts[:, 1] / self.crs_unit_m)
            return np.column_stack([lon, lat, pts[:, 2] + self.heights.undulation(lon, lat)])
        origin, enu, to_geo = self._ltp()
        local = np.column_stack([pts[:, 0] - self.anchor[0], pts[:, 1] - self.anchor[1], pts[:, 2]])
        ecef = origin + local @ enu.T
        lon, lat, h = to_geo.transform(ecef[:, 0], ecef[:, 1], ecef[:, 2])
        return np.column_stack([lon, lat, h])

    def centre_of(self, points) -> dict:
        """WGS84 latitude and longitude of the centre of (n, 3) scene points' bounding box (where a scan is)."""
        pts = np.atleast_2d(np.asarray(points, dtype=np.float64))
        lon, lat, _ = self.to_wgs84(((pts.min(0) + pts.max(0)) / 2)[None])[0]
        return {"lat": float(lat), "lon": float(lon)}

    def bearing(self, point, heading: float) -> float:
        """Degrees clockwise from true north of the scene direction ``heading`` (rad CCW from +X) at ``point``."""
        return float(self.placements(np.asarray(point, dtype=np.float64)[None, :3], np.array([heading]))[1][0])

    def placements(self, points, headings) -> tuple[np.ndarray, np.ndarray]:
        """For (n, 3) scene points and (n,) headings (rad): their (n, 3) WGS84 longitude, latitude, height and
        (n,) bearings (degrees clockwise from true north), in two vectorised transformations."""
        from pyproj import Geod

        p = np.atleast_2d(np.asarray(points, dtype=np.float64))[:, :3]
        h = np.asarray(headings, dtype=np.float64).ravel()
        ahead = p + np.column_stack([np.cos(h), np.sin(h), np.zeros(len(h))])
        both = self.to_wgs84(np.vstack([p, ahead]))
        a, b = both[:len(p)], both[len(p):]
        az, _, _ = Geod(ellps="WGS84").inv(a[:, 0], a[:, 1], b[:, 0], b[:, 1])
        return a, np.mod(np.asarray(az, dtype=np.float64), 360.0)


def georef_from_options(lat=None, lon=None, alt: float = 0.0, anchor=None, crs: str | None = None,
                        required: bool = True, vertical_crs: str | None = None,
                        override_crs: bool = False) -> Georef | None:
    """Validate the georeferencing options. Raises :class:`GeorefError` with the fix. With ``required`` False,
    no option at all gives None (the scene's own CRS is used once it is read: :func:`scene_georef`).
    ``vertical_crs``: the datum of the scan's heights (and of ``alt``), overriding a header's. ``override_crs``:
    ``crs`` replaces a CRS the file's header states (without it, a ``crs`` that differs from the header's is
    refused when the file is read)."""
    if override_crs and not crs:
        raise GeorefError("--override-crs says that --crs replaces the CRS the file's header states; give --crs "
                          "EPSG:NNNN with it")
    g = _georef_from_options(lat, lon, alt, anchor, crs, required and vertical_crs is None)
    if override_crs:
        g = replace(g, override=True)
    if vertical_crs is None:
        return g

    v = vertical_of(vertical_crs, "--vertical-crs", f"--vertical-crs {vertical_crs}")
    if g is None:  # the file's CRS, with these heights
        return Georef(None, None, float(alt or 0.0), (0.0, 0.0), None, vertical=v)
    return replace(g, vertical=v)


def _georef_from_options(lat, lon, alt, anchor, crs, required) -> Georef | None:
    for flag, value in (("--lat", lat), ("--lon", lon), ("--alt", alt)) + tuple(
            (f"--anchor {'XY'[k]}", v) for k, v in enumerate(anchor or ())):
        if value is not None and not (math.isfinite(float(value)) and abs(float(value)) < 1e8):
            raise GeorefError(f"{flag} {value}: not a finite number; give a position in degrees, metres or the "
                              "scene's units")
    if crs:
        if lat is not None or lon is not None:
            raise GeorefError("give either --crs or --lat/--lon, not both")
        info = crs_info(crs, "--crs", where=f"--crs {crs}")
        return Georef(None, None, float(alt or 0.0), (0.0, 0.0), None).with_crs(info)
    if lat is None and lon is None and not required:
        return None
    if lat is None or lon is None:
        raise GeorefError("georeference the scene with --lat and --lon (the scene origin's WGS84 position) or "
                          "--crs EPSG:NNNN")
    if not -90.0 < float(lat) < 90.0:
        raise GeorefError(f"--lat {lat} is out of range; a local east/north/up frame needs a latitude strictly "
                          "between -90 and 90 degrees (at a pole east is undefined)")
    if not -180.0 <= float(lon) <= 180.0:
        raise GeorefError(f"--lon {lon} is out of range; longitude is between -180 and 180 degrees")
    a = (0.0, 0.0) if anchor is None else (float(anchor[0]), float(anchor[1]))
    return Georef(float(lat), float(lon), float(alt or 0.0), a, None)


def scene_georef(georef: Georef | None, scene) -> Georef:
    """The georeference of a read scene (:class:`~twinreg.io.points.PointSet`): the options' when given (a
    ``--crs`` takes the units the reader resolved for it), else the CRS the file states, else an error naming the
    file and the fix."""
    info = getattr(scene, "crs_info", None)
    if georef is None or (georef.crs is None and georef.lat is None):  # nothing, or only --vertical-crs
        if info is None:
            raise GeorefError(f"{scene.path}: the file states no CRS; georeference it with --crs EPSG:NNNN (its "
                              "projected CRS) or --lat/--lon (the WGS84 position of its origin)")
        return (georef or Georef(None, None, 0.0, (0.0, 0.0), None)).with_crs(info)
    if georef.crs and info is not None:
        return georef.with_crs(info) if info.source == "--crs" else georef
    return georef


#: how far (degrees) a scan may reach beyond its CRS's area of use before it is refused: the areas are those of
#: the CRS's definition, and a survey may cross a zone's edge
AREA_MARGIN_DEG = 1.0


def check_area(georef: Georef, lo, hi, where: str, error=GeorefError) -> None:
    """Refuse a scan whose footprint ``lo``-``hi`` ((2,) or (3,) scene metres) falls outside the area of use of its
    CRS (by more than :data:`AREA_MARGIN_DEG`): a valid but wrong CRS would put it elsewhere on Earth. One line
    naming the CRS, its area and where the scan would land."""
    if not georef.crs:
        return
    from pyproj import CRS

    area = CRS.from_user_input(georef.crs).area_of_use
    if area is None:
        return
    lo, hi = np.asarray(lo, dtype=np.float64)[:2], np.asarray(hi, dtype=np.float64)[:2]
    corners = np.array([[lo[0], lo[1], 0.0], [hi[0], lo[1], 0.0], [lo[0], hi[1], 0.0], [hi[0], hi[1], 0.0],
                        [(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, 0.0]])
    with np.errstate(all="ignore"):
        ll = georef.to_wgs84(corners)
    m = AREA_MARGIN_DEG
    inside = (np.isfinite(ll[:, :2]).all(1) & (ll[:, 0] >= area.west - m) & (ll[:, 0] <= area.east + m)
              & (ll[:, 1] >= area.south - m) & (ll[:, 1] <= area.north + m))
    if inside.all():
        return
    lon, lat = ll[4, 0], ll[4, 1]
    there = (f"{abs(lat):.1f} {'N' if lat >= 0 else 'S'}, {abs(lon):.1f} {'E' if lon >= 0 else 'W'}"
             if np.isfinite(ll[4, :2]).all() else "nowhere on Earth")
    raise error(f"{where}: in {georef.crs_name or georef.crs} ({georef.crs}) the scan would lie at {there}, outside "
                f"the CRS's area of use ({area.name}: {area.south:.2f} to {area.north:.2f} N, {area.west:.2f} to "
                f"{area.east:.2f} E); give the CRS the coordinates are in (--crs EPSG:NNNN), or check --unit")


@functools.lru_cache(maxsize=32)
def authority_code(crs: str, lon: float | None = None, lat: float | None = None) -> str | None:
    """``EPSG:NNNN`` of a CRS given as a code or WKT: PROJ's own identification, else the projected CRS used at
    ``lon``, ``lat`` that equals it (a LAS header's WKT named after ESRI's names, Autzen's for one, has a code PROJ
    does not find by name); None when there is none."""
    from pyproj import CRS
    from pyproj.aoi import AreaOfInterest
    from pyproj.database import query_crs_info
    from pyproj.enums import PJType

    c = CRS.from_user_input(crs)
    auth = c.to_authority(min_confidence=70)
    if auth:
        return f"{auth[0]}:{auth[1]}"
    if lon is None or lat is None or c.is_compound:
        return None
    area = AreaOfInterest(lon - 0.01, lat - 0.01, lon + 0.01, lat + 0.01)
    for info in query_crs_info(auth_name="EPSG", pj_types=[PJType.PROJECTED_CRS], area_of_interest=area,
                               contains=False):
        if not info.deprecated and CRS.from_authority("EPSG", info.code).equals(c, ignore_axis_order=True):
            return f"EPSG:{info.code}"
    return None


@functools.lru_cache(maxsize=32)
def _is_compound(crs: str) -> bool:
    from pyproj import CRS

    return CRS.from_user_input(crs).is_compound


@functools.lru_cache(maxsize=32)
def compound_code(horizontal: str, vertical: str) -> str | None:
    """The registered code of the compound of two CRSs (``EPSG:28992`` and ``EPSG:5709`` give ``EPSG:7415``), or
    None when EPSG registers none."""
    from pyproj import CRS

    (h_auth, h_code), (v_auth, v_code) = horizontal.split(":", 1), vertical.split(":", 1)
    if h_auth != v_auth:
        return None
    auth = CRS.from_user_input(f"{h_auth}:{h_code}+{v_code}").to_authority(min_confidence=90)
    return f"{auth[0]}:{auth[1]}" if auth else None


def ogc_url(code: str | None) -> str | None:
    """The OGC URL of an authority code, as CityJSON and GeoPackage readers name a CRS.

    >>> ogc_url("EPSG:7415")
    'https://www.opengis.net/def/crs/EPSG/0/7415'
    """
    if not code or ":" not in code:
        return None
    auth, number = code.split(":", 1)
    return f"https://www.opengis.net/def/crs/{auth.upper()}/0/{number}"
