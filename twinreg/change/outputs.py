"""changes.geojson: every change as WGS84 footprints (before and after, one feature each) with its status and
attributes, so that a GIS styles the map by status."""

from __future__ import annotations

import json

import numpy as np

from .footprints import record_corners

_KEYS = ("status", "confidence", "from", "to", "displacement_m", "turn_rad", "reason")


def _rings(epoch, objs: list[dict]) -> list:
    if not objs:
        return []
    z = np.array([o["centroid"][2] for o in objs], dtype=np.float64)
    flat = np.column_stack([record_corners(objs).reshape(-1, 2), np.repeat(z, 4)])
    ll = epoch.georef.to_wgs84(flat)[:, :2].reshape(-1, 4, 2)
    return [[[round(float(x), 8), round(float(y), 8)] for x, y in np.vstack([q, q[:1]])] for q in ll]


def write_geojson(path, doc: dict, epochs) -> None:
    """Write changes.geojson (RFC 7946: WGS84 longitude, latitude)."""
    features = []
    for phase in ("before", "after"):
        for k in range(len(epochs)):
            side = k if phase == "before" else k  # the epoch whose twin holds this footprint
            items = [c for c in doc["changes"] if c[phase] is not None and
                     (c["from"] if phase == "before" else c["to"]) == side]
            for c, ring in zip(items, _rings(epochs[side], [c[phase] for c in items])):
                o = c[phase]
                props = {key: c[key] for key in _KEYS} | {
                    "phase": phase, "epoch": side, "date": epochs[side].date, "id": o["id"], "model": o["model"],
                    "from_date": epochs[c["from"]].date, "to_date": epochs[c["to"]].date}
                features.append({"type": "Feature", "geometry": {"type": "Polygon", "coordinates": [ring]},
                                 "properties": props})
    path.write_text(json.dumps({"type": "FeatureCollection", "name": "twinreg changes", "features": features}),
                    encoding="utf-8")
