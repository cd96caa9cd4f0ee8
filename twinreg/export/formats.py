"""The twin's files, written by one writer for a scene and a city (:func:`write_twin`) from the placed objects
(:class:`~twinreg.export.objects.PlacedObject`): each format is its module and one line in a table. In this
process (:data:`TWIN_FORMATS`): twin.kmz (:mod:`.kmz`; on a helper process when one is given), twin.ply
(:mod:`.twin_ply`), 3D Tiles and twin.glb (:mod:`.tiles3d`). From the objects' records, on a thread or in a forked
child (:data:`RECORD_FORMATS`): CityJSON (:mod:`.cityjson`), GeoJSON (:mod:`.geojson`), sections.json
(:mod:`.sections`) and GeoPackage (:mod:`.gpkg`)."""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..io.ply import write_ply
from ..process.helpers import Forked, Pending
from .cityjson import write_cityjson
from .geojson import footprints_lonlat, write_geojson
from .gpkg import unit_name, write_gpkg
from .kmz import placemark_fields, write_kmz
from .sections import write_sections
from .tiles3d import TILE_MAX_TRIANGLES, instance_of, write_tiles
from .twin_ply import write_prj, write_twin_ply

#: how long the record formats may take in a forked child before this process writes them itself (s, and s an
#: object: about 2 ms an object is usual)
RECORD_FORMATS_S = 60.0
RECORD_FORMATS_S_PER_OBJECT = 0.02


@dataclass
class TwinFiles:
    """What the twin's files are written from, and how. ``stage``: the folder; ``scene``: the scan's name (the
    files' titles); ``placed``: the :class:`~twinreg.export.objects.PlacedObject` of every object; ``georef``;
    ``models``: the matcher's :class:`~twinreg.matching.match.ModelCache` (the tiles' lighter meshes);
    ``groups``: (name, indices into ``placed``) of the tiles' groups (a scene's one, a city's cells); ``scans``:
    each group's scan sample (name, (n, 3) scene points, (n, 3) uint8 colours, or the name and a cell's written
    tiles), or None; ``ply``: None, ``"twin"`` (twin.ply and twin.prj) or ``"groups"`` (``ply/<group>.ply``);
    ``regions``: group name -> WGS84 bounds for a KMZ with a Folder and Region a group (None: one list);
    ``templates``: CityJSON with geometry templates; ``seq``: also twin.city.jsonl; ``fork``: the record formats
    in a forked child instead of a thread (faster where JSON encoding is a large share of the export, but the
    child copies the pages of the records it reads: a city writes them on a thread); ``helper``: the helper
    process that writes the KMZ (None: this one)."""

    stage: Path
    scene: str
    placed: list  # PlacedObject each
    georef: object  # the scene's Georef
    models: object  # ModelCache
    groups: list  # (name, indices)
    scans: list | None = None  # each group's sample
    ply: str | None = None  # None, "twin" or "groups"
    regions: dict | None = None  # name -> WGS84 bounds
    templates: bool = False
    seq: bool = False
    fork: bool = False
    helper: object = None

    @property
    def title(self) -> str:
        return f"twinreg: {self.scene}"


def _kmz(f: TwinFiles):
    meshes: dict = {}
    for p in f.placed:
        meshes.setdefault(p.mesh_key, p.mesh)
    folders = None
    if f.regions is not None:
        folders = [{"name": name, "bounds": f.regions[name], "ids": [f.placed[k].id for k in rows]}
                   for name, rows in f.groups if rows]
    return Pending(f.helper, write_kmz, f.stage / "twin.kmz", f.title, [placemark_fields(p) for p in f.placed],
                   meshes, folders)


def _ply_parts(placed: list) -> tuple[list, np.ndarray]:
    """(placed vertices, faces, label) of each object, in the first object's frame, and that frame's offset."""
    base = np.asarray(placed[0].offset)
    parts = []
    for p in placed:
        v = p.placed
        if np.any(p.offset != base):
            v = v + (p.offset - base)
        parts.append((v, p.faces, int(p.label)))
    return parts, base


def _ply(f: TwinFiles):
    if f.ply == "twin" and f.placed:
        parts, base = _ply_parts(f.placed)
        write_twin_ply(f.stage / "twin.ply", parts, base, f.georef, f.scene)
        write_prj(f.stage / "twin.prj", f.georef)
    elif f.ply == "groups":
        for name, rows in f.groups:
            if rows:
                parts, base = _ply_parts([f.placed[k] for k in rows])
                write_twin_ply(f.stage / "ply" / f"{name}.ply", parts, base, f.georef, f"{f.scene}, cell {name}")
    return None


def _tiles(f: TwinFiles):
    meshes = {p.mesh_key: p.mesh for p in f.placed if p.scale is None}
    return {"tiles": write_tiles(Path(f.stage), _instances(f.placed), meshes, f.georef, f.groups, f.scans,
                                 tile_meshes=_light(f.placed, f.models))}


def _shapes(f: TwinFiles):
    """Each fused shape as ``shapes/type_<T>.ply`` (the type's frame: metres, front +X, the ground at z = 0; what
    ``add-model --from-twin`` promotes), and twin.json's ``shapes``: per type its kind, members, quality, file."""
    seen: dict = {}
    for p in f.placed:
        if p.shape_source == "fused":
            seen.setdefault(p.type, []).append(p)
    if seen:
        (f.stage / "shapes").mkdir(exist_ok=True)
    out = []
    for t, ps in sorted(seen.items()):
        name = f"shapes/type_{t}.ply"
        write_ply(f.stage / name, ps[0].mesh[0], ps[0].mesh[1],
                  comments=[f"twinreg: the fused shape of type {t} of {f.scene[:80]}, {len(ps)} members",
                            "metres; front +X; the ground at z = 0"])
        kind = ps[0].kind.kind if ps[0].kind is not None else None
        out.append({"type": int(t), "kind": kind, "members": [p.id for p in ps], "quality": ps[0].shape_quality
                    and {k: v for k, v in ps[0].shape_quality.items() if k != "rmse_m"}, "file": name})
    return {"shapes": out} if out else None


#: the formats written in this process, in order, each ``(files) -> None``, a dict of twin.json's entries, or a
#: job to ``wait()`` for (the KMZ on a helper): a new format is its module and one line here
TWIN_FORMATS = (_kmz, _ply, _tiles, _shapes)


def write_twin(f: TwinFiles, beside=None) -> dict:
    """Every file of the twin but twin.json, the report and the scan's: :data:`RECORD_FORMATS` on a thread (or
    in a forked child) beside :data:`TWIN_FORMATS` here, then ``beside()`` (the caller's own files) while the
    records' formats finish. Returns twin.json's entries the formats give (the tiles' summary), then those
    ``beside()`` returns as a dict."""
    texts = start_text_formats(f)
    entries: dict = {}
    try:
        jobs = []
        for write in TWIN_FORMATS:
            got = write(f)
            if isinstance(got, dict):
                entries |= got
            elif got is not None:
                jobs.append(got)
        if beside is not None and isinstance(got := beside(), dict):
            entries |= got
        for job in jobs:
            job.wait()
        texts.wait(timeout=RECORD_FORMATS_S + RECORD_FORMATS_S_PER_OBJECT * len(f.placed))
    finally:
        texts.stop()
    return entries


def _instances(placed: list) -> list:
    return [instance_of(p) for p in placed]


def _light(placed: list, models) -> dict:
    """The tiles' (and CityJSON's) lighter mesh of every model the objects show, by mesh key; a fused shape's own
    (already decimated)."""
    meshes = {p.mesh_key: (p.model_id, p.mesh[2]) for p in placed if p.model_id is not None}
    out = {key: (*models.light_mesh(model_id, TILE_MAX_TRIANGLES), rgb) for key, (model_id, rgb) in meshes.items()}
    return out | {p.mesh_key: p.mesh for p in placed if p.shape_source in ("fused", "generic")}


@dataclass
class RecordView:
    """What the formats of the objects' records are written from: the placed objects (``placed``, their
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
    placed: list
    rings: np.ndarray | None = None


def _cityjson(v: RecordView) -> None:
    write_cityjson(v.stage / "twin.city.json", v.instances, v.light, v.docs, [d["heading_rad"] for d in v.docs],
                   v.georef, v.title, v.templates, v.stage / "twin.city.jsonl" if v.seq else None)


def _geojson(v: RecordView) -> None:
    write_geojson(v.stage / "twin.geojson", v.docs, v.lonlat)


def _sections(v: RecordView) -> None:
    write_sections(v.stage / "sections.json", v.placed)


def _gpkg(v: RecordView) -> None:
    crs = gpkg_crs(v.georef)
    write_gpkg(v.stage / "twin.gpkg", v.docs, v.lonlat if v.rings is None else v.rings, crs,
               unit_name(v.georef.crs_unit_m if crs is not None else 1.0))


#: the formats written from the objects' records, in order (on a thread, or in a forked child with ``fork``): a
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
    """The JSON formats written on a thread beside the tiles' numpy work (a scene's, a city's)."""

    def __init__(self, *args):
        self._pool = ThreadPoolExecutor(1)
        self._future = self._pool.submit(write_text_formats, *args)

    def wait(self, timeout=None):
        return self._future.result()

    def stop(self):
        self._pool.shutdown(wait=True)


def record_view(f: TwinFiles) -> RecordView:
    """The :class:`RecordView` of ``f``'s objects (their footprints transformed here: pyproj's transformations
    and the catalogue's connection stay in this process and thread)."""
    corners = [np.asarray(p.footprint()["corners"]) + p.offset[:2] for p in f.placed]
    ll = footprints_lonlat(corners, f.georef)
    rings = None
    if f.georef.crs and corners:
        flat = np.vstack(corners)
        rings = f.georef.to_crs_units(np.c_[flat, np.zeros(len(flat))])[:, :2]
    return RecordView(Path(f.stage), _instances(f.placed), _light(f.placed, f.models), [p.doc for p in f.placed],
                      ll, f.georef, f.title, f.templates, f.seq, f.placed, rings)


def start_text_formats(f: TwinFiles):
    """Start :func:`write_text_formats` on a thread, or with ``f.fork`` in a forked child (JSON encoding holds
    Python's lock, so a thread shares one core with the caller); returns what to ``wait()`` for, and to
    ``stop()`` on every path (:class:`~twinreg.process.helpers.Forked`)."""
    view = record_view(f)
    return Forked(write_text_formats, view) if f.fork else _Threaded(view)
