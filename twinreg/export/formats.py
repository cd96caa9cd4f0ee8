"""The twin's open formats, written together by the per-scene pipeline and the city engine: 3D Tiles and
twin.glb (:mod:`.tiles3d`), CityJSON (:mod:`.cityjson`), GeoJSON (:mod:`.geojson`) and GeoPackage
(:mod:`.gpkg`)."""

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
    texts = start_text_formats(stage, outputs, offsets, georef, title, models, templates, seq)
    try:
        summary = write_tile_formats(stage, outputs, offsets, georef, groups, scans, models)
        texts.wait()
    finally:
        texts.stop()
    return summary


def _instances(outputs: list, offsets: list) -> list:
    return [instance_of(o, np.asarray(off)) for o, off in zip(outputs, offsets)]


def _light(outputs: list, models) -> dict:
    """The tiles' (and CityJSON's) lighter mesh of every model the objects show, by mesh key."""
    meshes = {o.mesh_key: (o.model_id, o.mesh[2]) for o in outputs if o.model_id is not None}
    return {key: (*models.light_mesh(model_id, TILE_MAX_TRIANGLES), rgb) for key, (model_id, rgb) in meshes.items()}


def write_tile_formats(stage: Path, outputs: list, offsets: list, georef, groups: list, scans: list | None,
                       models) -> dict:
    """3D Tiles and twin.glb (:func:`write_formats`' arguments); returns the tiles' summary."""
    meshes = {o.mesh_key: o.mesh for o in outputs if o.scale is None}
    return write_tiles(Path(stage), _instances(outputs, offsets), meshes, georef, groups, scans,
                       tile_meshes=_light(outputs, models))


def write_text_formats(stage: Path, instances: list, light: dict, docs: list, lonlat: list, georef, title: str,
                       templates: bool, seq: bool, outputs: list, rings=None) -> None:
    """The formats of the objects' records: twin.city.json (and twin.city.jsonl with ``seq``), twin.geojson (the
    footprints' ``lonlat``), sections.json and twin.gpkg (the footprints' ``rings`` in the CRS's units)."""
    from .gpkg import write_gpkg

    stage = Path(stage)
    write_cityjson(stage / "twin.city.json", instances, light, docs, [d["heading_rad"] for d in docs], georef,
                   title, templates, stage / "twin.city.jsonl" if seq else None)
    write_geojson(stage / "twin.geojson", docs, lonlat)
    write_sections(stage / "sections.json", outputs)
    write_gpkg(stage / "twin.gpkg", docs, lonlat if rings is None else rings, gpkg_crs(georef))


def gpkg_crs(georef) -> str | None:
    """The CRS of twin.gpkg's layer: the compound or horizontal code, else the CRS's WKT (None: WGS84)."""
    if not georef.crs:
        return None
    return georef.reference_code or georef.crs_code or georef.crs


class _Threaded:
    """The JSON formats written on a thread beside the tiles' numpy work (a scene's few objects)."""

    def __init__(self, *args):
        self._pool = ThreadPoolExecutor(1)
        self._future = self._pool.submit(write_text_formats, *args)

    def wait(self, timeout=None):
        return self._future.result()

    def stop(self):
        self._pool.shutdown(wait=True)


def start_text_formats(stage: Path, outputs: list, offsets: list, georef, title: str, models, templates: bool,
                       seq: bool, fork: bool = False):
    """Start :func:`write_text_formats` on a thread, or with ``fork`` in a forked child (a city's thousands of
    objects: JSON encoding holds Python's lock, so a thread shares one core with the caller); returns what to
    ``wait()`` for, and to ``stop()`` on every path (:class:`~twinreg.process.helpers.Forked`)."""
    docs = [o.doc for o in outputs]
    # pyproj's transformations and the catalogue's connection stay in this process and thread
    corners = [np.asarray(o.footprint["corners"]) + np.asarray(off)[:2] for o, off in zip(outputs, offsets)]
    ll = footprints_lonlat(corners, georef)
    rings = None
    if georef.crs and corners:
        flat = np.vstack(corners)
        rings = georef.to_crs_units(np.c_[flat, np.zeros(len(flat))])[:, :2]
    args = (Path(stage), _instances(outputs, offsets), _light(outputs, models), docs, ll, georef, title, templates,
            seq, outputs, rings)
    if not fork:
        return _Threaded(*args)
    from ..process.helpers import Forked

    return Forked(write_text_formats, *args)


def _polyline(a, n: int = 80) -> list:
    a = np.asarray(a, dtype=np.float64).reshape(-1, 2)
    a = a[np.linspace(0, len(a) - 1, min(n, len(a))).astype(int)] if len(a) else a
    return np.round(a, 3).tolist()


def write_sections(path: Path, outputs: list) -> Path:
    """``sections.json``: each object's longitudinal and transverse sections ((u, z) and (v, z), metres) and
    its model's, registered onto them, at most 80 points each (the viewer draws them on a click)."""
    import json

    # written an object at a time (the bytes ``json.dumps`` of the whole mapping gives; ids are unique), so that
    # memory does not grow with the objects (each object's polylines are some 600 Python floats)
    with open(path, "w", encoding="utf-8") as fh:
        fh.write("{")
        for n, o in enumerate(outputs):
            item = json.dumps(_section_item(o.sections), separators=(",", ":"))
            fh.write(("," if n else "") + json.dumps(o.doc["id"]) + ":" + item)
        fh.write("}")
    return Path(path)


def _section_item(s: dict) -> dict:
    """One object's entry of sections.json: its polylines and, when matched, its model's."""
    item = {"lon": _polyline(s["object"]["lon"]), "tra": _polyline(s["object"]["tra"])}
    if s.get("model"):
        item.update(model_lon=_polyline(s["model"]["lon"]), model_tra=_polyline(s["model"]["tra"]))
    return item
