"""``twinreg classify``: the kind, the type and (when the scan decides it) the model of objects given one per
file. Each object is described as any object is (its COSCO shape and level of symmetry); its kind comes from the
catalogue's nearest references (:mod:`.kinds`); its type from the taxonomy of all the objects given (objects of
one design share a type whether or not a reference exists); its model from the matcher, claimed only when the
model is of that kind and its confidence reaches the floor (``--min-confidence``); below it ``match`` is null and
``candidates`` lists the near references."""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

import cosco
from cosco.arrays import point_spacing
from cosco.levels import symmetry_level
from cosco.taxonomy import taxonomy_of

from ..errors import SceneReadError, require_probability
from ..io.asprs import class_shares
from ..io.points import POINT_SUFFIXES, read_points
from ..matching.match import Evidence, ModelCache, match_objects
from ..settings import DEFAULT, Settings
from .decide import decide
from .kinds import UNKNOWN, References, kind_of, object_types

#: the range noise (m) an object given alone is verified with (a file of one object has no ground to measure the
#: scan's noise on)
OBJECT_NOISE_M = 0.03


@dataclass
class GivenObject:
    """One object file read and described: its ``path``, ``points`` and COSCO ``shape``, its ``level`` of
    symmetry (:class:`cosco.levels.Level`)."""

    path: Path
    points: np.ndarray
    shape: cosco.ObjectShape
    level: object


def object_files(paths) -> list[Path]:
    """The point files of ``paths``: files as given, a folder's point files (not its sub-folders) sorted; a path
    that is neither, or a folder without point files, is refused naming it."""
    files: list[Path] = []
    for p in map(Path, paths):
        if p.is_dir():
            found = sorted((f for f in p.iterdir() if f.is_file() and f.suffix.lower() in POINT_SUFFIXES),
                           key=lambda f: (len(f.stem), f.stem))
            if not found:
                raise SceneReadError(f"{p}: no point files ({', '.join(sorted(POINT_SUFFIXES))})")
            files += found
        elif p.is_file():
            files.append(p)
        else:
            raise SceneReadError(f"{p}: no such file or folder")
    return files


def read_object(path: Path, unit: str = "auto", params: Settings = DEFAULT, warn=None) -> GivenObject:
    """One object's file read and described; a degenerate object is refused naming its file; ``warn(line)`` hears
    what the reader dropped."""
    ps = read_points(path, unit=unit)
    if ps.dropped_note and warn is not None:
        warn(ps.dropped_note)
    try:
        shape = cosco.describe_object(ps.points, params)
    except ValueError as exc:
        raise SceneReadError(f"{path}: {exc}; classify takes one object's points a file") from exc
    if ps.classes is not None and params.open_world.scan_classes:  # a classified file's classes, as build-twin reads them
        shape = replace(shape, classes=class_shares(ps.classes))
    return GivenObject(path, ps.points, shape, symmetry_level(ps.points, params))


def classify_objects(objects: list[GivenObject], catalogue, min_confidence: float | None = None,
                     params: Settings = DEFAULT, progress=None) -> list[dict]:
    """Each object's item as ``classify --json`` prints it (docs/CONTRACT.md). ``progress(stage, done, total)``
    as the objects are matched."""
    floor = (params.min_confidence if min_confidence is None
             else require_probability("--min-confidence", min_confidence))  # build-twin's floor, one default
    refs = References.of_catalogue(catalogue, params)
    shapes = [o.shape for o in objects]
    # the threshold at least taxonomy.spacing_k point spacings, as a twin's
    labels = (taxonomy_of(shapes, params, spacing=[point_spacing(o.points) for o in objects]).labels
              if len(shapes) > 1 else np.ones(len(shapes), dtype=int))
    kinds = [kind_of(o.shape, o.level.level, refs, params) for o in objects]
    outcomes = [None] * len(objects)
    cache = None
    if len(refs):
        cache = ModelCache(catalogue, params)
        done = (lambda k, n: progress("matching", k, n)) if progress else None
        outcomes, _ = match_objects(shapes, catalogue, labels=labels, params=params,
                                    evidence=Evidence([o.points for o in objects], OBJECT_NOISE_M), cache=cache, done=done)
        outcomes, kinds = decide(outcomes, kinds, refs, floor)  # build-twin's rules, one function
    matches = [_match_item(res.match if res is not None else None) for res in outcomes]
    types = object_types(labels, [k.kind for k in kinds])
    return [_item(o, k, t, match, cache, params) for o, k, match, t in zip(objects, kinds, matches, types)]


def _match_item(m) -> dict | None:
    """``classify --json``'s ``match`` of a decided model (None: none)."""
    if m is None:
        return None
    return {"model_id": m.model_id, "name": m.name, "rmse_m": round(m.rmse, 4), "confidence": round(m.confidence, 3),
            "ambiguous_with": list(m.ambiguous_with)}


def _item(o: GivenObject, kind, label: int, match: dict | None, cache, params: Settings) -> dict:
    s = o.shape
    return {"file": str(o.path), "n_points": int(s.n_points), "kind": kind.kind,
            "kind_confidence": round(kind.confidence, 3), "type": label,
            "symmetry": {"found": bool(s.symmetry.found), "pcr": round(float(s.symmetry.pcr), 4),
                         "level": o.level.level},
            "size": s.size.as_dict(), "match": match,
            "candidates": [] if match is not None or cache is None else near_candidates(s, kind, cache, params)}


def near_candidates(shape, kind, cache, params: Settings) -> list[dict]:
    """The references nearest an object of its kind (of any kind when it is unknown): name, kind, the sections'
    dissimilarity (m, ``score_m``) and the share of the kind vote each carried (``confidence``)."""
    near = [n for n in kind.near if kind.kind == UNKNOWN or n.kind == kind.kind]
    missing = sorted({n.id for n in near} - set(cache.known()))
    if missing:
        cache.add_rows(cache.catalogue.rows(missing))
    if not near:
        return []
    # the object's sections prepared once, each model's as the cache keeps them (cosco.dissimilarity's numbers)
    own = cosco.SectionPair(shape.sections, params)

    def score(model_id: int) -> float:
        other = (cache.pair(model_id) if cache.params is params
                 else cosco.SectionPair(cache.geometry(model_id).sections, params))
        return float(cosco.register_sections(own, other, params).rmse)

    return [{"name": n.name, "kind": n.kind, "score_m": round(score(n.id), 4), "confidence": round(n.share, 3)}
            for n in near]


def classify_files(paths, catalogue, unit: str = "auto", min_confidence: float | None = None,
                   params: Settings = DEFAULT, progress=None, warn=None) -> list[dict]:
    """``classify``: every object file of ``paths`` (a folder stands for its point files) read, then
    :func:`classify_objects`. A file that cannot be read or described does not stop the batch: its item, in its
    place, holds ``error`` (the one line said to ``warn``) and nulls."""
    if min_confidence is not None:  # refused before a file is read
        require_probability("--min-confidence", min_confidence)
    say = warn or (lambda line: None)
    files = object_files(paths)
    objects, failed = [], {}
    for k, f in enumerate(files):
        try:
            objects.append(read_object(f, unit, params, warn=say))
        except SceneReadError as exc:
            failed[k] = str(exc)
            say(f"skipped: {exc}")
        if progress:
            progress("reading", k + 1, len(files))
    items = iter(classify_objects(objects, catalogue, min_confidence, params, progress) if objects else [])
    return [_failed_item(f, failed[k]) if k in failed else next(items) for k, f in enumerate(files)]


def _failed_item(path: Path, error: str) -> dict:
    """The item of a file classify could not read or describe: every key, null, and the ``error``."""
    return {"file": str(path), "n_points": 0, "kind": None, "kind_confidence": None, "type": None,
            "symmetry": None, "size": None, "match": None, "candidates": [], "error": error}
