"""twin.kmz: ``doc.kml`` with one Placemark per object (a Model at its WGS84 position, heading clockwise from north,
clamped to the ground; ExtendedData with its kind, type, shape, model and confidences), in a Folder per kind with
a Style per kind, and one COLLADA file per distinct model (plus a box per unmatched object)."""

from __future__ import annotations

import tempfile
import zipfile
import zlib
from pathlib import Path

import numpy as np

from ..io.decimate import decimate
from ..io.outdir import atomic_path
from .collada import escape, write_collada
from .twin_json import trust_text

# COLLADA files are authored with the car's front along +Y (north), so a KML heading is the front's bearing
FRONT_TO_NORTH = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])


def _data(name: str, value) -> str:
    return f'<Data name="{escape(name)}"><value>{escape(str(value))}</value></Data>'


def placemark_fields(p) -> dict:
    """A :class:`~twinreg.export.objects.PlacedObject`'s placemark: id, lon, lat, alt, bearing, the mesh's key, a
    description and the ExtendedData fields (from its twin.json record)."""
    m, size = p.doc["match"], p.size
    description = (f"{m['name']} ({m['make'] or ''} {m['model'] or ''}), RMSE {m['rmse_m'] * 100:.1f} cm"
                   f"{trust_text(m)}" if m else f"unmatched: {p.outcome.reason}")
    kind = str(p.doc.get("kind") or "unknown")
    kind_conf = p.doc.get("kind_confidence")
    return {"id": p.id, "lon": p.lon, "lat": p.lat, "alt": 0.0, "bearing": p.bearing, "mesh": p.mesh_key,
            "description": description, "kind": kind,
            "data": {"kind": kind, "kind_confidence": "" if kind_conf is None else f"{kind_conf:.2f}",
                     "type": int(p.type), "shape": p.shape_source,
                     "model": m["name"] if m else "none", "make": (m or {}).get("make") or "",
                     "length_m": f"{size['length']:.2f}", "width_m": f"{size['width']:.2f}",
                     "height_m": f"{size['height']:.2f}", "rmse_m": f"{m['rmse_m']:.4f}" if m else "",
                     "cluster": int(p.label),
                     "confidence": "" if not m or m["confidence"] is None else f"{m['confidence']:.2f}",
                     "ambiguous_with": ", ".join(m["ambiguous_with"]) if m else "",
                     "outside_tolerance": str(bool(m and m["outside_tolerance"])).lower()}}


#: the label colour of a kind in Google Earth's list and map (KML aabbggrr); other kinds take a colour of their name
KIND_COLOURS = {"car": "ff3a7bd5", "unknown": "ff9e9e9e", "vegetation": "ff3fae3f", "structure": "ff5a6e8c"}


def kind_colour(kind: str) -> str:
    """A kind's KML colour (aabbggrr): fixed for the common kinds, else one of its name (the same in every twin).

    >>> kind_colour("car"), kind_colour("hydrant") == kind_colour("hydrant")
    ('ff3a7bd5', True)
    """
    if kind in KIND_COLOURS:
        return KIND_COLOURS[kind]

    h = zlib.crc32(kind.encode("utf-8"))
    return "ff" + "".join(f"{64 + (h >> s) % 160:02x}" for s in (0, 8, 16))


def _style_id(kind: str) -> str:
    return "kind-" + "".join(c if c.isalnum() or c in "_-" else "_" for c in kind)[:60]


def kind_style(kind: str) -> str:
    """A Style for the placemarks of one kind: its icon and label in the kind's colour."""
    c = kind_colour(kind)
    return (f'<Style id="{_style_id(kind)}"><IconStyle><color>{c}</color></IconStyle><LabelStyle><color>{c}</color>'
            "<scale>0.8</scale></LabelStyle></Style>")


def placemark(obj: dict, href: str) -> str:
    """One Placemark: obj has id, lon, lat, alt, bearing, kind and the ExtendedData fields."""
    ext = "".join(_data(k, v) for k, v in obj["data"].items())
    style = f"<styleUrl>#{_style_id(obj['kind'])}</styleUrl>" if obj.get("kind") else ""
    return (f"<Placemark><name>{escape(obj['id'])}</name><description>{escape(obj['description'])}</description>"
            f"{style}<ExtendedData>{ext}</ExtendedData>"
            f"<Model id=\"model_{escape(obj['id'])}\"><altitudeMode>clampToGround</altitudeMode>"
            f"<Location><longitude>{obj['lon']:.9f}</longitude><latitude>{obj['lat']:.9f}</latitude>"
            f"<altitude>{obj['alt']:.3f}</altitude></Location>"
            f"<Orientation><heading>{obj['bearing']:.3f}</heading><tilt>0</tilt><roll>0</roll></Orientation>"
            f"<Scale><x>1</x><y>1</y><z>1</z></Scale><Link><href>{escape(href)}</href></Link></Model></Placemark>")


def region_folder(name: str, bounds: dict, marks: str, min_pixels: int = 128) -> str:
    """A KML Folder with a Region (``bounds``: north, south, east, west in degrees): Google Earth loads its
    placemarks only when the region covers at least ``min_pixels`` on screen, so a city opens at once."""
    box = "".join(f"<{k}>{bounds[k]:.9f}</{k}>" for k in ("north", "south", "east", "west"))
    return (f"<Folder><name>{escape(name)}</name><Region><LatLonAltBox>{box}</LatLonAltBox>"
            f"<Lod><minLodPixels>{min_pixels}</minLodPixels><maxLodPixels>-1</maxLodPixels></Lod></Region>"
            f"{marks}</Folder>")


def write_kmz(path, name: str, objects: list[dict], meshes: dict, folders: list[dict] | None = None) -> Path:
    """Write the KMZ. ``objects``: dicts with id, lon, lat, alt, bearing, description, data, mesh (a key of
    ``meshes``). ``meshes``: key -> (vertices, faces, rgb) in model coordinates (metres, Z up, front +X).
    ``folders``: for a tiled run, dicts with name, bounds (see :func:`region_folder`) and ids (of ``objects``):
    one Folder with a Region each. The placemarks go in a Folder a kind (``kind (count)``, unknown last), each kind
    with its Style (:func:`kind_style`); a city's Regions sit inside each kind's Folder."""
    path = Path(path)
    with tempfile.TemporaryDirectory() as tmpdir:
        files = {}
        for key, (v, f, rgb) in meshes.items():
            v2, f2 = decimate(v, f)
            rel = f"models/{key}.dae"
            write_collada(Path(tmpdir) / f"{key}.dae", np.asarray(v2) @ FRONT_TO_NORTH.T, f2, rgb, key)
            files[rel] = Path(tmpdir) / f"{key}.dae"
        kinds = sorted({o.get("kind") or "unknown" for o in objects}, key=lambda k: (k == "unknown", k))
        by_kind = {k: [o for o in objects if (o.get("kind") or "unknown") == k] for k in kinds}
        parts = []
        for kind in kinds:  # a Folder a kind (by name, unknown last), in it the cells' Regions of a city
            ids = {o["id"] for o in by_kind[kind]}
            if folders is None:
                marks = "".join(placemark(o, f"models/{o['mesh']}.dae") for o in by_kind[kind])
            else:
                by_id = {o["id"]: o for o in by_kind[kind]}
                marks = "".join(region_folder(f["name"], f["bounds"], "".join(
                    placemark(by_id[i], f"models/{by_id[i]['mesh']}.dae") for i in f["ids"] if i in ids))
                    for f in folders if any(i in ids for i in f["ids"]))
            parts.append(f"<Folder><name>{escape(kind)} ({len(by_kind[kind])})</name>{marks}</Folder>")
        styles = "".join(kind_style(k) for k in kinds)
        kml = ('<?xml version="1.0" encoding="UTF-8"?>\n<kml xmlns="http://www.opengis.net/kml/2.2">'
               f"<Document><name>{escape(name)}</name><open>1</open>{styles}{''.join(parts)}</Document></kml>\n")
        with atomic_path(path, ".kmz") as tmp, zipfile.ZipFile(tmp, "w", compression=zipfile.ZIP_DEFLATED,
                                                                compresslevel=1) as z:
            z.writestr("doc.kml", kml)  # the first entry, as Google Earth expects
            for rel, src in files.items():
                z.write(src, rel)
    return path
