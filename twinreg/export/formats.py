"""The twin's open formats, written together by the per-scene pipeline and the city engine: 3D Tiles and
twin.glb (:mod:`.tiles3d`), CityJSON (:mod:`.cityjson`) and GeoJSON (:mod:`.geojson`)."""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

from .cityjson import write_cityjson
from .geojson import footprints_lonlat, write_geojson
from .tiles3d import TILE_MAX_TRIANGLES, instance_of, write_tiles


def write_formats(stage: Path, outputs: list, offsets: list, georef, groups: list, scans: list | None,
                  title: str, models, templates: bool = False, seq: bool = False) -> dict:
    """``outputs``: the objects' :class:`~twinreg.export.objects.ObjectOutput`; ``offsets``: (3,) each, from
    its local frame to the scene frame; ``groups``: (tile name, indices into outputs); ``scans``: (tile name,
    (n, 3) scene points, (n, 3) uint8 colours), or None; ``models``: the matcher's
    :class:`~twinreg.matching.match.ModelCache` (the tiles' lighter meshes); ``templates``: CityJSON with geometry
    templates; ``seq``: also twin.city.jsonl (CityJSONSeq). Returns the tiles' summary."""
    stage = Path(stage)
    instances = [instance_of(o, np.asarray(off)) for o, off in zip(outputs, offsets)]
    meshes = {o.mesh_key: o.mesh for o in outputs if o.scale is None}
    light = {key: (*models.light_mesh(int(key[len("model"):]), TILE_MAX_TRIANGLES), rgb)
             for key, (_, _, rgb) in meshes.items()}

    docs = [o.doc for o in outputs]
    # pyproj's transformations stay in this thread (its objects are not shared between threads)
    ll = footprints_lonlat([np.asarray(o.footprint["corners"]) + np.asarray(off)[:2]
                            for o, off in zip(outputs, offsets)], georef)
    with ThreadPoolExecutor(2) as pool:  # JSON encoding beside the tiles' numpy work
        side = [pool.submit(write_cityjson, stage / "twin.city.json", instances, light, docs,
                            [d["heading_rad"] for d in docs], georef, title, templates,
                            stage / "twin.city.jsonl" if seq else None),
                pool.submit(write_geojson, stage / "twin.geojson", docs, ll)]
        summary = write_tiles(stage, instances, meshes, georef, groups, scans, tile_meshes=light)
        write_sections(stage / "sections.json", outputs)
        for f in side:
            f.result()
    return summary


def _polyline(a, n: int = 80) -> list:
    a = np.asarray(a, dtype=np.float64).reshape(-1, 2)
    a = a[np.linspace(0, len(a) - 1, min(n, len(a))).astype(int)] if len(a) else a
    return np.round(a, 3).tolist()


def write_sections(path: Path, outputs: list) -> Path:
    """``sections.json``: each object's longitudinal and transverse sections ((u, z) and (v, z), metres) and
    its model's, registered onto them, at most 80 points each (the viewer draws them on a click)."""
    import json

    doc = {}
    for o in outputs:
        s = o.sections
        item = {"lon": _polyline(s["object"]["lon"]), "tra": _polyline(s["object"]["tra"])}
        if s.get("model"):
            item.update(model_lon=_polyline(s["model"]["lon"]), model_tra=_polyline(s["model"]["tra"]))
        doc[o.doc["id"]] = item
    Path(path).write_text(json.dumps(doc, separators=(",", ":")), encoding="utf-8")
    return Path(path)
