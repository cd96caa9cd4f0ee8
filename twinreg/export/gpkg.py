"""twin.gpkg: the objects' footprints as polygons in the scan's own CRS and units (a GeoPackage, for QGIS and any
GDAL reader: RD New or a state plane where the user works, not WGS84), with the attributes of twin.geojson
(:data:`~twinreg.export.geojson.PROPERTIES`), written with pyogrio (its bundled GDAL). The layer's CRS is the
compound one when the heights' datum is stated and EPSG registers the pair (RD New + NAP: 7415), else the
horizontal CRS; a twin placed by --lat/--lon has no projected CRS and its footprints are in WGS84 longitude and
latitude (EPSG:4326)."""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np

from .geojson import PROPERTIES, properties

LAYER = "objects"
#: the GeoPackage's names of the sizes: metres said in the name (x, y, z are in the CRS's unit, said by ``xyz_unit``)
METRE_FIELDS = ("length", "width", "height", "measured_length", "measured_width", "measured_height")


def unit_name(metres: float) -> str:
    """The name of a CRS's unit from its length in metres.

    >>> unit_name(1.0), unit_name(0.3048), unit_name(1200 / 3937)
    ('m', 'ft', 'US ft')
    """
    for name, m in (("m", 1.0), ("ft", 0.3048), ("US ft", 1200 / 3937)):
        if abs(metres - m) < 1e-9:
            return name
    return f"{metres:g} m"


def field_names() -> list[str]:
    """The GeoPackage's columns: twin.geojson's properties, sizes named with ``_m``, then ``xyz_unit``."""
    return [f"{n}_m" if n in METRE_FIELDS else n for n, _ in PROPERTIES] + ["xyz_unit"]


def polygon_wkb(ring: np.ndarray) -> bytes:
    """The WKB of a polygon from its (n, 2) exterior ring (closed here).

    >>> len(polygon_wkb(np.zeros((4, 2))))
    93
    """
    r = np.asarray(ring, dtype="<f8").reshape(-1, 2)
    r = np.vstack([r, r[:1]])
    return struct.pack("<BIII", 1, 3, 1, len(r)) + r.tobytes()


def _column(values: list, kind) -> tuple[np.ndarray, np.ndarray | None]:
    """One field's array and its mask of nulls (None: no null)."""
    missing = np.array([v is None for v in values], dtype=bool)
    if kind is str:
        return np.array(["" if v is None else str(v) for v in values], dtype=object), missing if missing.any() else None
    dtype = {int: np.int64, float: np.float64, bool: np.bool_}[kind]
    filled = np.array([0 if v is None else v for v in values], dtype=dtype)
    return filled, missing if missing.any() else None


def write_gpkg(path, docs: list[dict], rings: np.ndarray, crs: str | None, xyz_unit: str = "m") -> Path:
    """``docs``: the objects' twin.json records; ``rings``: their footprints, four (x, y) corners each ((4n, 2), in
    ``crs``'s units); ``crs``: an authority code or WKT (None: WGS84 longitude, latitude); ``xyz_unit``: the unit
    of the objects' x, y, z (the CRS's: :func:`unit_name`), a column and the layer's description say it."""
    from pyogrio.raw import write

    rings = np.asarray(rings, dtype=np.float64).reshape(-1, 4, 2)
    geometry = np.array([polygon_wkb(r) for r in rings], dtype=object)
    rows = [properties(d) for d in docs]
    data, masks = [], []
    for name, kind in [*PROPERTIES, ("xyz_unit", str)]:
        col, mask = _column([r.get(name, xyz_unit) for r in rows], kind)
        data.append(col)
        masks.append(mask)
    description = (f"twinreg objects: footprints and x, y, z in the CRS's unit ({xyz_unit}), sizes in metres (_m), "
                   "lat/lon in degrees, angles bearing_deg in degrees and heading_rad in radians")
    write(str(path), geometry, data, field_names(), field_mask=masks, layer=LAYER,
          driver="GPKG", geometry_type="Polygon", crs=crs or "EPSG:4326", layer_options={"DESCRIPTION": description})
    return Path(path)
