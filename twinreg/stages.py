"""The stages a scene and a city both run, one copy: the run's parameters checked (:func:`checked_params`), the
catalogue checked (:func:`require_models`), the scan placed on Earth (:func:`locate`), the objects' taxonomy
(:func:`taxonomy`), the objects' kinds and the models under the confidence floor withdrawn (:func:`recognise`),
their types (:func:`types_of`), the shapes of the types without a model (:func:`fuse`), every object placed
(:func:`place`). The per-scene pipeline
(:mod:`twinreg.pipeline`) runs them on one scene; the city engine (:mod:`twinreg.city`) maps them over cells and
batches; the simulator's accuracy runs use them too. Nothing here imports the pipeline or the city engine."""

from __future__ import annotations

import time
from collections import Counter

import numpy as np

from cosco.kernels import in_use as kernels_in_use
from cosco.taxonomy import taxonomy_of

from .catalogue.categories import VEHICLES
from .errors import CatalogueError, require_positive, require_probability
from .export.objects import fused_pose, place_object, pose
from .export.twin_json import object_record
from .geo.georef import check_area
from .process.helpers import HELPER_TIMEOUT_S, Forked, Pending, apart
from .progress import say
from .recognition.classify import near_candidates
from .recognition.decide import decide
from .recognition.kinds import References, kind_of, object_types
from .settings import Settings
from .shapes.fuse import FusedShape, fuse_type, generic_solid


def checked_params(params: Settings, tol: float | None, threshold: float | None,
                   min_confidence: float | None = None) -> Settings:
    """``params`` with the size tolerance and cluster threshold the user gave (both must be positive) and the
    models' confidence floor (0-1)."""
    if min_confidence is not None:
        params = params.with_(min_confidence=require_probability("--min-confidence", min_confidence))
    tol = require_positive("--tol", tol, f" (default {params.matching.size_tol:g})")
    threshold = require_positive("--threshold", threshold, f" (default {params.taxonomy.threshold:g})")
    # a tolerance given by the user is the window, as in the paper: it no longer grows with the point spacing
    if tol is not None:
        params = params.with_(matching={"size_tol": tol, "size_spacing_k": 0.0})
    if threshold is not None:
        params = params.with_(taxonomy={"threshold": threshold, "spacing_k": 0.0})
    return params


def require_models(catalogue) -> None:
    """:class:`CatalogueError` naming the folder and the fix when the catalogue a run matches against is missing
    (the folder, or its database) or holds no model."""
    folder = catalogue.folder
    if not folder.exists():
        raise CatalogueError(f"{folder}: no catalogue there (the folder does not exist); pass --library with the "
                             "folder that holds catalogue.sqlite, or add models to a new one with `twinreg "
                             f"--library {folder} add-model MESH`")
    if not catalogue.exists:
        raise CatalogueError(f"{folder}: the folder holds no catalogue (no catalogue.sqlite); pass --library with "
                             "the folder that holds one, or add models with `twinreg add-model MESH`")
    if catalogue.count() == 0:
        raise CatalogueError(f"the catalogue in {folder} is empty; add models with `twinreg add-model MESH` or "
                             "`twinreg import-models DIR`")


def locate(georef, lo, hi, where: str):
    """The georeference of a scan whose footprint is ``lo``-``hi`` (scene metres): refused when its CRS puts it
    outside that CRS's area of use (:func:`~twinreg.geo.georef.check_area`, one line naming ``where``), else with
    the CRS's code and the reference system identified where the scan is."""
    check_area(georef, lo, hi, where)
    centre = georef.centre_of(np.array([np.asarray(lo, dtype=np.float64)[:3], np.asarray(hi, dtype=np.float64)[:3]]))
    return georef.identified(centre["lon"], centre["lat"])


def taxonomy(shapes, params: Settings, timing: dict, progress=None, distances_of=None, spacing=None):
    """The objects' :class:`~cosco.taxonomy.Taxonomy` (:func:`cosco.taxonomy.taxonomy_of`: the paper's matrix and
    dendrogram up to ``params.taxonomy.full_max`` objects, the sparse graph beyond), its parts timed in
    ``timing``. ``spacing``: the objects' point spacings (m): the threshold is at least
    ``params.taxonomy.spacing_k`` times their median (a sparse scan)."""
    return taxonomy_of(shapes, params, timing, (lambda text: say(progress, text)) if progress else None,
                       distances_of, spacing)


def with_targets(catalogue, params: Settings) -> Settings:
    """``params`` detecting every object on the ground (``segment.targets="all"``) when the catalogue holds models of
    other kinds than vehicles (what a run can recognise is what it looks for), else as given."""
    kinds = {r.category or "car" for r in catalogue.list()}
    return params.with_(segment={"targets": "all"}) if kinds - VEHICLES else params


def recognise(outcomes: list, shapes: list, levels: list[str], catalogue, params: Settings) -> tuple[list, list]:
    """The recognition's two steps for every object: its kind (:class:`~twinreg.recognition.kinds.KindResult`)
    from the catalogue's nearest references by size and level of symmetry (:mod:`twinreg.recognition.kinds`; one
    query for the references, numpy for the rest), and its model kept only at ``params.min_confidence`` or
    above, of the object's kind (:func:`~twinreg.recognition.decide.decide`). Returns (the matching outcomes, the
    kinds)."""
    refs = References.of_catalogue(catalogue, params)
    kinds = [kind_of(s, level, refs, params) for s, level in zip(shapes, levels)]
    return decide(outcomes, kinds, refs, params.min_confidence)


def types_of(labels, outcomes: list, kinds: list | None, params: Settings, spacing=None) -> list[int]:
    """Each object's type (:func:`twinreg.recognition.kinds.object_types`): its taxonomy group split by kind, by
    decided model and by size, two objects of a type no farther apart in size than the catalogue's size window
    (``params.matching.size_tol`` plus ``params.matching.size_spacing_k`` times the objects' median point ``spacing``).
    Twice the window grouped more of a sparse scan's copies, but let a type's shape outgrow a member cut by the scan's
    edge by over 3 m on an AHN tile. Poles without a model group by kind and size alone
    (``params.fusion.pole_ratio``)."""
    s = float(np.median(spacing)) if spacing is not None and len(spacing) else 0.0
    return object_types(labels, [k.kind for k in kinds] if kinds is not None else None,
                        sizes=[res.shape.size.as_array() for res in outcomes],
                        models=[res.match.name if res.match is not None else None for res in outcomes],
                        tol=params.matching.size_tol + params.matching.size_spacing_k * s,
                        pole_ratio=params.fusion.pole_ratio)


def fuse(types: list[int], outcomes: list, clouds: list, levels: list | None, params: Settings,
         timing: dict | None = None, kinds: list | None = None, helper=None, fork: bool = False) -> dict:
    """The fused shape of every type whose members have no decided model (:func:`twinreg.shapes.fuse.fuse_type`:
    the members co-registered, their points gathered and completed by the type's level of symmetry, meshed), by
    type: ``(member indices, FusedShape)``. ``clouds``: each object's points (the scene frame); the type's level is
    its members' most common one. Types whose members have too few points together (``params.fusion.min_points``)
    keep their boxes, but for vehicles (``kinds``), which get the kind's template: a body lofted from each one's
    own sections (:func:`twinreg.shapes.fuse.generic_solid`; keyed ``"<type>:<index>"``). In a type that is not
    of vehicles (a van's roof is all a scan sees of it), parts whose points all stand over
    ``params.fusion.hang_height`` hang (a lamp's arm, a sign's plate, a shelter's roof).

    With a ``helper`` (a :class:`~twinreg.process.helpers.Painter`: a scene's distance helper, idle once the
    matching is done), about half the types' work (by points) is sent to it and fused there while this process
    fuses the rest: the same calls, so the same shapes; one it does not answer in time is fused here. Without one,
    ``fork`` (a city's export: its Dask workers are gone, the second core idle) sends that half to a child forked for
    it (:class:`~twinreg.process.helpers.Forked`: the members' points inherited, not sent) when the types hold at
    least ``FORK_MIN_POINTS`` points."""
    t0 = time.perf_counter()
    groups: dict = {}
    for k, (t, res) in enumerate(zip(types, outcomes)):
        if res.match is None:
            groups.setdefault(t, []).append(k)
    out: dict = {}
    calls, order = [], []  # the shapes in the order of the types (the generic ones where their type is)
    for t, ks in groups.items():
        if sum(len(clouds[k]) for k in ks) < params.fusion.min_points:
            for k in ks:
                got = generic_solid(outcomes[k].shape) if kinds is not None and kinds[k].kind in VEHICLES else None
                if got is not None:
                    out[f"{t}:{k}"] = ([k], FusedShape(*got, np.eye(4)[None], {"members": 1}, np.zeros(1), "generic"))
                    order.append(f"{t}:{k}")
            continue
        level = Counter(levels[k] for k in ks).most_common(1)[0][0] if levels is not None else "mirror"
        vehicles = kinds is not None and Counter(kinds[k].kind for k in ks).most_common(1)[0][0] in VEHICLES
        order.append(t)
        calls.append((t, ks, ([clouds[k] for k in ks], [outcomes[k].shape for k in ks], level, params,
                              None if vehicles else params.fusion.hang_height)))
    forked = helper is None and fork and len(calls) >= 2 and _points(calls) >= FORK_MIN_POINTS
    # the helper, forked before this process took its compiled kernels, fuses with the numpy references
    slower = FUSE_HELPER_SLOWER if not forked and kernels_in_use() else 1.0
    sent, here = _shared_out(calls, forked or (helper is not None and len(calls) >= 2), slower)
    # one message each way (a call a type, sent one after another, could fill both pipes: each side waiting for the
    # other to read)
    job = None
    if sent:
        sent_calls = [args for _, _, args in sent]
        job = Forked(fuse_types, sent_calls) if forked else Pending(helper, fuse_types, sent_calls)
    for t, ks, args in here:
        out[t] = (ks, _fused(args))
    if job is not None:
        timeout = HELPER_TIMEOUT_S + FUSE_S_PER_POINT * _points(sent)
        for (t, ks, _), shape in zip(sent, job.wait(timeout=timeout)):
            out[t] = (ks, shape)
    if timing is not None:
        timing["shapes"] = time.perf_counter() - t0
    return {t: out[t] for t in order}


def _fused(call: tuple):
    """:func:`~twinreg.shapes.fuse.fuse_type` of one of :func:`fuse`'s calls: (clouds, shapes, level, params,
    hang)."""
    clouds, shapes, level, params, hang = call
    return fuse_type(clouds, shapes, level, params, hang=hang)


def fuse_types(calls: list) -> list:
    """The fused shape of each of :func:`fuse`'s calls (what it sends its helper)."""
    return [_fused(call) for call in calls]


#: how long the types sent to the helper may take to fuse there, beyond HELPER_TIMEOUT_S, before they are fused here
#: (s a point of their members)
FUSE_S_PER_POINT = 1e-4
#: a fusing call's fixed work, in its members' points (about 3.5 ms against 8 us a point, KITTI 000000's 59 types)
FUSE_CALL_POINTS = 400
#: how much longer the distance helper takes to fuse a type than this process once its compiled kernels are in use
#: (KITTI 000000: 23,701 points fused there in 0.70 s against 23,706 here in 0.45 s)
FUSE_HELPER_SLOWER = 1.5
#: the fewest points of the types to fuse for which a city's export forks a child to fuse half of them (a fork and
#: the shapes' way back cost tens of milliseconds; the copied city's 784 copies of one design hold 740,000)
FORK_MIN_POINTS = 100_000


def _points(calls: list) -> int:
    """The members' points of :func:`fuse`'s calls ``(type, member indices, (clouds, ...))``: their work."""
    return sum(len(c) for _, _, args in calls for c in args[0])


def _shared_out(calls: list, share: bool, slower: float = 1.0) -> tuple[list, list]:
    """The fusing calls split in two of about equal work (their members' points; the largest first, each to the
    lighter side: :func:`~twinreg.process.helpers.apart`): those for the helper, those for this process, each in
    the given order; all here when not ``share``."""
    if not share:
        return [], calls
    theirs = set(apart([_points([call]) + FUSE_CALL_POINTS for call in calls], slower=slower))
    return [c for k, c in enumerate(calls) if k in theirs], [c for k, c in enumerate(calls) if k not in theirs]


def finish(ids: list[str], n_points: list[int], outcomes: list, shapes: list, labels, offsets: list,
           levels: list, spacing: list, clouds_of, georef, models, catalogue, params: Settings, timing: dict,
           progress=None, fork: bool = False) -> tuple[list, list]:
    """What a scene and a city both do once every object is matched: the kinds recognised and the models under the
    floor withdrawn (:func:`recognise`), the types (:func:`types_of`), the types without a model fused
    (:func:`fuse`; ``clouds_of(outcomes)`` gives each object's points, read only then: a city keeps them in its
    cells' files), every object placed (:func:`place`). Returns the outcomes (after the floor) and the placed
    objects."""
    outcomes, kinds = recognise(outcomes, shapes, levels, catalogue, params)
    types = types_of(labels, outcomes, kinds, params, spacing)
    say(progress, "shapes of the types without a model")
    helper = getattr(getattr(models, "prober", None), "helper", None)
    fused = fuse(types, outcomes, clouds_of(outcomes), levels, params, timing, kinds, helper=helper, fork=fork)
    placed = place(ids, n_points, outcomes, labels, offsets, georef, models, kinds, levels, types, fused)
    return outcomes, placed


def place(ids: list[str], n_points: list[int], outcomes: list, labels, offsets: list, georef, models,
          kinds: list | None = None, levels: list | None = None, types: list | None = None,
          fused: dict | None = None) -> list:
    """Place every object: its :class:`~twinreg.export.objects.PlacedObject` (the mesh at its pose, where it is
    on Earth, its kind and type, its twin.json record) from its matching outcome, its taxonomy label, ``offsets``
    (each (3,), its local frame to the scene frame) and its recognised kind and level of symmetry
    (:func:`recognise`; None: not recognised), its ``types`` (:func:`types_of`; None: computed here) and the
    ``fused`` shapes of types without a model (:func:`fuse`; None: boxes). Every object's lat/lon and bearing come
    from two vectorised transformations (one per object took 8 s at 5,000 objects)."""
    if types is None:
        types = types_of(labels, outcomes, kinds, models.params)
    shaped = {}
    for t, (ks, fs) in (fused or {}).items():
        for i, k in enumerate(ks):
            shaped[k] = (f"fused{t}" if fs.source == "fused" else f"generic_{ids[k]}", fs.vertices, fs.faces,
                         fused_pose(outcomes[k].shape, fs.member_poses[i]),
                         {**fs.quality, "rmse_m": round(float(fs.rmse_m[i]), 4)} if fs.source == "fused" else None,
                         fs.source)
    poses = [pose(res) for res in outcomes]
    poses = [(c, float(np.arctan2(shaped[k][3][1, 0], shaped[k][3][0, 0])) if k in shaped else h)
             for k, (c, h) in enumerate(poses)]
    centres = np.array([c + np.asarray(off) for (c, _), off in zip(poses, offsets)]).reshape(-1, 3)
    lonlat, bearings = georef.placements(centres, [h for _, h in poses])
    members = Counter(types)
    placed = []
    for k, (oid, n, res, label, off) in enumerate(zip(ids, n_points, outcomes, labels, offsets)):
        p = place_object(oid, n, res, int(label), np.asarray(off),
                         (float(lonlat[k, 0]), float(lonlat[k, 1]), float(bearings[k])), models, shaped.get(k))
        p.type, p.members = types[k], members[types[k]]
        if kinds is not None:
            p.kind, p.level = kinds[k], levels[k]
            if res.match is None:
                p.candidates = near_candidates(res.shape, kinds[k], models, models.params)
        p.doc = object_record(p, georef)
        placed.append(p)
    return placed
