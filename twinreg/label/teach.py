"""``twinreg label OUT --type T --kind K``: the members of type T of the twin in OUT stored as scanned exemplars of
kind K (any lower-case kind: ``hedge``, ``bicycle``, or a negative such as ``not_a_car``), which the next run's kind
decision reads as it reads any scanned exemplar (:mod:`twinreg.recognition.kinds`: a kind of two or more exemplars
is held to their own spread). Exemplars stored by ``label`` are tagged ``exemplar`` and never placed as a model:
they teach a kind, not a design.

Each member's points come from the twin's classified scan, where each point's source id is its object's number:
``scan.copc.laz`` for a scene (object ``obj7`` is 7), ``classified/<cell>.copc.laz`` for a city built with
``--classified-scan`` (object ``<cell>-7`` is 7 in its cell's file). At most :data:`MAX_MEMBERS` members (those with
most points) become exemplars, each of at least ``segment.min_points`` points.

The twin is someone else's data: twin.json is read with its size checked; the scan files are found by fixed names
and a cell name of letters, digits and underscores (no path read from the twin), must be regular files inside the
folder, and are read in chunks (a member's points capped at :data:`MAX_POINTS`, evenly thinned); nothing is added
unless every exemplar can be (those added before a failure are removed)."""

from __future__ import annotations

import re
import tempfile
from pathlib import Path

import numpy as np

from ..catalogue.categories import check_category
from ..catalogue.names import printable
from ..errors import CatalogueError
from ..io._files import file_of, twin_doc
from ..io.points import UNIT_SCALES
from ..recognition.kinds import EXEMPLAR
from ..settings import DEFAULT, Settings

MAX_MEMBERS = 20
MAX_POINTS = 200_000
_SCENE_ID = re.compile(r"obj(\d{1,9})")
_CITY_ID = re.compile(r"([A-Za-z0-9_]{1,64})-(\d{1,9})")


def members_of(doc: dict, type_: int, where: str) -> list[dict]:
    """The objects of type ``type_`` in twin.json's document, most points first; a :class:`CatalogueError` naming
    the twin's types when there is none."""
    objs = doc.get("objects") if isinstance(doc, dict) else None
    objs = [o for o in objs if isinstance(o, dict)] if isinstance(objs, list) else []
    mine = [o for o in objs if o.get("type") == type_ and isinstance(o.get("id"), str)]
    if not mine:
        have = sorted({o.get("type") for o in objs if isinstance(o.get("type"), int)})
        raise CatalogueError(f"{where}: no object of type {type_}; its types: "
                             f"{', '.join(map(str, have[:30])) or 'none'}")
    return sorted(mine, key=lambda o: -(o.get("n_points") if isinstance(o.get("n_points"), int) else 0))


def scan_file(folder: Path, object_id: str) -> tuple[Path, int]:
    """(the classified scan holding ``object_id``'s points, its number there)."""
    m = _SCENE_ID.fullmatch(object_id)
    if m:
        path, number = folder / "scan.copc.laz", int(m.group(1))
    else:
        m = _CITY_ID.fullmatch(object_id)
        if not m:
            raise CatalogueError(f"{folder / 'twin.json'}: object id '{printable(object_id)[:80]}' is not a twin's")
        path, number = folder / "classified" / f"{m.group(1)}.copc.laz", int(m.group(2))
    if not file_of(folder, path):
        fix = "rerun build-twin" if m.re is _SCENE_ID else "rerun build-twin with --classified-scan"
        raise CatalogueError(f"{path}: missing or not a file of the twin (label reads each member's points "
                             f"there); {fix}")
    return path, number


def read_members(path: Path, numbers: set, unit_m: float, chunk: int = 1_000_000) -> dict:
    """{number: (n, 3) metres} of the points of ``path`` whose source id is one of ``numbers``, read in chunks;
    a member's points beyond :data:`MAX_POINTS` thinned evenly."""
    import laspy

    parts: dict = {n: [] for n in numbers}
    wanted = np.array(sorted(numbers), dtype=np.int64)
    try:
        with laspy.open(path) as f:
            for pts in f.chunk_iterator(chunk):
                ids = np.asarray(pts.point_source_id, dtype=np.int64)
                keep = np.isin(ids, wanted)
                if not keep.any():
                    continue
                xyz = np.c_[np.asarray(pts.x)[keep], np.asarray(pts.y)[keep], np.asarray(pts.z)[keep]] * unit_m
                for n in np.unique(ids[keep]):
                    parts[int(n)].append(xyz[ids[keep] == n])
    except (OSError, ValueError, laspy.errors.LaspyException) as exc:
        raise CatalogueError(f"{path}: not a readable LAS/LAZ ({exc}); rerun build-twin") from exc
    out = {}
    for n, chunks in parts.items():
        p = np.concatenate(chunks) if chunks else np.zeros((0, 3))
        if len(p) > MAX_POINTS:
            p = p[np.linspace(0, len(p) - 1, MAX_POINTS).astype(np.int64)]
        out[n] = p
    return out


def _height(o: dict) -> float | None:
    """An object's height in twin.json (m), or None when it gives none that is plausible."""
    size = o.get("size")
    h = size.get("height") if isinstance(size, dict) else None
    return float(h) if isinstance(h, (int, float)) and 0.0 < h < 1000.0 else None


def label_type(catalogue, folder: Path, type_: int, kind: str, params: Settings = DEFAULT) -> tuple[list, list]:
    """Store the members of type ``type_`` of the twin in ``folder`` as scanned exemplars of ``kind`` in
    ``catalogue``; returns (the rows added, the ids of the members left out for their few points); see the
    module's text."""
    folder = Path(folder)
    if not isinstance(type_, int) or type_ < 1:
        raise CatalogueError(f"--type {type_}: give a type number (twin.json's objects carry theirs)")
    kind = check_category(kind)
    if kind == "unknown":
        raise CatalogueError("--kind unknown: unknown is what fits no kind; give the kind these objects are")
    doc_path, doc = twin_doc(folder, CatalogueError, "label")
    unit = doc.get("unit") if isinstance(doc, dict) else None
    if unit not in UNIT_SCALES:
        raise CatalogueError(f"{doc_path}: its unit '{printable(str(unit))[:20]}' is not one of "
                             f"{', '.join(UNIT_SCALES)}; rerun build-twin")
    members = members_of(doc, type_, str(doc_path))[:MAX_MEMBERS]
    where: dict = {}
    for o in members:
        path, number = scan_file(folder, o["id"])
        where.setdefault(path, {})[number] = o["id"]
    base = re.sub(r"[^a-z0-9_]+", "_", folder.resolve().name.lower()).strip("_")[:40] or "twin"
    names = {o["id"]: f"{kind}-{base}-{o['id'].lower()}"[:100] for o in members}
    for name in names.values():
        catalogue.check_free_name(name, f"{doc_path}: ")
    points: dict = {}
    for path, numbers in where.items():
        got = read_members(path, set(numbers), UNIT_SCALES[unit])
        points.update({numbers[n]: p for n, p in got.items()})
    usable = [o["id"] for o in members if len(points.get(o["id"], ())) >= params.segment.min_points]
    if not usable:
        raise CatalogueError(f"{folder}: type {type_}'s members hold fewer than {params.segment.min_points} points "
                             "each in the classified scan; label a type with more points")
    few = [o["id"] for o in members if o["id"] not in usable]
    heights = {o["id"]: _height(o) for o in members}
    return _add_all(catalogue, folder, type_, kind, usable, points, names, heights), few


def _add_all(catalogue, folder: Path, type_: int, kind: str, ids: list, points: dict, names: dict,
             heights: dict) -> list:
    """Add each member as an exemplar, all or none (``heights``: each member's height in the twin, m)."""
    added = []
    twin_tag = f"twin:{printable(folder.resolve().name)[:80]}"
    try:
        with tempfile.TemporaryDirectory(prefix="twinreg-label-") as tmp:
            for oid in ids:
                p = points[oid] - points[oid].mean(axis=0)
                path = Path(tmp) / f"{len(added)}.xyz"
                np.savetxt(path, p, fmt="%.4f")
                # its ground as the twin measured it: its height is from the ground, its top its highest point
                ground = float(p[:, 2].max() - heights[oid]) if heights.get(oid) is not None else None
                added.append(catalogue.add(path, name=names[oid], category=kind, unit="m", ground_z=ground,
                                           tags=[EXEMPLAR, twin_tag, f"type:{type_}", f"object:{oid}"]))
    except BaseException:
        for row in added:
            catalogue.remove(row.id)
        raise
    return added
