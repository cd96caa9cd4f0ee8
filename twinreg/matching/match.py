"""Matching detected objects to catalogue models (paper 4.3, and beyond it for sparse scans and large catalogues).

1. Candidates (:mod:`twinreg.matching.prefilter`): every model's descriptor is read once; an object's candidates are the
   models in its density-aware size window, ranked by descriptor (the best ``matching.register_k``), and the
   ``matching.nearest_k`` nearest outside the window.
2. Registration (the paper): each candidate's sections are registered to the object's over rz in {0, pi/2, pi,
   3pi/2}, a continuous tz and a small axial shift du, and ranked by RMSE. Objects of one cluster share work: the
   cluster's first object (its leader) tries every candidate, the others first the leader's favourites and their
   own nearest, and all of their candidates only when those fit clearly worse (by ``matching.share_margin``).
   Where the leader's model explains it cleanly, a member is first decided among the leader's contenders alone
   (:meth:`_Matcher.as_type`: the models that came within ``matching.refine_sigma`` noise units of the leader's
   winner): it keeps the leader's model when it wins there and scores within ``matching.type_slack`` noise units of
   its leader, and is decided in full otherwise.
3. Decision (:mod:`twinreg.matching.decision`), when the object's points are given: the best
``matching.accept_candidates``
   are placed, their pose refined on the points (:mod:`twinreg.matching.refine`), checked
   (:mod:`twinreg.matching.acceptance`) and scored on all the evidence; the lowest acceptable score wins, with a
   confidence, the models it cannot be told from, and whether it lies outside the size window. An object no
   candidate explains gets no model (a box, a skip or a kiosk of car size), with the reason.
"""

from __future__ import annotations

import time
from collections import Counter
from dataclasses import dataclass, field, fields
from typing import NamedTuple

import numpy as np

import cosco
from cosco.arrays import point_spacing
from cosco.frames import yaw_pose
from cosco.nearest import BoundedTree
from cosco.sections import measure_size

from ..catalogue.repository import Catalogue
from ..settings import DEFAULT, Settings
from .acceptance import sample_cloud
from .cache import ModelCache
from .decision import confidence_of, copy_factors, decide, evidence
from .refine import free_pose, refine


class Candidate(NamedTuple):
    """One catalogue model registered to one object by its sections: the registration and the model's id."""

    reg: cosco.Registration
    model_id: int


@dataclass
class MatchStats:
    """What a matching did: its stages' seconds, its registration trials, the object-model pairs a full search
    would have tried, the objects no model's size window held, the trials the clusters saved, and each cluster's
    leader's ranking (``{label: (model ids, best RMSE)}``, for members matched in another call). Batches of a
    city add up with :meth:`add`."""

    prefilter_s: float = 0.0  # s, size windows
    model_prep_s: float = 0.0  # s, models loaded
    registration_s: float = 0.0  # s, section registration
    verification_s: float = 0.0  # s, acceptance and decision
    n_trials: int = 0  # registrations tried
    n_pairs_without_prefilter: int = 0  # a full search's pairs
    n_without_window: int = 0  # objects no window held
    n_trials_saved_by_clusters: int = 0  # by the leaders' rankings
    n_type_offered: int = 0  # members decided first among their leader's contenders
    n_type_decided: int = 0  # of them, kept the leader's model
    n_forked: int = 0  # objects matched in a forked child (match_objects' split)
    leaders: dict = field(default_factory=dict)

    def add(self, other: "MatchStats") -> None:
        """Add another call's counts and seconds to these (its leaders joined to these)."""
        for f in fields(self):
            if f.name != "leaders":
                setattr(self, f.name, getattr(self, f.name) + getattr(other, f.name))
        self.leaders.update(other.leaders)


@dataclass
class Match:
    """A registered model: ``transform`` (4, 4) takes the model's normalised mesh to the scene (local frame);
    ``heading`` (rad) is the direction of the model's front in the scene."""

    model_id: int
    name: str
    rmse: float
    rz: float
    tz: float
    du: float
    transform: np.ndarray
    heading: float
    centre: np.ndarray
    runner_up: dict | None = None
    n_candidates: int = 0
    n_trials: int = 0
    verdict: object = None
    confidence: float | None = None
    margin_sigma: float | None = None
    ambiguous_with: list = field(default_factory=list)
    outside_tolerance: bool = False
    evidence: dict | None = None
    decided_by: str = "object"  # "type": a member decided among its leader's contenders (_Matcher.as_type)


@dataclass
class ObjectMatch:
    """One object's outcome: its COSCO shape, its match (or None with a reason, in words and as one of
    :data:`REASON_CODES`)."""

    shape: cosco.ObjectShape
    match: Match | None
    reason: str = ""
    candidates: list = field(default_factory=list)
    rejected: dict | None = None
    reason_code: str | None = None


#: why an object got no model, as GIS tables filter it: no catalogue model of its size; the best model leaves too
#: many of its points unexplained; fits only sunk into the ground (taller than the object); only floating above it
#: (lower); leaves too much of its top surface unseen; its best model's confidence is under the floor
#: (:func:`twinreg.recognition.decide.apply_floor`)
REASON_CODES = ("no_model_of_this_size", "points_unexplained", "model_too_tall", "model_too_low", "top_unseen",
                "under_floor", "kind_not_model")


def _rot(a: float) -> np.ndarray:
    return yaw_pose(a)


def _shift(x: float, y: float, z: float) -> np.ndarray:
    m = np.eye(4)
    m[:3, 3] = [x, y, z]
    return m


def placement(obj_frame: cosco.Frame, model_frame: cosco.Frame, reg: cosco.Registration) -> np.ndarray:
    """(4, 4) transform: model coordinates -> model frame -> (registration) object frame -> scene."""
    to_model_frame = _rot(-model_frame.heading) @ _shift(-model_frame.origin_xy[0], -model_frame.origin_xy[1],
                                                          -model_frame.ground_z)
    registered = _shift(reg.du, 0.0, reg.tz) @ _rot(reg.rz)
    to_scene = _shift(obj_frame.origin_xy[0], obj_frame.origin_xy[1], obj_frame.ground_z) @ _rot(obj_frame.heading)
    return to_scene @ registered @ to_model_frame


def quarter_turned(m: np.ndarray, obj_heading: float, model_heading: float) -> bool:
    """Whether the model placed by ``m`` (4, 4) lies with its frame's length (its heading ``model_heading`` in its
    own coordinates) nearer the object's width than its length (the object's frame heading ``obj_heading``): the
    registration turned it a quarter.

    >>> m = placement(cosco.Frame(np.zeros(2), 0.3, 0.0), cosco.Frame(np.zeros(2), 0.1, 0.0),
    ...               cosco.Registration(0.0, np.pi / 2, 0.0, 0.0))
    >>> quarter_turned(m, 0.3, 0.1), quarter_turned(np.eye(4), 0.3, 0.3)
    (True, False)
    """
    turn = np.arctan2(m[1, 0], m[0, 0]) + model_heading - obj_heading
    return bool(abs(np.sin(turn)) > abs(np.cos(turn)))


def _trial(obj_pair, cache: ModelCache, model_id: int, params: Settings):
    return cosco.register_sections(obj_pair, cache.pair(model_id), params)


@dataclass
class Evidence:
    """The points an object's best candidates are verified against (:mod:`twinreg.matching.acceptance`):
    ``clouds``, each object's points ((n, 3) metres, the frame of its shape); ``noise``, the scan's range noise (m),
    one value or one per object (a city's tiles); ``spacings``, each object's point spacing (m) when ``clouds``
    are samples of the objects' points, else None (measured on the clouds); ``seen``, where each object's
    scanners could see (a mobile survey's trajectory), None: everywhere."""

    clouds: list
    noise: object
    spacings: list | None = None
    seen: list | None = None  # each object's cosco.visibility.SeenGrid (or None), the clouds' frame

    def noise_of(self, i: int):
        return self.noise if self.noise is None or np.ndim(self.noise) == 0 else float(self.noise[i])


def match_objects(shapes: list[cosco.ObjectShape], catalogue: Catalogue, labels: np.ndarray | None = None,
                  params: Settings = DEFAULT, evidence: Evidence | None = None, cache: ModelCache | None = None,
                  leaders: dict | None = None, done=None, split: bool = False) -> tuple[list[ObjectMatch], MatchStats]:
    """Match every object; returns the per-object outcomes and statistics (trials, timings); ``done(k, n)`` is
    called as each of the n objects is decided.

    labels : cluster label per object (objects of one cluster share work), or None. evidence : the points to
    verify the best candidates with (:class:`Evidence`); without it the lowest RMSE wins unverified. leaders :
    ``{label: (ranking, best RMSE, type decision)}`` of clusters whose leader was matched in another call
    (``stats.leaders`` of that call): all the objects given for those labels are members, so one cluster's members
    can be matched in several batches with exactly the outcome of one call. cache : a :class:`ModelCache` to fill
    (the export then reuses the models' rows, meshes and sections), or None. split : half the clusters (by their
    expected work) matched in a child forked here, on the other core (:func:`_forked_half`): the same outcomes.
    """
    m = _Matcher(shapes, catalogue, params, evidence, ModelCache(catalogue, params) if cache is None else cache)
    # the distance fields of a model are built the first time it is tried (counted in the registration time): a
    # member of a cluster tries only a few of its candidates. Order: per cluster, the leader (its first object)
    # first: it tries every candidate; then the members
    groups: dict[int, list[int]] = {}
    for i in range(len(shapes)):
        groups.setdefault(int(labels[i]) if labels is not None else -1 - i, []).append(i)
    known = {g for g in groups if leaders is not None and labels is not None and g in leaders}
    t = time.perf_counter()
    there = _forked_half(m, groups, known, leaders, labels is not None) if split else None
    mine = [g for g in groups if there is None or g not in there.groups]
    _match_groups(m, {g: groups[g] for g in mine}, known, leaders, labels is not None, done, len(shapes))
    if there is not None:
        there.join(m, time.perf_counter() - t)
        if done is not None:  # the child's objects counted once they are back
            done(m.n_done, len(shapes))
    wall = time.perf_counter() - t
    if there is not None:  # the two processes' seconds as shares of the call's
        m.stats.verification_s *= wall / max(there.work_s, 1e-9)
    m.stats.registration_s = wall - m.stats.verification_s
    m.stats.n_trials_saved_by_clusters = sum(len(c) for c in m.cands) - m.stats.n_trials
    return m.results, m.stats


def _match_groups(m: "_Matcher", groups: dict, known: set, leaders: dict | None, labelled: bool, done=None,
                  n: int = 0) -> None:
    """Decide the objects of ``groups`` (``{label: object indices}``), each cluster's leader first; ``known``: the
    labels whose leader was matched in another call (its ranking in ``leaders``)."""
    for label, members in groups.items():
        # a cluster whose leader was matched elsewhere (a batch of leaders) brings the leader's ranking along
        ranking = (list(leaders[label][0]), float(leaders[label][1]), *leaders[label][2:]) if label in known else None
        for i in members:
            ranking = m.match(i, ranking)
            if labelled and label not in known:
                m.stats.leaders.setdefault(label, ranking)
            if done is not None:
                done(m.n_done, n)


#: the fewest objects whose matching is split with a forked child (below, the fork and the answers' return cost more
#: than half the matching)
SPLIT_MIN_OBJECTS = 30


def _work(m: "_Matcher", members: list[int]) -> float:
    """A cluster's expected matching work: its leader screens every candidate, a member a few."""
    share = max(int(m.params.matching.cluster_share), 1)
    return 1.0 + len(m.cands[members[0]]) + sum(1.0 + min(len(m.cands[i]), share) for i in members[1:])


class _Half:
    """The clusters ``groups`` matched in a child forked now (:class:`~twinreg.process.helpers.Forked`), beside
    this process's own; :meth:`join` adds its outcomes and statistics to this call's (the clusters matched here when
    the child failed, died or did not answer in time)."""

    def __init__(self, m: "_Matcher", groups: dict, known: set, leaders, labelled: bool):
        import os

        from ..process.helpers import Forked

        self.groups = groups
        self.work_s = 0.0  # both processes' seconds of matching (set by join)
        self.job = Forked(_child_half, m, groups, known, leaders, labelled, os.getpid())

    def join(self, m: "_Matcher", mine_s: float) -> None:
        """Wait for the child's outcomes (``mine_s``: this process's seconds of matching, for the timings)."""
        from ..process.helpers import HELPER_TIMEOUT_S

        n = sum(len(v) for v in self.groups.values())
        results, stats = self.job.wait(timeout=HELPER_TIMEOUT_S + CHILD_S_PER_OBJECT * n)
        for i, r in results.items():
            m.results[i] = r
        self.work_s = mine_s + stats.registration_s + stats.verification_s
        stats.registration_s = 0.0
        m.stats.add(stats)
        if self.job.ran_apart:  # (else they were matched here, and counted as they were)
            m.n_done += len(results)
            m.stats.n_forked += len(results)


#: the share of a sweep's matching work that importing open3d takes (about 0.25 s of 1 s): the half that imports it
#: before the fork (this process's) takes that much less work
IMPORT_SHARE = 0.2

#: how long the child's half may take, beyond HELPER_TIMEOUT_S, before it is stopped and its clusters matched here
#: (s an object; a sweep's objects take about 15 ms)
CHILD_S_PER_OBJECT = 1.0


def _child_half(m: "_Matcher", groups: dict, known: set, leaders, labelled: bool, parent: int):
    """In the forked child (or in ``parent`` when the child failed): the clusters ``groups`` matched; their outcomes
    by object and the statistics of that work alone (``registration_s`` its seconds less the verification's)."""
    import os

    own = m.stats
    m.stats = MatchStats()
    try:
        if os.getpid() != parent:
            m.cache.catalogue.after_fork()  # the catalogue the child reads its models from
        t = time.perf_counter()
        _match_groups(m, groups, known, leaders, labelled)
        m.stats.registration_s = time.perf_counter() - t - m.stats.verification_s
        return {i: m.results[i] for v in groups.values() for i in v}, m.stats
    finally:
        m.stats = own


def _forked_half(m: "_Matcher", groups: dict, known: set, leaders, labelled: bool) -> "_Half | None":
    """About half the clusters' work given to a forked child, or None (too few objects, no fork, helpers off, or
    distances asked of a helper process, whose pipe one process alone may use)."""
    import os
    import sys

    from ..o3d import fork_safe, load
    from ..process.helpers import apart

    if len(m.shapes) < SPLIT_MIN_OBJECTS or len(groups) < 2 or os.environ.get("TWINREG_NO_HELPER"):
        return None
    prober = m.cache.prober
    if prober is not None and prober.helper is not None and not prober.here:
        return None
    if not fork_safe():  # open3d's thread pools, once started here, are not the child's to use
        return None
    labels = list(groups)
    work = [_work(m, groups[g]) for g in labels]
    head_start = 0.0
    if m.evidence is not None and "open3d" not in sys.modules:
        load()  # once, before the fork: the child's distances need it too; this half waits for it (its import)
        head_start = IMPORT_SHARE * sum(work)
    return _Half(m, {labels[k]: groups[labels[k]] for k in apart(work, head_start)}, known, leaders, labelled)


class _Matcher:
    """One call's state: the objects' section pairs, their prefiltered candidates (``found``, ``cands``), the
    model cache, the statistics and the outcomes so far."""

    def __init__(self, shapes, catalogue, params: Settings, evidence: Evidence | None, cache: ModelCache):
        self.shapes, self.params, self.evidence, self.cache = shapes, params, evidence, cache
        self.stats = MatchStats()
        self.pairs = [cosco.SectionPair(s.sections, params) for s in shapes]
        t = time.perf_counter()
        index = cache.size_index()
        clouds = evidence.clouds if evidence is not None else [None] * len(shapes)
        spacings = evidence.spacings if evidence is not None else None
        self.spacings = spacings if spacings is not None else [
            point_spacing(np.asarray(c)) if c is not None and len(c) >= 3 else 0.0 for c in clouds]
        self.found = [index.candidates(s, self.spacings[i], params) for i, s in enumerate(shapes)]
        self.cands = [f.all for f in self.found]
        tried = Counter(m for c in self.cands for m in c)  # each candidate model: how many objects try it
        cache.add_rows(catalogue.rows(sorted(set(tried) - set(cache.known()))))
        # the most tried models first: their distance indexes are built on the helper while this process registers
        cache.prepare_surfaces(sorted(tried, key=lambda m: (-tried[m], m)))
        self.stats.prefilter_s = time.perf_counter() - t
        self.stats.n_pairs_without_prefilter = len(index) * len(shapes)
        self.stats.n_without_window = sum(f.outside for f in self.found)
        self.results: list[ObjectMatch | None] = [None] * len(shapes)
        self.n_done = 0

    def match(self, i: int, ranking: tuple | None) -> tuple:
        """Decide object ``i``: a leader (``ranking`` None) tries every candidate; a member is first decided among
        its leader's contenders where the leader's model explains it cleanly (:meth:`as_type`), else tries its
        leader's favourites first (``ranking``: the leader's models best first, its best RMSE and its type
        decision). Returns the ranking the cluster's members follow."""
        if ranking is not None and len(ranking) > 2 and ranking[2] is not None and self.params.matching.type_reuse:
            self.stats.n_type_offered += 1
            out = self.as_type(i, ranking)
            if out is not None:
                self.stats.n_type_decided += 1
                self.results[i] = out
                self.n_done += 1
                return ranking
        ids, share = self.cands[i], self.params.matching.cluster_share
        if ranking is not None and share and ranking[0]:
            # the leader's favourites, and this object's own nearest by descriptor (a cluster may hold two kinds
            # of car that the leader's ranking alone would not tell apart)
            led = ranking[0][:share]
            preferred = [m for m in led if m in ids] + [m for m in ids[:share] if m not in led]
            ids = preferred or ids
        regs = _registrations(self.pairs[i], ids, self.cands[i], self.cache, self.params,
                              None if ranking is None else ranking[1], self.stats)
        leader = ranking is None
        if leader:
            ranking = ([c.model_id for c in regs], regs[0].reg.rmse if regs else np.inf)
        ev = self.evidence
        t_v = time.perf_counter()
        self.results[i], decision = _outcome(self.shapes[i], regs, self.cache, self.found[i],
                                             ev.clouds[i] if ev is not None else None,
                                             ev.noise_of(i) if ev is not None else None, self.pairs[i], self.params,
                                             self.spacings[i], ev.seen[i] if ev is not None and ev.seen is not None
                                             else None)
        self.stats.verification_s += time.perf_counter() - t_v
        self.n_done += 1
        if leader:
            ranking = (*ranking, _type_decision(self.results[i], decision, ev.noise_of(i) if ev is not None else None,
                                                self.spacings[i], self.cache, self.params))
        return ranking

    def as_type(self, i: int, ranking: tuple) -> ObjectMatch | None:
        """Member ``i`` decided among its leader's contenders alone (``ranking[2]``, :func:`_type_decision`): the
        models that came within ``matching.refine_sigma`` noise units of the leader's winner are registered, placed
        and refined on the member's points (and the winner end for end, where the leader's two ends came that
        close); what lay farther behind for the leader is taken to lie as far behind for a member that fits the
        winner as well: its margin is at most the leader's to the first of them, less what the member scores behind
        its leader. None (decide it in full) when a contender is not among its candidates, its sections fit the
        winner worse than the leader's by ``matching.share_margin``, another contender wins, none is acceptable,
        it scores more than ``matching.type_slack`` noise units behind its leader, or it explains the winner as a copy
        of its design worse or better than its leader did (:func:`_copy_factor`, by ``matching.type_fit_slack``:
        a member that explains the winner as loosely as its leader gets the leader's loose decision, with its own
        confidence; one that explains it better may be a better-seen copy of another design)."""
        rec, p, ev = ranking[2], self.params.matching, self.evidence
        mid = int(rec["model_id"])
        ids = [mid] + [int(c) for c in rec["contenders"]]
        found = self.found[i]
        if any(c not in self.cands[i] or c in found.nearest for c in ids):
            return None
        pair = self.pairs[i]
        regs = [Candidate(_trial(pair, self.cache, c, self.params), c) for c in ids]
        self.stats.n_trials += len(ids)
        if regs[0].reg.rmse > ranking[1] + p.share_margin:
            return None
        # the winner polished, as the full path's is before its refinement (_decided); the others as registered
        regs[0] = regs[0]._replace(reg=cosco.polished(pair, self.cache.pair(mid), regs[0].reg, self.params))
        t = time.perf_counter()  # the registrations' time is the rest of the call's (match_objects)
        try:
            noise = ev.noise_of(i)
            shape = self.shapes[i]
            # a clean leader's members are judged on fewer points; a loose leader sits on the design test's ramp,
            # where a member's copy factor must be measured as closely as its leader's was
            scorer = _Scorer(shape, self.cache, ev.clouds[i], noise, self.spacings[i], self.params,
                             ev.seen[i] if ev.seen is not None else None,
                             judged=p.type_judged_points if rec["copy"] >= 1.0 else 0)
            found_e = [scorer.placed_refined(c.reg, c.model_id) for c in regs]
            if rec["ends"] <= p.refine_sigma:  # the winner end for end: its leader's other end came as close
                turned = scorer.placed_refined(_turned(regs[0].reg), mid)
                if turned.score < found_e[0].score:
                    found_e[0] = turned
            approximate = frozenset(c for c in ids if made_from_scans(self.cache.row(c)))
            decision = decide(found_e, noise, self.params, self.spacings[i], approximate)
            best = decision.best
            if best is None or best.model_id != mid:
                return None
            behind = (best.score - rec["score"]) / noise
            copy = _copy_factor(best, noise, self.spacings[i], self.params, approximate)
            if behind > p.type_slack or abs(copy - rec["copy"]) > p.type_fit_slack:
                return None
            margin = decision.margin_sigma if len(ids) > 1 or rec["beyond"] is None else np.inf
            if rec["beyond"] is not None:
                margin = min(margin, max(rec["beyond"] - max(behind, 0.0), 0.0))
            decision.margin_sigma = float(margin)
            decision.confidence = confidence_of(best, margin, noise, self.params, self.spacings[i], approximate)
            decision.ends_sigma = rec["ends"]
            out = _placed(shape, regs, self.cache, found, decision, self.params)
            if len(ids) == 1:
                out.match.runner_up = dict(rec["runner_up"]) if rec["runner_up"] is not None else None
            out.match.decided_by = "type"
            out.candidates = ids + [c for c in ranking[0] if c not in ids and c in self.cands[i]]
            return out
        finally:
            self.stats.verification_s += time.perf_counter() - t


def _copy_factor(best, noise: float, spacing: float, params: Settings, approximate) -> float:
    """The product of ``best``'s :func:`~twinreg.matching.decision.copy_factors` (1: it explains its object as a
    copy of its design). A member more than ``matching.type_fit_slack`` from its leader's (under it: another design
    grouped with the leader's, a sparse or occluded copy; over it, where the leader explained only loosely: a
    better-seen copy, perhaps of another design) is decided in full."""
    fit, design = copy_factors(best, noise, params, spacing, approximate)
    return float(fit if design is None else fit * design)


def _turned(reg: cosco.Registration) -> cosco.Registration:
    """``reg`` end for end: turned half a turn about the vertical."""
    return cosco.Registration(reg.rmse, reg.rz + np.pi, reg.tz, reg.du)


def _type_decision(result: ObjectMatch, decision, noise, spacing: float, cache: ModelCache,
                   params: Settings) -> dict | None:
    """What a cluster's leader's decision tells its members (:meth:`_Matcher.as_type`), or None when it tells
    them nothing (no model; one outside the size window; a winner that did not also score lowest). ``model_id``
    and ``score`` (m): the winner; ``copy``: how closely it explains the leader as a copy of its design
    (:func:`_copy_factor`: 1 cleanly; under 1 an uncatalogued design's nearest, whose members are decided as
    loosely, each with its own confidence, where they explain it as loosely);
    ``contenders``: the other models scored within ``matching.refine_sigma`` noise units of it; ``beyond``: the
    margin (noise units) to the first model farther behind (None: none was); ``ends``: between the winner's two ends
    (noise units); ``runner_up``: the first of those beyond, by id and name (None: none)."""
    if decision is None or decision.best is None or result.match is None or result.match.outside_tolerance:
        return None
    if decision.best.extra.get("free"):  # placed at any heading: its members' sections cannot follow it
        return None
    best = decision.best
    if decision.scored[0] is not best:
        return None
    reach = params.matching.refine_sigma
    gaps = [(e.score - best.score) / noise for e in decision.scored[1:]]
    contenders = [int(e.model_id) for e, g in zip(decision.scored[1:], gaps) if g <= reach]
    far = [(g, e) for e, g in zip(decision.scored[1:], gaps) if g > reach]
    if len(set(contenders + [int(best.model_id)])) != len(contenders) + 1:
        return None  # a model twice (one scored at each end): decided in full
    approximate = frozenset([best.model_id]) if made_from_scans(cache.row(best.model_id)) else frozenset()
    copy = _copy_factor(best, noise, spacing, params, approximate)
    return {"model_id": int(best.model_id), "score": float(best.score), "copy": copy, "contenders": contenders,
            "beyond": float(far[0][0]) if far else None, "ends": float(decision.ends_sigma),
            "runner_up": {"model_id": int(far[0][1].model_id), "name": cache.row(far[0][1].model_id).name,
                          "from_type": True} if far else None}


def _registrations(pair, ids, all_ids, cache: ModelCache, params: Settings, leader_best,
                   stats: MatchStats) -> list:
    """The section registrations of one object to the models ``ids``, best (lowest RMSE) first, the best one
    polished. A member of a cluster (``leader_best``: the RMSE its leader reached) that fits those clearly worse
    than its leader did is not the same kind of car after all: it tries the rest of ``all_ids`` too."""
    regs = []
    for mid in ids:
        regs.append(Candidate(_trial(pair, cache, mid, params), mid))
        stats.n_trials += 1
    regs.sort(key=lambda c: c.reg.rmse)
    if leader_best is not None and regs and regs[0].reg.rmse > leader_best + params.matching.share_margin:
        for mid in [m for m in all_ids if m not in ids]:
            regs.append(Candidate(_trial(pair, cache, mid, params), mid))
            stats.n_trials += 1
        regs.sort(key=lambda c: c.reg.rmse)
    if regs:  # the winner's pose to a few millimetres (shifts below the 2 cm field cell)
        regs[0] = regs[0]._replace(reg=cosco.polished(pair, cache.pair(regs[0].model_id), regs[0].reg, params))
    return regs


class _Scorer:
    """One object's candidates scored on its points (:mod:`twinreg.matching.decision`): ``sample`` the points
    judged (the same sample whether the cloud is all of the object's points, a scene, or already its sample, a city
    cell) and their KD-tree, the object's measured size, the scan's noise and spacing."""

    def __init__(self, shape, cache: ModelCache, cloud, noise, spacing, params: Settings, seen=None,
                 judged: int = 0):
        self.shape, self.cache, self.noise, self.spacing, self.params = shape, cache, noise, spacing, params
        self.judged = judged  # >0: refined poses scored on that many points apart from the refinement's
        self.seen = seen  # where the object's scanners could see (the cloud's frame), None: everywhere
        self.cloud = cloud
        self._every = None  # every point's tree (:meth:`every_tree`), built when first asked
        self.sample = sample_cloud(np.asarray(cloud, dtype=np.float64), params.matching.accept_max_points)
        # the evidence's bounded look-ups compiled where numba is in use (cosco.kernels), else the KD-tree's
        self.tree = BoundedTree(self.sample)
        self.measured = shape.size.as_array()

    def scored(self, reg, mid, m, points_in_model, size=None, tree=None):
        """The evidence of model ``mid`` placed by ``m`` (4, 4), the object's points in its frame (``size``: the
        model's L, W, H along the object's frame, None: its stored ones, turned a quarter where it lies so)."""
        cache = self.cache
        top = cache.top(mid) @ m[:3, :3].T + m[:3, 3]
        row = cache.row(mid)
        if size is None:
            size = np.array([row.length, row.width, row.height])
            if quarter_turned(m, self.shape.frame.heading, cache.frame(mid).heading):
                size = size[[1, 0, 2]]  # its length across the object's (a bus shelter drawn facing its own x axis)
        # the model's lowest point is z = 0 in its frame, and the pose only turns about the vertical
        e = evidence(mid, reg.rmse, cache.surface(mid).distances(points_in_model), top,
                     self.tree if tree is None else tree,
                     size, self.measured, self.noise, self.spacing,
                     self.params, sink=float(self.shape.frame.ground_z - m[2, 3]),
                     top_known=None if self.seen is None else self.seen.known(top))
        e.extra.update(transform=m, rz=float(np.mod(reg.rz, 2 * np.pi)), refined=False)
        return e

    def free(self, reg, mid):
        """The evidence of model ``mid`` (one without symmetry) placed at any heading on the object's points
        (:func:`~twinreg.matching.refine.free_pose`), scored on its judged points; its size the placed model's
        measured in the object's frame as the object's was (an asymmetric model's stored length and width lie along
        axes of its own). ``reg`` (the sections' registration, whose pose it replaces) kept in ``extra["reg"]``."""
        cache, frame, away = self.cache, self.shape.frame, self.away()
        m = free_pose(self.sample, frame.ground_z, cache.coarse_tree(mid), cache.tree(mid), self.params, away)
        placed = cache.geometry(mid).points @ m[:3, :3].T + m[:3, 3]
        size = measure_size(placed, frame, False, self.params).as_array()  # as the object's was measured
        below = away is not None and frame.ground_z + self.measured[2] > float(np.mean(self.seen.views[:, 2]))
        judged = measured_bounds(frame.heading, away, below)
        # its top held to every point: a tree's thousands of points, thinned to the judged sample, would leave
        # most of a crown's top with no point near it
        e = self.scored(reg, mid, m, (self.sample - m[:3, 3]) @ m[:3, :3], size, self.every_tree())
        turn = np.arctan2(m[1, 0], m[0, 0]) + cache.frame(mid).heading - frame.heading
        e.extra.update(rz=float(np.mod(turn, 2 * np.pi)), refined=True, free=True, reg=reg, size=size,
                       judged=judged)
        return e

    def away(self):
        """(2,) the unit vector in plan from the object's scanner positions towards its points' centre, or None
        where they are not known (or stand over it)."""
        views = None if self.seen is None else self.seen.views
        if views is None or not len(views):
            return None
        v = self.sample[:, :2].mean(0) - np.asarray(views, dtype=np.float64)[:, :2].mean(0)
        n = float(np.hypot(*v))
        return v / n if n > 1e-6 else None

    def every_tree(self):
        """A :class:`~cosco.nearest.BoundedTree` of all the object's points (the judged sample's when that is all of
        them), built once for the scorer's candidates."""
        if self._every is None:
            every = np.asarray(self.cloud, dtype=np.float64)
            self._every = BoundedTree(every) if len(every) > len(self.sample) else self.tree
        return self._every

    def placed(self, reg, mid):
        """(the (4, 4) transform, the points in the model's frame) as the section registration placed the
        model."""
        m = placement(self.shape.frame, self.cache.frame(mid), reg)
        # the points go to the model's frame (the inverse of a rotation is its transpose): one index per model
        return m, (self.sample - m[:3, 3]) @ m[:3, :3]

    def screened(self, reg, mid):
        """(evidence, the points in the model's frame) as the section registration placed the model, on the
        ``matching.refine_max_points`` points the refinement would use."""
        m, in_model = self.placed(reg, mid)
        return self.scored(reg, mid, m, sample_cloud(in_model, self.params.matching.refine_max_points)), in_model

    def refined(self, reg, mid, screen):
        """The screened pose (its transform, the points in the model's frame) sharpened on the points: a turn
        about the vertical and a shift (twinreg/matching/refine.py), scored on every point."""
        e, in_model = screen
        return self.refined_from(reg, mid, e.extra["transform"], in_model, e.sink)

    def placed_refined(self, reg, mid):
        """The evidence of model ``mid`` as the registration ``reg`` placed it, refined on the points (no screen);
        ``reg`` kept in its ``extra["reg"]``."""
        m, in_model = self.placed(reg, mid)
        e = self.refined_from(reg, mid, m, in_model, float(self.shape.frame.ground_z - m[2, 3]))
        e.extra["reg"] = reg
        return e

    def refined_from(self, reg, mid, m, in_model, sink: float):
        """The pose ``m`` (the points ``in_model`` in the model's frame; the model ``sink`` m into the object's
        ground) refined and scored on every point (:meth:`refined`)."""
        q = sample_cloud(in_model, self.params.matching.refine_max_points)
        c = refine(q, self.cache.tree(mid), self.params.matching.refine_reach, params=self.params)
        # scanned from the ground (a van's scan lines), the road around the object is measured densely: a model
        # the points sank into it beyond the sink limit (one sloped face seen, the model slid down it) is stood on
        # it and refined again; one within the limit keeps the height its points give (a mesh's lowest vertex is
        # not always where its tyres touch, and a boxy car's side seen from afar pins its height loosely)
        # (the screened sink is the ground's level in the model's frame, as the sections placed it)
        surface = self.shape.surface
        sink_limit = self.params.matching.accept_sink_sigmas * self.noise + self.params.matching.accept_sink_tol
        if surface is not None and surface.along_lines and sink + c[2, 3] > sink_limit:
            c = refine(q, self.cache.tree(mid), self.params.matching.refine_reach, params=self.params,
                       ground=sink)
        judged = held_out(in_model, self.params.matching.refine_max_points, self.judged)
        e = self.scored(reg, mid, m @ np.linalg.inv(c), judged @ c[:3, :3].T + c[:3, 3])
        e.extra["refined"] = True
        return e


def held_out(points: np.ndarray, refined: int, judged: int) -> np.ndarray:
    """The points a refined pose is scored on: all ``points`` where ``judged`` is 0 or the refinement used every
    one of them (no more than ``refined``), else at most ``judged`` of those the refinement did not use
    (:func:`~twinreg.matching.acceptance.sample_cloud`'s stride: a pose is not judged on the points it was fitted
    to), at a regular stride: of an object's ``matching.accept_max_points`` at most, at least a third.

    >>> p = np.arange(1500.0)[:, None] * np.ones(3)
    >>> q = held_out(p, 500, 500)
    >>> len(q), bool(np.isin(q[:, 0], sample_cloud(p, 500)[:, 0]).any())
    (500, False)
    >>> len(held_out(p, 500, 0)), len(held_out(p[:400], 500, 500)), len(held_out(p[:900], 500, 500))
    (1500, 400, 450)
    """
    n = len(points)
    if judged <= 0 or n <= refined:
        return points
    keep = np.ones(n, dtype=bool)
    keep[sample_cloud(np.arange(n), refined)] = False  # the refinement's rows, as it samples them
    rest = np.flatnonzero(keep)
    return points[rest[::int(np.ceil(len(rest) / judged))]]


def _decided(shape, regs, cache: ModelCache, cloud, noise, spacing, params: Settings, seen=None, obj_pair=None):
    """Score the best ``matching.accept_candidates`` registrations on all of the object's evidence
    (:mod:`twinreg.matching.decision`).

    Each candidate is first screened as the section registration placed it, on the ``matching.refine_max_points`` points
    the refinement would use; only the candidates whose screened score lies within ``matching.refine_sigma``
    noise units of the best one's are refined and scored on every point. Refining lowers a score by about one
    noise unit at most, so a candidate further behind can neither win nor come close enough to change the
    confidence: it keeps its screened score (docs/METHOD.md, "Deciding between candidates"). The winner is refined
    from its polished registration (``regs[0]``, the best by RMSE, comes polished; another winner is polished and
    refined again), kept in its evidence's ``extra["reg"]``: the same start whichever path decides it
    (:meth:`_Matcher.as_type`)."""
    scorer = _Scorer(shape, cache, cloud, noise, spacing, params, seen)
    reach = params.matching.refine_sigma * noise
    candidates = list(regs[:params.matching.accept_candidates])
    screens = [scorer.screened(reg, mid) for reg, mid in candidates]
    found = [e for e, _ in screens]
    polished = [j == 0 or obj_pair is None for j in range(len(candidates))]
    for j, (reg, mid) in enumerate(candidates):  # a model without symmetry at any heading too, where its height fits
        if cache.asymmetric(mid) and abs(cache.row(mid).height - scorer.measured[2]) <= params.matching.free_height_tol:
            e = scorer.free(reg, mid)
            if e.score < found[j].score:
                found[j], polished[j] = e, True

    def refine_at(j):
        found[j] = scorer.refined(*candidates[j], screens[j])
        found[j].extra["reg"] = candidates[j].reg

    def polish_at(j):  # the winner from its polished registration (at the end it won at)
        reg, mid = candidates[j]
        turned = found[j].extra.get("turned", False)
        candidates[j] = Candidate(cosco.polished(obj_pair, cache.pair(mid), reg, params), mid)
        polished[j] = True
        p = candidates[j].reg
        found[j] = scorer.placed_refined(_turned(p) if turned else p, mid)
        found[j].extra["turned"] = turned

    best = min((e.score for e in found), default=np.inf)
    for j, e in enumerate(list(found)):
        if e.score <= best + reach and not e.extra["refined"]:
            refine_at(j)
    if found:  # the favourite end for end too: a box-like van's sections hardly tell its front from its back
        k = int(np.argmin([e.score for e in found]))
        if not found[k].extra["refined"]:
            refine_at(k)
        reg, mid = candidates[k]
        turned_reg = _turned(reg)
        screen = scorer.screened(turned_reg, mid)
        turned = scorer.refined(turned_reg, mid, screen) if screen[0].score <= found[k].score + reach else screen[0]
        turned.extra.update(reg=turned_reg, turned=True)
        ends = abs(turned.score - found[k].score) / noise
        if turned.score < found[k].score:
            found[k] = turned
    approximate = frozenset(mid for _, mid in candidates if made_from_scans(cache.row(mid)))
    while True:  # the winner (or, with none acceptable, the best refused) is always one refined
        decision = decide(found, noise, params, spacing, approximate)
        top = decision.best if decision.best is not None else (decision.scored[0] if decision.scored else None)
        j = next((i for i, e in enumerate(found) if e is top), None)
        if j is not None and not found[j].extra["refined"]:
            refine_at(j)
        elif j is not None and decision.best is not None and not polished[j]:
            polish_at(j)
        else:
            decision.ends_sigma = ends if found else None
            return decision


def made_from_scans(row) -> bool:
    """Whether a catalogue model's surface comes from scans (a scanned reference, or a type's fused shape promoted
    by ``add-model --from-twin``): an approximation at the scan's grid, not held to a design's closeness."""
    return (row.source or "mesh") == "scan" or "fused" in (row.tags or ())


def _size_gap_text(gap: np.ndarray) -> str:
    """How a model differs in size from an object (``gap``: its L, W, H minus the object's, m).

    >>> _size_gap_text(np.array([0.36, -0.04, 0.0]))
    '0.36 m longer, 0.04 m narrower'
    """
    words = (("longer", "shorter"), ("wider", "narrower"), ("taller", "lower"))
    out = [f"{abs(g):.2f} m {w[0] if g > 0 else w[1]}" for g, w in zip(gap, words) if abs(g) >= 0.005]
    return ", ".join(out) or "of the same size"


def _outcome(shape: cosco.ObjectShape, regs, cache: ModelCache, found, cloud=None, noise=None,
             obj_pair=None, params: Settings = DEFAULT, spacing=0.0, seen=None) -> tuple:
    """(the object's :class:`ObjectMatch`, the :class:`~twinreg.matching.decision.Decision` it came from, None
    without points) from its registrations ``regs``, best first."""
    if not regs:
        near = cache.size_index().nearest_gap(shape.size.as_array(), spacing, params)
        reason = "no catalogue model within the size tolerance"
        if near is not None:
            cache.add_rows(cache.catalogue.rows([near[0]]))
            reason += f"; the nearest, {cache.row(near[0]).name}, is {_size_gap_text(near[1])} than the object"
        return ObjectMatch(shape, None, reason, [], reason_code="no_model_of_this_size"), None
    decision = None
    if cloud is not None:
        decision = _decided(shape, regs, cache, cloud, noise, spacing, params, seen, obj_pair)
        if decision.best is None:
            best = decision.scored[0]
            name = cache.row(best.model_id).name
            reason = best.reason(name)
            if found.outside:
                near = cache.row(found.nearest[0])
                gap = np.array([near.length, near.width, near.height]) - shape.size.as_array()
                reason = (f"no catalogue model within the size tolerance; the nearest, {near.name}, is "
                          f"{_size_gap_text(gap)} than the object, and none of the nearest fits it ({reason})")
            return ObjectMatch(shape, None, reason, [c.model_id for c in regs],
                               rejected={"name": name, "rmse_m": round(best.rmse, 4), **best.verdict.as_dict(),
                                         **best.as_dict()},
                               reason_code="no_model_of_this_size" if found.outside else best.reason_code()), decision
        k = next(j for j, c in enumerate(regs) if c.model_id == decision.best.model_id)
        # the winner's registration polished (it was, before its refinement; the first by RMSE came polished)
        regs[k] = regs[k]._replace(reg=decision.best.extra.get("reg", regs[k].reg))
        regs.insert(0, regs.pop(k))
    return _placed(shape, regs, cache, found, decision, params), decision


def measured_bounds(heading: float, away, below: bool = False) -> np.ndarray:
    """(2, 3) bool: which bounds of an object's length, width and height (its frame turned ``heading`` rad) the
    scanners measured, the lower (row 0: the object is at least that) and the upper (row 1: at most). From one side
    (``away``, the unit vector in plan from them towards it; None: from everywhere, as from the air): neither along
    the axis nearer that way, whose far part they could not see (a crown's depth from a van); and where the object's
    top is above them (``below``), not its height's upper bound: they saw its top from below (a crown's highest
    leaves behind its lower ones).

    >>> measured_bounds(0.0, None).all(), measured_bounds(0.3, np.array([0.0, 1.0])).tolist()
    (np.True_, [[True, False, True], [True, False, True]])
    >>> measured_bounds(0.3, np.array([0.0, 1.0]), below=True)[1].tolist()
    [True, False, False]
    """
    judged = np.ones((2, 3), dtype=bool)
    if away is not None:
        u = np.array([np.cos(heading), np.sin(heading)])
        judged[:, 0 if abs(u @ away) >= abs(u[0] * away[1] - u[1] * away[0]) else 1] = False
        judged[1, 2] = not below
    return judged


def _placed(shape: cosco.ObjectShape, regs, cache: ModelCache, found, decision, params: Settings) -> ObjectMatch:
    """The :class:`ObjectMatch` of the winner ``regs[0]`` (its ``decision``, or None: the lowest RMSE unverified)."""
    n_candidates = found.n_window
    reg, mid = regs[0].reg, regs[0].model_id
    row = cache.row(mid)
    m = decision.best.extra["transform"] if decision is not None else placement(shape.frame, cache.frame(mid), reg)
    front = m[:2, :2] @ np.array([1.0, 0.0])
    heading = float(np.mod(np.arctan2(front[1], front[0]), 2 * np.pi))
    centre = (m @ np.array([0.0, 0.0, row.height / 2, 1.0]))[:3]
    runner = None
    if decision is not None:
        others = [e for e in decision.scored if e.model_id != mid]
        if others:
            # refined: False when the runner-up was only screened (scored as its registration placed it, on the
            # refinement's points: it lay far behind, docs/METHOD.md "Deciding between candidates")
            runner = {"model_id": others[0].model_id, "name": cache.row(others[0].model_id).name,
                      "rmse_m": round(others[0].rmse, 4), "score_m": round(others[0].score, 4),
                      "refined": bool(others[0].extra["refined"])}
    elif len(regs) > 1:
        r2, m2 = regs[1].reg, regs[1].model_id
        runner = {"model_id": m2, "name": cache.row(m2).name, "rmse_m": round(r2.rmse, 4)}
    rz = decision.best.extra["rz"] if decision is not None else reg.rz
    outside = mid in found.nearest
    if decision is not None and decision.best.extra.get("free"):  # its window along the object's axes, as placed
        lo, hi = found.window  # (along the axes the scanners measured)
        size, judged = decision.best.extra["size"], decision.best.extra["judged"]
        outside = not bool(np.all(((size >= lo) | ~judged[0]) & ((size <= hi) | ~judged[1])))
    match = Match(model_id=mid, name=row.name, rmse=reg.rmse, rz=rz, tz=reg.tz, du=reg.du, transform=m,
                  heading=heading, centre=centre, runner_up=runner, n_candidates=n_candidates, n_trials=len(regs),
                  verdict=decision.best.verdict if decision else None,
                  confidence=(decision.confidence * (params.matching.outside_factor if outside else 1.0)
                              if decision else None),
                  margin_sigma=decision.margin_sigma if decision else None,
                  ambiguous_with=[cache.row(a).name for a in decision.ambiguous_with] if decision else [],
                  outside_tolerance=outside,
                  evidence=decision.best.as_dict() if decision else None)
    return ObjectMatch(shape, match, "", [c.model_id for c in regs])
