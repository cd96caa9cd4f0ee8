"""The twin's open formats, written together by the per-scene pipeline and the city engine: 3D Tiles and
twin.glb (:mod:`.tiles3d`), CityJSON (:mod:`.cityjson`), GeoJSON (:mod:`.geojson`) and GeoPackage
(:mod:`.gpkg`)."""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
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


@dataclass
class RecordView:
    """What the formats of the objects' records are written from: the placed objects (``outputs``, their
    ``docs``, tiles ``instances``, the models' ``light`` meshes), their footprints (``lonlat`` in WGS84, ``rings``
    in the CRS's units or None), the run's ``georef`` and ``title``, and the options (CityJSON ``templates``,
    CityJSONSeq ``seq``)."""

    stage: Path
    instances: list
    light: dict
    docs: list
    lonlat: np.ndarray
    georef: object
    title: str
    templates: bool
    seq: bool
    outputs: list
    rings: np.ndarray | None = None


def _cityjson(v: RecordView) -> None:
    write_cityjson(v.stage / "twin.city.json", v.instances, v.light, v.docs, [d["heading_rad"] for d in v.docs],
                   v.georef, v.title, v.templates, v.stage / "twin.city.jsonl" if v.seq else None)


def _geojson(v: RecordView) -> None:
    write_geojson(v.stage / "twin.geojson", v.docs, v.lonlat)


def _sections(v: RecordView) -> None:
    write_sections(v.stage / "sections.json", v.outputs)


def _gpkg(v: RecordView) -> None:
    from .gpkg import write_gpkg

    write_gpkg(v.stage / "twin.gpkg", v.docs, v.lonlat if v.rings is None else v.rings, gpkg_crs(v.georef))


#: the formats written from the objects' records, in order (a scene's on a thread, a city's in a forked child): a
#: new format of the records is its module and one line here
RECORD_FORMATS = (_cityjson, _geojson, _sections, _gpkg)


def write_text_formats(view: RecordView) -> None:
    """Every format of :data:`RECORD_FORMATS` from ``view``: twin.city.json (and twin.city.jsonl with ``seq``),
    twin.geojson, sections.json and twin.gpkg."""
    for write in RECORD_FORMATS:
        write(view)


def gpkg_crs(georef) -> str | None:
    """The CRS of twin.gpkg's layer: the compound or horizontal code, else the CRS's WKT (None: WGS84)."""
    if not georef.crs:
        return None
    return georef.reference or georef.crs


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
    view = RecordView(Path(stage), _instances(outputs, offsets), _light(outputs, models), docs, ll, georef, title,
                      templates, seq, outputs, rings)
    if not fork:
        return _Threaded(view)
    from ..process.helpers import Forked

    return Forked(write_text_formats, view)


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
