"""Georeferencing scene coordinates with pyproj.

Two ways, as in the contract:

- ``--lat/--lon [--alt] [--anchor X Y]``: the scene is a local east/north/up tangent plane whose point (X, Y, 0)
  sits at (lat, lon, alt) on the WGS84 ellipsoid. Scene points go east/north/up -> ECEF -> geodetic, exactly.
- ``--crs EPSG:NNNN``: the scene coordinates are in that projected CRS; every point is converted by pyproj.

Headings: a scene direction (rad, counter-clockwise from +X) becomes a bearing (degrees clockwise from true north)
by converting the point and a point one metre ahead and taking the geodesic azimuth between them, so grid
convergence is accounted for.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .errors import GeorefError


@dataclass
class Georef:
    """Scene -> WGS84. Build with :func:`georef_from_options`."""

    lat: float | None
    lon: float | None
    alt: float
    anchor: tuple[float, float]
    crs: str | None

    def to_json(self) -> dict:
        return {"lat": self.lat, "lon": self.lon, "alt": self.alt, "anchor": [float(a) for a in self.anchor],
                "crs": self.crs}

    def _ltp(self):
        from pyproj import Transformer

        to_ecef = Transformer.from_crs("EPSG:4979", "EPSG:4978", always_xy=True)
        to_geo = Transformer.from_crs("EPSG:4978", "EPSG:4979", always_xy=True)
        x0, y0, z0 = to_ecef.transform(self.lon, self.lat, self.alt)
        la, lo = np.radians(self.lat), np.radians(self.lon)
        # columns: east, north, up unit vectors in ECEF
        enu = np.array([[-np.sin(lo), -np.sin(la) * np.cos(lo), np.cos(la) * np.cos(lo)],
                        [np.cos(lo), -np.sin(la) * np.sin(lo), np.cos(la) * np.sin(lo)],
                        [0.0, np.cos(la), np.sin(la)]])
        return np.array([x0, y0, z0]), enu, to_geo

    def to_wgs84(self, points) -> np.ndarray:
        """(n, 3) scene points -> (n, 3) longitude, latitude (degrees), ellipsoidal height (m)."""
        pts = np.atleast_2d(np.asarray(points, dtype=np.float64))
        if self.crs:
            from pyproj import Transformer

            t = Transformer.from_crs(self.crs, "EPSG:4326", always_xy=True)
            lon, lat = t.transform(pts[:, 0], pts[:, 1])
            return np.column_stack([lon, lat, pts[:, 2]])
        origin, enu, to_geo = self._ltp()
        local = np.column_stack([pts[:, 0] - self.anchor[0], pts[:, 1] - self.anchor[1], pts[:, 2]])
        ecef = origin + local @ enu.T
        lon, lat, h = to_geo.transform(ecef[:, 0], ecef[:, 1], ecef[:, 2])
        return np.column_stack([lon, lat, h])

    def bearing(self, point, heading: float) -> float:
        """Degrees clockwise from true north of the scene direction ``heading`` (rad CCW from +X) at ``point``."""
        from pyproj import Geod

        p = np.asarray(point, dtype=np.float64)[:3]
        ahead = p + np.array([np.cos(heading), np.sin(heading), 0.0])
        a, b = self.to_wgs84(np.vstack([p, ahead]))
        az, _, _ = Geod(ellps="WGS84").inv(a[0], a[1], b[0], b[1])
        return float(np.mod(az, 360.0))


def georef_from_options(lat=None, lon=None, alt: float = 0.0, anchor=None, crs: str | None = None) -> Georef:
    """Validate the georeferencing options. Raises :class:`GeorefError` with the fix."""
    if crs:
        if lat is not None or lon is not None:
            raise GeorefError("give either --crs or --lat/--lon, not both")
        from pyproj import CRS
        from pyproj.exceptions import CRSError

        try:
            c = CRS.from_user_input(crs)
        except CRSError as exc:
            raise GeorefError(f"--crs {crs}: not a CRS pyproj knows ({exc}); e.g. --crs EPSG:2157") from exc
        if not c.is_projected:
            raise GeorefError(f"--crs {crs}: not a projected CRS; scene coordinates must be metres east/north")
        return Georef(None, None, float(alt or 0.0), (0.0, 0.0), crs)
    if lat is None or lon is None:
        raise GeorefError("georeference the scene with --lat and --lon (the scene origin's WGS84 position) or "
                          "--crs EPSG:NNNN")
    if not -90.0 <= float(lat) <= 90.0:
        raise GeorefError(f"--lat {lat} is out of range; latitude is between -90 and 90 degrees")
    if not -180.0 <= float(lon) <= 180.0:
        raise GeorefError(f"--lon {lon} is out of range; longitude is between -180 and 180 degrees")
    a = (0.0, 0.0) if anchor is None else (float(anchor[0]), float(anchor[1]))
    return Georef(float(lat), float(lon), float(alt or 0.0), a, None)
