"""twin.geojson (RFC 7946): one Feature per object, its footprint as a WGS84 polygon (longitude, latitude; the
exterior ring counter-clockwise) with the object's twin.json record as properties, for QGIS and web maps."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

#: twin.json keys left out of the properties (large or nested beyond what GIS tables show)
SKIP = {"centroid", "symmetry"}


def _flat(doc: dict) -> dict:
    """Properties: the record's scalars, with ``size``/``measured_size``/``match`` flattened to one level."""
    props = {}
    for k, v in doc.items():
        if k in SKIP:
            continue
        if isinstance(v, dict):
            for kk, vv in v.items():
                if not isinstance(vv, (dict, list)):
                    props[f"{k}_{kk}"] = vv
        elif v is None and k == "match":
            props["model"] = None
        elif not isinstance(v, list):
            props[k] = v
    if doc.get("match"):
        props["model"] = doc["match"]["name"]
    return props


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
    return {"type": "Feature", "id": doc["id"], "geometry": geometry, "properties": _flat(doc)}
