"""The global stages of a city run, over every cell's objects: the taxonomy (its comparisons spread over the
workers) and the matching (whole clusters per batch, so that objects of one cluster still share work)."""

from __future__ import annotations

import time

import numpy as np

from ..errors import EngineError
from ..matching.match import MatchStats, ModelCache
from ..stages import taxonomy
from .batches import compare_pairs, guided_sizes, leader_indices, match_batch, match_batches, pair_batches

#: the most a batch holds: a batch of a 500M-point survey's objects cut in eight was 120 MB of point samples in
#: flight on the client, the scheduler and a worker at once; a bounded batch keeps the memory flat in the city's size
PAIRS_PER_BATCH = 2_000
OBJECTS_PER_BATCH = 250


def classify_and_match(eng, results, objects, catalogue, params, progress, timing, samples=None):
    """(taxonomy, outcomes in object order, matching statistics, the client's ModelCache). ``samples``: where each
    object's point sample is, ``(cell file, index in it)``, for objects that do not hold it (the workers read
    them)."""
    shapes = [o.shape for o in objects]
    tax = taxonomy(shapes, params, timing, distances_of=_pair_distances(eng, shapes, params, progress),
                   spacing=[o.spacing for o in objects])
    noise_of = {r.name: r.noise for r in results}
    noise = np.array([noise_of[o.cell] for o in objects])
    t = time.perf_counter()
    outcomes, stats = _match_all(eng, objects, tax, noise, str(catalogue.folder), params, progress, samples)
    timing["matching"] = time.perf_counter() - t  # the workers' own sums are in twin.json's matching.worker_s
    models = ModelCache(catalogue, params)
    models.add_rows(catalogue.list())
    return tax, outcomes, stats, models


def _pair_distances(eng, shapes: list, params, progress):
    """The taxonomy's ``distances_of(pairs)`` on the workers: batches shrinking towards the end, so that the workers
    finish together (each object's sections sent a few times only), at most PAIRS_PER_BATCH pairs each (what one
    batch carries does not grow with the city), pairs ordered by the objects' rank by length (an object's nearest
    neighbours by descriptor sit next to it)."""
    sections = [s.sections for s in shapes]
    rank = np.argsort(np.argsort([s.size.length for s in shapes], kind="stable"), kind="stable")

    def distances_of(pairs):
        r = rank[np.asarray(pairs, dtype=np.int64).reshape(-1, 2)]
        perm = np.lexsort((r.max(1), r.min(1))) if len(r) else np.zeros(0, dtype=np.int64)
        batches = pair_batches(sections, np.asarray(pairs)[perm], params,
                               size=guided_sizes(len(pairs), eng.n_workers, PAIRS_PER_BATCH, 250))
        if progress:
            progress("taxonomy", 0, len(batches))
        out = eng.map(compare_pairs, batches, [f"pairs{k}" for k in range(len(batches))])
        if progress:
            progress("taxonomy", len(batches), len(batches))
        d = np.zeros(len(perm))
        d[perm] = np.concatenate(out) if out else np.zeros(0)
        return d

    return distances_of


def _match_all(eng, objects: list, tax, noise: np.ndarray, folder: str, params, progress, samples):
    """Every object matched on the workers, the types' leaders first and then their members (who start from their
    leader's models): (outcomes in object order, the statistics)."""
    if progress:
        progress("matching", 0, len(objects))
    outcomes = [None] * len(objects)
    stats = MatchStats()
    leaders: dict = {}
    done = [0]
    first = leader_indices(tax.labels)
    rest = np.setdiff1d(np.arange(len(objects)), first)
    for indices, known in [(first, None), (rest, leaders)]:
        if not len(indices):
            continue
        size = guided_sizes(len(indices), eng.n_workers, OBJECTS_PER_BATCH, 20)
        batches, members = match_batches(objects, tax.labels, noise, folder, params, indices, size=size,
                                         leaders=known, samples=samples)
        names = [f"batch{k}" for k in range(len(batches))]

        def batch_done(name, result, members=members, number={n: k for k, n in enumerate(names)}):
            res, st = result
            for i, r in zip(members[number[name]], res):
                outcomes[i] = r
            stats.add(st)
            leaders.update(st.leaders)
            done[0] += len(res)
            if progress:
                progress("matching", done[0], len(objects))

        fails = eng.run(match_batch, batches, names, on_result=batch_done)
        if fails:
            raise EngineError(f"matching failed twice for {fails[0].name} ({fails[0].error})")
    return outcomes, stats
