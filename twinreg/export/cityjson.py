"""twin.city.json (CityJSON 2.0): one city object per object, of its kind's type (:func:`city_type`: a
``CityFurniture`` of function vehicle for a car), with the object's twin.json
record as attributes, drawn by its catalogue model's mesh (the tiles' mesh of at most 2,000 triangles) or a box of
its measured size when it has no model. For city runs also ``twin.city.jsonl``, the same objects as CityJSONSeq
(CityJSON Text Sequences: a first line with the transform and metadata, then one ``CityJSONFeature`` a line, each
with its own vertices), which cjio and the streaming tools read a feature at a time.

Geometry is explicit by default (one ``MultiSurface`` per object, its vertices placed in the file's vertex list):
the web viewer ninja, the three.js CityJSON loader and older cjio cannot draw geometry templates, and explicit
geometry opens everywhere. With ``templates`` (``build-twin --cityjson-templates``) each model is one geometry
template (a unit box for objects with no model) and each object a ``GeometryInstance`` of it: a much smaller file
for the tools that read templates. A city run's twin.city.json always has templates (explicit geometry is 69 kB a
car: 500 MB for a city of 5,200), and its CityJSONSeq the explicit geometry, a feature a line.

Coordinates are in the scene's CRS and its units (``metadata.referenceSystem``); a template is the model's mesh in
metres (Z up, front +X, footprint centred, lowest point at 0) and each instance's ``transformationMatrix`` (4 x 4,
row-major as CityJSON says) turns, scales (boxes) and converts it to CRS units; the instance's one boundary vertex
is the reference point it is then moved to. Explicit geometry is that placement applied, rounded to the file's
integers (0.1 mm).
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from cosco.frames import yaw
from cosco.kernels import fast, kernel

from ..geo.georef import ogc_url
from .geojson import properties
from .tiles3d import UNIT_BOX

#: CityJSON integer coordinates: tenths of a millimetre (explicit geometry and a template placed by its matrix
#: then agree within 0.2 mm)
SCALE = 0.0001


def _reference_system(georef) -> str | None:
    """The OGC URL of the CRS the file's coordinates are in: the compound CRS when the heights' datum is stated
    and EPSG registers the pair (RD New + NAP: 7415), else the horizontal CRS (its code identified from a WKT)."""
    return ogc_url(georef.reference)


def _extent(p: "_Placed") -> list[float]:
    """``geographicalExtent``: the bounds (CRS units) of every placed vertex, from each mesh's convex hull (an affine
    map keeps a hull's extremes): [minx, miny, minz, maxx, maxy, maxz]."""
    from scipy.spatial import ConvexHull, QhullError

    lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
    groups: dict = {}
    for k, key in enumerate(p.keys):
        groups.setdefault(key, []).append(k)
    for key, rows in groups.items():
        v = p.meshes[key][0]
        try:
            hull = v[ConvexHull(v).vertices] if len(v) > 4 else v
        except (QhullError, ValueError):  # flat or degenerate: every vertex
            hull = v
        mats = np.array([p.matrices[k][:3, :3] for k in rows])
        placed = np.einsum("kij,hj->khi", mats, hull) + p.ref[rows][:, None, :]
        lo = np.minimum(lo, placed.reshape(-1, 3).min(0))
        hi = np.maximum(hi, placed.reshape(-1, 3).max(0))
    return [float(v) for v in (*lo, *hi)]


@dataclass
class _Placed:
    """What every variant needs: the templates (vertices, faces) by mesh key, each object's template key,
    reference point (CRS units), matrix (4 x 4, row-major), attributes and CityJSON type; the file's translate."""

    meshes: dict
    keys: list
    ref: np.ndarray
    matrices: list
    attributes: list
    ids: list
    translate: np.ndarray
    types: list = field(default_factory=list)


#: the kinds drawn as vehicles (CityJSON has no vehicle type: a CityFurniture of function vehicle, as before)
VEHICLES = frozenset({"car", "van", "truck", "bus"})


def city_type(kind: str | None) -> tuple[str, str | None]:
    """The CityJSON type of an object of ``kind`` and its ``function`` attribute (None: no function).

    >>> city_type("car"), city_type("lamp_post"), city_type("tree"), city_type("unknown")
    (('CityFurniture', 'vehicle'), ('CityFurniture', 'lamp_post'), ('SolitaryVegetationObject', None), ('GenericCityObject', None))
    """
    if kind in VEHICLES:
        return "CityFurniture", "vehicle"
    if kind == "tree":
        return "SolitaryVegetationObject", None
    if not kind or kind == "unknown":
        return "GenericCityObject", None
    return "CityFurniture", kind


def _placed(instances, meshes, docs, headings, georef) -> _Placed:
    unit = georef.crs_unit_m if georef.crs else 1.0
    vunit = georef.vertical_unit_m if georef.crs else 1.0
    to_crs = np.diag([1.0 / unit, 1.0 / unit, 1.0 / vunit])
    used = {}
    for i in instances:
        v, f = (UNIT_BOX if i.mesh == "box" else meshes[i.mesh][:2])
        used.setdefault(i.mesh, (np.round(np.asarray(v, dtype=np.float64), 4), np.asarray(f, dtype=np.int64)))
    ref = np.array([i.origin for i in instances], dtype=np.float64).reshape(-1, 3) @ to_crs
    matrices, attributes, types = [], [], []
    for inst, doc, a in zip(instances, docs, headings):
        m = np.eye(4)
        m[:3, :3] = to_crs @ yaw(a) @ np.diag(inst.scale or (1, 1, 1))
        matrices.append(m)
        flat = {k: v for k, v in properties(doc).items() if v is not None and k != "id"}
        kind_type, function = city_type(doc.get("kind"))
        attributes.append(({"function": function} if function else {}) | flat)
        types.append(kind_type)
    translate = np.floor(ref.min(0)) if len(ref) else np.zeros(3)
    return _Placed(used, [i.mesh for i in instances], ref, matrices, attributes, [d["id"] for d in docs], translate,
                   types)


def _explicit(p: _Placed, k: int, base: int) -> tuple[np.ndarray, dict]:
    """Object ``k``'s vertices (millimetre integers) and its MultiSurface, its indices from ``base``."""
    f = p.meshes[p.keys[k]][1]
    geometry = {"type": "MultiSurface", "lod": "2", "boundaries": (f + base).reshape(-1, 1, 3).tolist()}
    return _placed_ints(p, k), geometry


def _header(p: _Placed, title: str, georef) -> dict:
    doc = {"type": "CityJSON", "version": "2.0",
           "transform": {"scale": [SCALE, SCALE, SCALE], "translate": [float(t) for t in p.translate]},
           "metadata": {"title": title}, "CityObjects": {}, "vertices": []}
    rs = _reference_system(georef)
    if rs:
        doc["metadata"]["referenceSystem"] = rs
    if len(p.ref):
        doc["metadata"]["geographicalExtent"] = _extent(p)
    return doc


def write_cityjson(path, instances: list, meshes: dict, docs: list[dict], headings: list[float], georef,
                   title: str, templates: bool = False, seq_path=None) -> Path:
    """``instances``: :class:`~twinreg.export.tiles3d.Instance` (scene-frame origins); ``headings``: each one's
    turn (rad, counter-clockwise from the scene's +X) of the mesh's +X; ``docs``: the twin.json records;
    ``templates``: geometry templates instead of explicit geometry; ``seq_path``: also write CityJSONSeq there."""
    p = _placed(instances, meshes, docs, headings, georef)
    doc = _header(p, title, georef)
    if templates:
        keys = sorted(p.meshes)
        index = {key: n for n, key in enumerate(keys)}
        bases = np.cumsum([0] + [len(p.meshes[key][0]) for key in keys])
        doc["geometry-templates"] = {
            "templates": [{"type": "MultiSurface", "lod": "2",
                           "boundaries": (p.meshes[key][1] + bases[n]).reshape(-1, 1, 3).tolist()}
                          for n, key in enumerate(keys)],
            "vertices-templates": np.vstack([p.meshes[key][0] for key in keys]).tolist() if keys else []}
        doc["vertices"] = np.rint((p.ref - p.translate) / SCALE).astype(np.int64).tolist()
        for k, oid in enumerate(p.ids):
            doc["CityObjects"][oid] = {"type": p.types[k], "attributes": p.attributes[k], "geometry": [
                {"type": "GeometryInstance", "template": index[p.keys[k]], "boundaries": [k],
                 "transformationMatrix": [float(x) for x in p.matrices[k].ravel()]}]}
    else:
        verts, base = [], 0
        for k, oid in enumerate(p.ids):
            ints, geometry = _explicit(p, k, base)
            verts.append(ints)
            base += len(ints)
            doc["CityObjects"][oid] = {"type": p.types[k], "attributes": p.attributes[k],
                                       "geometry": [geometry]}
        doc["vertices"] = np.vstack(verts).tolist() if verts else []
    Path(path).write_text(json.dumps(doc, separators=(",", ":")), encoding="utf-8")
    if seq_path is not None:
        write_cityjson_seq(seq_path, p, title, georef)
    return Path(path)


def write_cityjson_seq(path, p: _Placed, title: str, georef) -> Path:
    """CityJSONSeq: the header line, then one CityJSONFeature a line with explicit geometry. Written as bytes, the
    placed vertices by :func:`int_rows_json` (the copied city's file is 686 MB, most of it their digits): the
    same bytes as the json module gives (it escapes every non-ASCII character)."""
    boundaries: dict = {}  # a model's faces are the same text in every feature that draws it (indices from 0)
    with open(path, "wb") as fh:
        fh.write(json.dumps(_header(p, title, georef), separators=(",", ":")).encode("ascii") + b"\n")
        for k, oid in enumerate(p.ids):
            key = p.keys[k]
            if key not in boundaries:
                boundaries[key] = json.dumps(p.meshes[key][1].reshape(-1, 1, 3).tolist(),
                                             separators=(",", ":")).encode("ascii")
            feature = {"type": "CityJSONFeature", "id": oid,
                       "CityObjects": {oid: {"type": p.types[k], "attributes": p.attributes[k],
                                             "geometry": [{"type": "MultiSurface", "lod": "2", "boundaries": 0}]}},
                       "vertices": 0}
            text = json.dumps(feature, separators=(",", ":"))
            # the two placeholders, last in their objects, take the faces and the placed vertices
            head, tail = text.rsplit('"vertices":0', 1)
            head, mid = head.rsplit('"boundaries":0', 1)
            fh.write(b"".join((head.encode("ascii"), b'"boundaries":', boundaries[key], mid.encode("ascii"),
                               b'"vertices":', int_rows_json(_placed_ints(p, k)), tail.encode("ascii"), b"\n")))
    return Path(path)


#: the largest magnitude :func:`int_rows_json` writes compiled (19 digits); beyond it, the json module
INT_LIMIT = 10 ** 18


def int_rows_json(a) -> bytes:
    """``json.dumps(a.tolist(), separators=(",", ":"))`` of a 2-D integer array, as ASCII bytes: compiled
    (:func:`_int_rows_fast`) where the kernels are in use, else the json module's (the reference). A CityJSONSeq's
    placed vertices: their encoding was about half of the copied city's CityJSONSeq in a profile, and the sequence
    most of its formats' time (docs/PERFORMANCE.md).

    >>> int_rows_json(np.array([[1, -20, 300], [0, 7, -1]]))
    b'[[1,-20,300],[0,7,-1]]'
    >>> int_rows_json(np.zeros((0, 3), dtype=np.int64)), int_rows_json(np.zeros((2, 0), dtype=np.int64))
    (b'[]', b'[[],[]]')
    """
    a = np.asarray(a)
    compiled = fast(_int_rows_fast)
    if (compiled is not None and a.ndim == 2 and a.dtype.kind in "iu" and a.size
            and -INT_LIMIT < int(a.min()) and int(a.max()) < INT_LIMIT):
        return compiled(np.ascontiguousarray(a, dtype=np.int64)).tobytes()
    return json.dumps(a.tolist(), separators=(",", ":")).encode("ascii")


def _ints_example(rng) -> tuple:
    """Rows of integers of every length and sign, zeros and the largest compiled (the registry's example for
    :func:`int_rows_json`)."""
    a = rng.integers(-10 ** 9, 10 ** 9, (400, 3)) // rng.choice([1, 10, 1000, 10 ** 6, 10 ** 8], (400, 3))
    return np.r_[a, [[0, -1, 9], [INT_LIMIT - 1, -(INT_LIMIT - 1), 10]]],


@kernel(entry="int_rows_json", example="_ints_example")
def _int_rows_fast(a):
    """:func:`int_rows_json`'s text as uint8 (each value's magnitude under :data:`INT_LIMIT`)."""
    n, k = a.shape
    out = np.empty(2 + n * (3 + 21 * k), dtype=np.uint8)
    digits = np.empty(20, dtype=np.uint8)
    out[0] = 91  # [
    pos = 1
    for i in range(n):
        if i > 0:
            out[pos] = 44  # ,
            pos += 1
        out[pos] = 91
        pos += 1
        for j in range(k):
            if j > 0:
                out[pos] = 44
                pos += 1
            v = a[i, j]
            if v < 0:
                out[pos] = 45  # -
                pos += 1
                v = -v
            m = 0
            while True:
                digits[m] = np.uint8(48 + v % 10)
                v //= 10
                m += 1
                if v == 0:
                    break
            while m > 0:
                m -= 1
                out[pos] = digits[m]
                pos += 1
        out[pos] = 93  # ]
        pos += 1
    out[pos] = 93
    return out[:pos + 1]


def _placed_ints(p: _Placed, k: int) -> np.ndarray:
    """Object ``k``'s vertices placed, in the file's integers."""
    v = p.meshes[p.keys[k]][0]
    return np.rint((v @ p.matrices[k][:3, :3].T + p.ref[k] - p.translate) / SCALE).astype(np.int64)

