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


def write_geojson(path, docs: list[dict], footprints: list[np.ndarray], georef) -> Path:
    """``docs``: the objects' twin.json records; ``footprints``: each one's (4, 2) footprint corners in the scene
    frame (x, y) with its ground height as a third column or not."""
    feats = []
    if docs:
        corners = np.vstack([np.c_[np.asarray(f)[:, :2], np.zeros(len(f))] for f in footprints])
        ll = georef.to_wgs84(corners)[:, :2]
    for k, doc in enumerate(docs):
        ring = ll[4 * k:4 * k + 4]
        # counter-clockwise exterior ring (signed area > 0 in lon/lat), closed
        area = np.sum(ring[:, 0] * np.roll(ring[:, 1], -1) - np.roll(ring[:, 0], -1) * ring[:, 1])
        if area < 0:
            ring = ring[::-1]
        coords = [[round(float(x), 9), round(float(y), 9)] for x, y in ring]
        feats.append({"type": "Feature", "id": doc["id"],
                      "geometry": {"type": "Polygon", "coordinates": [coords + [coords[0]]]},
                      "properties": _flat(doc)})
    Path(path).write_text(json.dumps({"type": "FeatureCollection", "features": feats}), encoding="utf-8")
    return Path(path)
