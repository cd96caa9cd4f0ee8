"""twin.city.json (CityJSON 2.0): one ``CityFurniture`` (function: vehicle) per object, drawn by a
``GeometryInstance`` of a geometry template (one template per catalogue model, the tiles' mesh of at most
2,000 triangles, plus a unit box for objects with no model), with the object's twin.json record as attributes.

Coordinates are in the scene's CRS and its units (``metadata.referenceSystem``); a template is the model's mesh
in metres (Z up, front +X, footprint centred, lowest point at 0) and each instance's ``transformationMatrix``
(4 x 4, row-major as CityJSON says) turns, scales (boxes) and converts it to CRS units; the instance's one
boundary vertex is the reference point it is then moved to.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from .geojson import _flat

#: CityJSON integer coordinates: millimetres
SCALE = 0.001


def _reference_system(crs: str | None) -> str | None:
    if crs and crs.upper().startswith("EPSG:"):
        return f"https://www.opengis.net/def/crs/EPSG/0/{crs.split(':', 1)[1]}"
    return None


def write_cityjson(path, instances: list, meshes: dict, docs: list[dict], headings: list[float], georef,
                   title: str) -> Path:
    """``instances``: :class:`~twinreg.export.tiles3d.Instance` (scene-frame origins); ``headings``: each one's
    turn (rad, counter-clockwise from the scene's +X) of the mesh's +X; ``docs``: the twin.json records."""
    from .tiles3d import UNIT_BOX

    unit = georef.crs_unit_m if georef.crs else 1.0
    vunit = georef.vertical_unit_m if georef.crs else 1.0
    to_crs = np.diag([1.0 / unit, 1.0 / unit, 1.0 / vunit])
    keys = sorted({i.mesh for i in instances})
    templates, tverts = [], []
    index = {}
    for key in keys:
        v, f = (UNIT_BOX if key == "box" else meshes[key][:2])
        base = sum(len(t) for t in tverts)
        tverts.append(np.round(np.asarray(v, dtype=np.float64), 4))
        faces = (np.asarray(f, dtype=np.int64) + base).reshape(-1, 1, 3)
        templates.append({"type": "MultiSurface", "lod": "2", "boundaries": faces.tolist()})
        index[key] = len(templates) - 1
    ref = np.array([i.origin for i in instances], dtype=np.float64).reshape(-1, 3) @ to_crs
    translate = np.floor(ref.min(0)) if len(ref) else np.zeros(3)
    ints = np.rint((ref - translate) / SCALE).astype(np.int64)
    objects = {}
    for k, (inst, doc, a) in enumerate(zip(instances, docs, headings)):
        c, s = np.cos(a), np.sin(a)
        m = np.eye(4)
        m[:3, :3] = to_crs @ np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]) @ np.diag(inst.scale or (1, 1, 1))
        attrs = {"function": "vehicle", **{k2: v for k2, v in _flat(doc).items() if v is not None and k2 != "id"}}
        objects[doc["id"]] = {"type": "CityFurniture", "attributes": attrs,
                              "geometry": [{"type": "GeometryInstance", "template": index[inst.mesh],
                                            "boundaries": [k],
                                            "transformationMatrix": [float(x) for x in m.ravel()]}]}
    doc = {"type": "CityJSON", "version": "2.0",
           "transform": {"scale": [SCALE, SCALE, SCALE], "translate": [float(t) for t in translate]},
           "metadata": {"title": title},
           "CityObjects": objects,
           "vertices": ints.tolist(),
           "geometry-templates": {"templates": templates,
                                  "vertices-templates": np.vstack(tverts).tolist() if tverts else []}}
    rs = _reference_system(georef.crs)
    if rs:
        doc["metadata"]["referenceSystem"] = rs
    if len(ref):
        hi = ref.max(0)
        doc["metadata"]["geographicalExtent"] = [float(v) for v in (*translate, *hi)]
    Path(path).write_text(json.dumps(doc, separators=(",", ":")), encoding="utf-8")
    return Path(path)
