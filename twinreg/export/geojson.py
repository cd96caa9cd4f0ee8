"""twin.geojson (RFC 7946): one Feature per object, its footprint as a WGS84 polygon (longitude, latitude; the
exterior ring counter-clockwise) with the object's attributes as properties, for QGIS and web maps.

Every feature has the same properties (:data:`PROPERTIES`, null where a value does not apply), so a GIS table has
one column each: ``kind`` (and its confidence, the object's ``type``, level of symmetry and the source of its
drawn shape), ``matched`` (a boolean to filter on), the catalogue model's fields under ``model*``
(``model`` its name), ``reason_code`` (one word of :data:`~twinreg.matching.match.REASON_CODES`) beside the
reason's text, and ``x``, ``y``, ``z``: the object's position in the scan's CRS and units. twin.gpkg carries the
same attributes (:mod:`.gpkg`)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

#: the properties of every feature, in order, with their types (str, int, float, bool)
PROPERTIES = (("id", str), ("kind", str), ("kind_confidence", float), ("type", int), ("symmetry_level", str),
              ("shape_source", str), ("matched", bool), ("model", str), ("model_id", int),
              ("model_make", str), ("model_designation", str), ("confidence", float), ("rmse_m", float),
              ("ambiguous_with", str), ("outside_tolerance", bool), ("reason_code", str), ("reason", str),
              ("rejected_model", str), ("cluster", int), ("n_points", int), ("x", float), ("y", float),
              ("z", float), ("lon", float), ("lat", float), ("bearing_deg", float), ("heading_rad", float),
              ("length", float), ("width", float), ("height", float), ("measured_length", float),
              ("measured_width", float), ("measured_height", float), ("symmetry_found", bool),
              ("symmetry_pcr", float))


def properties(doc: dict) -> dict:
    """An object's twin.json record as the GIS attributes of :data:`PROPERTIES` (every key, None where absent)."""
    m = doc.get("match") or {}
    size, measured, sym = doc.get("size") or {}, doc.get("measured_size") or {}, doc.get("symmetry") or {}
    xyz = doc.get("position_crs") or doc.get("centroid") or [None] * 3
    rejected = doc.get("rejected_model")
    values = {"id": doc.get("id"), "kind": doc.get("kind"), "kind_confidence": doc.get("kind_confidence"),
              "type": doc.get("type"), "symmetry_level": sym.get("level"),
              "shape_source": (doc.get("shape") or {}).get("source"), "matched": bool(m), "model": m.get("name"),
              "model_id": m.get("model_id"), "model_make": m.get("make"), "model_designation": m.get("model"),
              "confidence": m.get("confidence"), "rmse_m": m.get("rmse_m"),
              "ambiguous_with": ", ".join(m["ambiguous_with"]) if m.get("ambiguous_with") else None,
              "outside_tolerance": m.get("outside_tolerance") if m else None,
              "reason_code": doc.get("reason_code"), "reason": doc.get("reason"),
              "rejected_model": rejected.get("name") if isinstance(rejected, dict) else None,
              "cluster": doc.get("cluster"), "n_points": doc.get("n_points"), "x": xyz[0], "y": xyz[1], "z": xyz[2],
              "lon": doc.get("lon"), "lat": doc.get("lat"), "bearing_deg": doc.get("bearing_deg"),
              "heading_rad": doc.get("heading_rad"), "length": size.get("length"), "width": size.get("width"),
              "height": size.get("height"), "measured_length": measured.get("length"),
              "measured_width": measured.get("width"), "measured_height": measured.get("height"),
              "symmetry_found": sym.get("found"), "symmetry_pcr": sym.get("pcr")}
    return {k: values[k] for k, _ in PROPERTIES}


def footprints_lonlat(footprints: list[np.ndarray], georef) -> np.ndarray:
    """(4n, 2) WGS84 longitude, latitude of the objects' (4, 2) footprint corners (scene frame), in one call."""
    if not footprints:
        return np.zeros((0, 2))
    corners = np.vstack([np.c_[np.asarray(f)[:, :2], np.zeros(len(f))] for f in footprints])
    return georef.to_wgs84(corners)[:, :2]


def write_geojson(path, docs: list[dict], ll: np.ndarray) -> Path:
    """``docs``: the objects' twin.json records; ``ll``: their footprints' corners in WGS84, four rows each
    (:func:`footprints_lonlat`)."""
    # a feature at a time (the bytes ``json.dumps`` of the whole collection gives): memory stays flat in objects
    with open(path, "w", encoding="utf-8") as fh:
        fh.write('{"type": "FeatureCollection", "features": [')
        for k, doc in enumerate(docs):
            fh.write((", " if k else "") + json.dumps(_feature(doc, ll[4 * k:4 * k + 4])))
        fh.write("]}")
    return Path(path)


def _feature(doc: dict, ring: np.ndarray) -> dict:
    """One object's Feature: ``ring`` its footprint's four corners (WGS84)."""
    # counter-clockwise exterior ring (signed area > 0 in lon/lat), closed
    area = np.sum(ring[:, 0] * np.roll(ring[:, 1], -1) - np.roll(ring[:, 0], -1) * ring[:, 1])
    if area < 0:
        ring = ring[::-1]
    coords = [[round(float(x), 9), round(float(y), 9)] for x, y in ring]
    geometry = {"type": "Polygon", "coordinates": [coords + [coords[0]]]}
    return {"type": "Feature", "id": doc["id"], "geometry": geometry, "properties": properties(doc)}
