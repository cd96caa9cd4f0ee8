"""The twin as OGC 3D Tiles 1.1 (``tiles/tileset.json``) and as one glTF (``twin.glb``).

- The root tile's ``transform`` takes the twin's east-north-up frame (:class:`~twinreg.geo.earth.EnuFrame`,
  about the objects' centre) to ECEF; ``refine: ADD``.
- One child per processing cell (one for a scene), placed by a translation to its centre, with a box bounding
  volume and a GLB: every catalogue model the cell uses is one mesh on one node drawn with
  ``EXT_mesh_gpu_instancing`` (translations relative to the cell centre, unit-quaternion rotations), objects with
  no model are one unit box scaled per instance; ``EXT_instance_features`` + ``EXT_structural_metadata`` give each
  instance its row: object id, model, make, confidence, matched, sizes.
- The scan beside it: ``tiles/scan/tileset.json`` (an external tileset referenced from the root, so a viewer shows
  both), a level-of-detail quadtree of point tiles per cell (:mod:`.scan_tiles`) holding every point, coloured by
  height above ground.
- ``twin.glb``: every instance in one GLB in the root's east-north-up frame (origin and CRS in ``asset.extras``).

glTF content is Y-up and tiles are Z-up; :mod:`twinreg.export.gltf` writes ``(x, y, z)`` as ``(x, z, -y)`` once,
and 3D Tiles viewers turn it back.
"""

from __future__ import annotations

import json
import zlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from cosco.kernels import fast, kernel

from ..geo.earth import EnuFrame, enu_angles
from .gltf import Glb
from .objects import box_mesh
from .scan_tiles import (
    box_volume,
    link_error,
    link_tree,
    prebuilt_entry,
    translation,
    write_cell_quadtree,
    write_scan_tileset,
)
from .twin_ply import PALETTE as TAB10

#: triangles of a model in the tiles (a city of thousands of cars must draw in a browser; twin.glb and the KMZ
#: keep Google Earth's 21,845)
TILE_MAX_TRIANGLES = 2_000
#: metres added around instances' origins for their bounding boxes (half a car's length and its height)
REACH = (3.5, 3.5, 3.5)


@dataclass
class Instance:
    """One object as the 3D formats place it: ``mesh`` (a key of the meshes), ``origin`` (3,) scene frame (where
    the mesh's origin goes), ``bearing`` (degrees clockwise from north, of the mesh's +X), ``scale`` (L, W, H)
    for a unit box or None, and its metadata row ``props``."""

    id: str
    mesh: str
    origin: np.ndarray
    bearing: float
    scale: tuple | None
    props: dict


def instance_of(p) -> Instance:
    """The :class:`Instance` of a :class:`~twinreg.export.objects.PlacedObject` (its origin in the scene
    frame)."""
    doc = p.doc
    m = doc["match"]
    props = {"id": doc["id"], "kind": doc.get("kind") or "unknown", "model": m["name"] if m else "",
             "make": (m or {}).get("make") or "",
             "matched": m is not None,
             "confidence": float(c) if (c := (m or {}).get("confidence")) is not None else -1.0,
             "length": doc["size"]["length"], "width": doc["size"]["width"], "height": doc["size"]["height"],
             "cluster": float(doc["cluster"]),
             "kind_confidence": float(c) if (c := doc.get("kind_confidence")) is not None else -1.0}
    return Instance(doc["id"], "box" if p.scale is not None else p.mesh_key, np.asarray(p.origin) + p.offset,
                    p.bearing, p.scale, props)


#: model colours (matplotlib's tab10 without its red, kept for objects with no model, and its grey, the scan's
#: ground), chosen by the model's key
PALETTE = [tuple(round(c / 255.0, 3) for c in rgb) for k, rgb in enumerate(TAB10.tolist()) if k not in (3, 7)]


def model_colour(key: str) -> tuple:
    """The colour a model is drawn in, the same in every tile and file (from a checksum of its key)."""
    return PALETTE[zlib.crc32(key.encode()) % len(PALETTE)]


UNIT_BOX = box_mesh(1.0, 1.0, 1.0)
BOX_COLOUR = (0.9, 0.2, 0.2)
DESCRIPTIONS = {"id": "object id in twin.json", "model": "catalogue model (empty: no model fits)",
                "kind": "the object's kind: a catalogue category (car, lamp_post, ...) or unknown",
                "kind_confidence": "0-1, the kind vote's share (-1: not known)",
                "confidence": "0-1 from the margin over the runner-up (-1: not known)",
                "matched": "a catalogue model was placed (else a box of the measured size)"}


def instances_glb(instances: list[Instance], positions: np.ndarray, angles: np.ndarray, meshes: dict,
                  extras: dict | None = None) -> bytes:
    """One GLB drawing ``instances`` at Z-up ``positions`` (n, 3) turned by ``angles`` (rad CCW about up): one
    mesh and one instanced node per distinct mesh; feature ids are the instances' rows of one property table."""
    g = Glb(extras)
    table = g.property_table("car", {k: [i.props[k] for i in instances] for k in instances[0].props},
                             DESCRIPTIONS)
    groups: dict = {}
    for k, inst in enumerate(instances):
        groups.setdefault(inst.mesh, []).append(k)
    for key, rows in groups.items():
        rows = np.asarray(rows)
        if key == "box":
            mesh = g.mesh(*UNIT_BOX, BOX_COLOUR, "box")
            scales = np.array([instances[r].scale for r in rows], dtype=np.float64)
        else:
            v, f, _ = meshes[key]
            mesh = g.mesh(v, f, model_colour(key), key)
            scales = None
        g.instanced(mesh, key, positions[rows], angles[rows], scales=scales, feature_ids=rows, property_table=table,
                    ids=[instances[r].id for r in rows])
    return g.to_bytes()


def scan_colours(hag: np.ndarray, is_ground: np.ndarray) -> np.ndarray:
    """(n, 3) uint8: ground grey, the rest from blue (low) to yellow (4 m and more) by height above ground."""
    kern = fast(_scan_colours_fast)
    if kern is not None:  # compiled: the same bytes, no (n,) floats
        return kern(np.ascontiguousarray(hag, dtype=np.float64), np.ascontiguousarray(is_ground, dtype=bool))
    t = np.clip(np.asarray(hag, dtype=np.float64) / 4.0, 0.0, 1.0)
    low = 1 - t
    rgb = np.empty((len(t), 3), dtype=np.uint8)
    ground = np.asarray(is_ground, dtype=bool)
    for c, (a, b) in enumerate(((40, 250), (90, 210), (200, 40))):  # a channel at a time (no (n, 3) floats)
        rgb[:, c] = np.where(ground, 150.0, low * a + t * b)
    return rgb


def _colours_example(rng) -> tuple:
    hag = rng.uniform(-1, 6, 3000)
    return hag, hag < 0.1


@kernel(entry="scan_colours", example="_colours_example")
def _scan_colours_fast(hag, ground):
    """:func:`scan_colours`: ground grey, the rest blue to yellow by height (0-4 m)."""
    n = hag.shape[0]
    rgb = np.empty((n, 3), dtype=np.uint8)
    ends = ((40.0, 250.0), (90.0, 210.0), (200.0, 40.0))
    for p in range(n):
        t = min(max(hag[p] / 4.0, 0.0), 1.0)
        for c in range(3):
            rgb[p, c] = np.uint8(150.0 if ground[p] else (1 - t) * ends[c][0] + t * ends[c][1])
    return rgb


def scan_sample(points: np.ndarray, hag: np.ndarray, is_ground: np.ndarray, rows=None) -> tuple:
    """The scan as the tiles carry it: the points ``rows`` (all when None), every one of them, and their colours:
    ``(indices into points, (m, 3) uint8)``."""
    rows = np.arange(len(points)) if rows is None else np.asarray(rows)
    return rows, scan_colours(hag[rows], is_ground[rows])


def write_tiles(out: Path, instances: list[Instance], meshes: dict, georef, groups: list[tuple[str, list[int]]],
                scans: list | None = None, tile_meshes: dict | None = None) -> dict:
    """Write ``out/tiles/`` (tileset.json, one GLB per group, the scan tileset) and ``out/twin.glb``.

    instances : every object; groups : (name, indices into instances) per cell; meshes : key -> (vertices,
    faces, rgb) in model coordinates (metres, Z up, front +X), for twin.glb, and ``tile_meshes`` the same with
    lighter meshes for the tiles (None: ``meshes``); scans : (name, (n, 3) scene points, (n, 3) uint8
    colours) per cell, or (name, dict) for a cell whose worker wrote its tiles
    (:func:`~twinreg.export.scan_tiles.write_cell_scan`), or None. Also writes ``out/twin.glb``. Returns a summary (the frame's origin, counts)."""
    tile_meshes = meshes if tile_meshes is None else tile_meshes
    out = Path(out)
    (out / "tiles" / "cells").mkdir(parents=True, exist_ok=True)
    origins = np.array([i.origin for i in instances], dtype=np.float64).reshape(-1, 3)
    lo, hi = origins.min(0), origins.max(0)
    frame = EnuFrame.at(georef, [(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, lo[2]])
    enu = frame.from_scene(georef, origins)
    angles = enu_angles([i.bearing for i in instances])
    reach = np.asarray(REACH)
    children, all_lo, all_hi = [], [], []
    for name, rows in groups:
        rows = np.asarray(rows, dtype=np.int64)
        if not len(rows):
            continue
        p = enu[rows]
        c = (p.min(0) + p.max(0)) / 2
        data = instances_glb([instances[r] for r in rows], p - c, angles[rows], tile_meshes)
        (out / "tiles" / "cells" / f"{name}.glb").write_bytes(data)
        blo, bhi = p.min(0) - c - reach, p.max(0) - c + reach
        all_lo.append(blo + c)
        all_hi.append(bhi + c)
        children.append({"transform": translation(c), "boundingVolume": {"box": box_volume(blo, bhi)},
                         "geometricError": 0.0, "content": {"uri": f"cells/{name}.glb"}})
    n_scan = 0
    if scans:
        n_scan = _write_scan(out / "tiles" / "scan", frame, georef, scans, all_lo, all_hi)
        lo, hi = np.min(all_lo, 0), np.max(all_hi, 0)
        children.append({"boundingVolume": {"box": box_volume(lo, hi)}, "geometricError": link_error(lo, hi, 0.0),
                         "content": {"uri": "scan/tileset.json"}})
    root_lo, root_hi = np.min(all_lo, 0), np.max(all_hi, 0)
    size = float(np.linalg.norm(root_hi - root_lo))
    origin = {"lon": frame.lon, "lat": frame.lat, "h": frame.h}
    tileset = {"asset": {"version": "1.1", "generator": "twinreg",
                         "extras": {"origin": origin, "crs": georef.crs, "frame": "east-north-up metres about origin"}},
               "geometricError": size,
               "root": {"transform": [float(v) for v in frame.to_ecef_matrix().T.ravel()],
                        "boundingVolume": {"box": box_volume(root_lo, root_hi)}, "geometricError": size / 2,
                        "refine": "ADD", "children": children}}
    (out / "tiles" / "tileset.json").write_text(json.dumps(tileset, indent=1), encoding="utf-8")
    extras = {"origin": origin, "crs": georef.crs,
              "frame": "east-north-up metres about origin (glTF Y-up: x east, y up, -z north)"}
    (out / "twin.glb").write_bytes(instances_glb(instances, enu, angles, meshes, extras))
    return {"origin": origin, "n_tiles": len(groups), "n_scan_points": n_scan}


def _write_scan(folder: Path, frame: EnuFrame, georef, scans, all_lo: list, all_hi: list) -> int:
    """The scan's level-of-detail tileset (:mod:`.scan_tiles`), a quadtree per cell."""
    folder.mkdir(parents=True, exist_ok=True)
    entries = []
    for k, (name, *data) in enumerate(scans):
        if isinstance(data[0], dict):  # written by the cell's worker: linked here, placed by an affine transform
            info = data[0]
            link_tree(Path(info["folder"]), folder)
            a, b = frame.affine_near(georef, np.asarray(info["centre"]))
            entries.append(prebuilt_entry(info, a, b))
            all_lo.append(entries[-1]["_lo"])
            all_hi.append(entries[-1]["_hi"])
            continue
        pts, rgb = data
        if not len(pts):
            continue
        centre = (pts.min(0) + pts.max(0)) / 2
        a, b = frame.affine_near(georef, centre)
        p = (pts - centre) @ a.T + b
        entries.append(write_cell_quadtree(folder, name, p, rgb, seed=k))
        all_lo.append(p.min(0))
        all_hi.append(p.max(0))
    return write_scan_tileset(folder, entries) if entries else 0
