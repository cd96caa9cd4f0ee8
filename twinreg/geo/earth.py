"""The twin's local east-north-up frame on the WGS84 ellipsoid, for the 3D exports (3D Tiles, glTF).

Scene points (a projected CRS, or the ``--lat/--lon`` tangent plane) go to longitude, latitude and height by
:meth:`~twinreg.geo.georef.Georef.to_wgs84` (pyproj), then to ECEF and to east/north/up metres about the frame's
origin, exactly. Heights are ellipsoidal: the scan's heights plus the geoid undulation of its vertical datum
(:mod:`twinreg.geo.vertical`; none when the datum is unknown or ellipsoidal).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


def enu_axes(lat: float, lon: float) -> np.ndarray:
    """(3, 3) columns: the east, north and up unit vectors in ECEF at ``lat``, ``lon`` (degrees).

    >>> (np.round(enu_axes(0.0, 0.0), 6) + 0.0).tolist()  # at (0, 0): east is ECEF +Y, north +Z, up +X
    [[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]
    """
    la, lo = np.radians(lat), np.radians(lon)
    return np.array([[-np.sin(lo), -np.sin(la) * np.cos(lo), np.cos(la) * np.cos(lo)],
                     [np.cos(lo), -np.sin(la) * np.sin(lo), np.cos(la) * np.sin(lo)],
                     [0.0, np.cos(la), np.sin(la)]])


@dataclass(frozen=True)
class EnuFrame:
    """East/north/up metres about ``(lon, lat, h)`` (degrees, degrees, metres above the ellipsoid)."""

    lon: float
    lat: float
    h: float

    @classmethod
    def at(cls, georef, scene_point) -> "EnuFrame":
        lon, lat, h = georef.to_wgs84(np.asarray(scene_point, dtype=np.float64).reshape(1, 3))[0]
        return cls(float(lon), float(lat), float(h))

    @property
    def axes(self) -> np.ndarray:
        """(3, 3) columns: the east, north and up unit vectors in ECEF (:func:`enu_axes`)."""
        return enu_axes(self.lat, self.lon)

    @property
    def origin(self) -> np.ndarray:
        from .georef import transformer

        return np.array(transformer("EPSG:4979", "EPSG:4978").transform(self.lon, self.lat, self.h))

    def to_ecef_matrix(self) -> np.ndarray:
        """(4, 4) ENU -> ECEF (3D Tiles' root ``transform``, which is stored column-major)."""
        m = np.eye(4)
        m[:3, :3] = self.axes
        m[:3, 3] = self.origin
        return m

    def from_geodetic(self, lonlath) -> np.ndarray:
        """(n, 3) longitude, latitude (degrees), height (m) -> (n, 3) east, north, up (m)."""
        from .georef import transformer

        g = np.atleast_2d(np.asarray(lonlath, dtype=np.float64))
        x, y, z = transformer("EPSG:4979", "EPSG:4978").transform(g[:, 0], g[:, 1], g[:, 2])
        return (np.column_stack([x, y, z]) - self.origin) @ self.axes

    def to_geodetic(self, enu) -> np.ndarray:
        """(n, 3) east, north, up (m) -> (n, 3) longitude, latitude (degrees), height (m)."""
        from .georef import transformer

        ecef = self.origin + np.atleast_2d(np.asarray(enu, dtype=np.float64)) @ self.axes.T
        lon, lat, h = transformer("EPSG:4978", "EPSG:4979").transform(ecef[:, 0], ecef[:, 1], ecef[:, 2])
        return np.column_stack([lon, lat, h])

    def from_scene(self, georef, points) -> np.ndarray:
        """(n, 3) scene points -> (n, 3) east, north, up (m), exactly."""
        return self.from_geodetic(georef.to_wgs84(points))

    def affine_near(self, georef, centre, span: float = 50.0) -> tuple[np.ndarray, np.ndarray]:
        """``(A (3, 3), b (3,))`` with ``enu = (p - centre) @ A.T + b`` for scene points ``p`` near ``centre``
        (a cell of a few hundred metres: the map's scale and convergence are constant there to well under a
        millimetre), for converting millions of scan points at the cost of four."""
        c = np.asarray(centre, dtype=np.float64).reshape(3)
        probe = np.vstack([c, c + [span, 0, 0], c + [0, span, 0], c + [0, 0, span]])
        e = self.from_scene(georef, probe)
        return (e[1:] - e[0]).T / span, e[0]


def enu_angles(bearings_deg) -> np.ndarray:
    """Bearings (degrees clockwise from true north) -> angles (rad counter-clockwise from east)."""
    return np.radians(90.0 - np.asarray(bearings_deg, dtype=np.float64))
