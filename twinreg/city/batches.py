"""The worker side of a city run's global stages: the taxonomy's pair comparisons and the matching, each cut into
batches. The matching runs the clusters' leaders first, then the members in batches of any cut, each with its
leader's ranking: exactly what one call over all objects would give, with the work spread evenly."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from cosco.taxonomy import pair_distances

from ..catalogue.repository import Catalogue
from ..matching.match import Evidence, ModelCache, match_objects
from ..settings import DEFAULT, Settings
from .cellfile import load_clouds


@dataclass(frozen=True)
class PairBatch:
    """Pairs ``(m, 2)`` of indices into ``sections`` (a dict index -> Sections of the objects involved)."""

    pairs: np.ndarray
    sections: dict
    params: Settings = DEFAULT


def compare_pairs(batch: PairBatch) -> np.ndarray:
    """The section dissimilarity (m) of each pair of the batch."""
    index = {k: n for n, k in enumerate(batch.sections)}
    local = np.array([[index[int(i)], index[int(j)]] for i, j in batch.pairs], dtype=np.int64).reshape(-1, 2)
    return pair_distances(list(batch.sections.values()), local, batch.params)


def guided_sizes(n: int, workers: int, largest: int, smallest: int = 1) -> list[int]:
    """Sizes of consecutive batches of ``n`` items for ``workers`` workers that take the next batch as they free
    up: each batch half of what is left per worker (``remaining / (2 workers)``, within ``smallest`` and
    ``largest``), so that the batches shrink towards the end and the workers finish together.

    >>> guided_sizes(100, 2, 20, 5)
    [20, 20, 15, 12, 9, 6, 5, 5, 5, 3]
    """
    sizes, left = [], int(n)
    while left > 0:
        k = min(left, max(smallest, min(largest, -(-left // (2 * max(workers, 1))))))
        sizes.append(k)
        left -= k
    return sizes


def _cuts(n: int, size) -> list[tuple[int, int]]:
    """``(start, end)`` of consecutive batches: ``size`` an int (every batch that size, the last what is left) or
    a list of sizes (e.g. :func:`guided_sizes`), which must hold every item.

    >>> _cuts(10, 4), _cuts(10, [3, 3, 4])
    ([(0, 4), (4, 8), (8, 10)], [(0, 3), (3, 6), (6, 10)])
    >>> _cuts(10, [3, 3])
    Traceback (most recent call last):
    ValueError: batch sizes for 6 items, not 10: every item goes in a batch
    """
    sizes = [size] * -(-n // size) if isinstance(size, int) else list(size)
    if sum(sizes) < n:
        raise ValueError(f"batch sizes for {sum(sizes)} items, not {n}: every item goes in a batch")
    ends = np.minimum(np.cumsum(sizes), n) if sizes else np.zeros(0, dtype=np.int64)
    return [(int(a), int(b)) for a, b in zip(np.r_[0, ends[:-1]], ends) if b > a]


def pair_batches(sections: list, pairs: np.ndarray, params: Settings, size=400) -> list[PairBatch]:
    """Consecutive batches of the pairs, as given, of ``size`` pairs (an int, or a list of sizes: see
    :func:`_cuts`); order them so that an object's pairs are together: each object is prepared once per batch
    that holds it."""
    pairs = np.asarray(pairs, dtype=np.int64).reshape(-1, 2)
    out = []
    for a, b in _cuts(len(pairs), size):
        p = pairs[a:b]
        ids = sorted(set(p.ravel().tolist()))
        out.append(PairBatch(p, {i: sections[i] for i in ids}, params))
    return out


@dataclass(frozen=True)
class MatchBatch:
    """Objects to match against the catalogue in ``folder``: shapes, cluster labels, point samples, each object's
    scan noise and point spacing (m). A sample left in its cell file is None in ``clouds``, and ``samples`` says
    where it is: ``(cell file, index of the object in it)`` (the worker reads it: the run's main process does not
    hold every object's sample)."""

    folder: str
    shapes: list
    labels: np.ndarray
    clouds: list
    noise: np.ndarray
    spacings: list
    params: Settings = DEFAULT
    leaders: dict | None = None
    samples: list | None = None


def batch_clouds(batch: MatchBatch) -> list:
    """The batch's point samples, those left in the cell files read from there (each file opened once)."""
    if any(c is None and (batch.samples is None or batch.samples[k] is None) for k, c in enumerate(batch.clouds)):
        raise ValueError("an object of the batch has no point sample")
    return read_clouds(batch.clouds, batch.samples)


def read_clouds(clouds: list, samples: list | None) -> list:
    """``clouds`` with each None whose ``samples`` entry says where it is (``(cell file, index of the object in
    it)``) read from that file, each file opened once; the others as they are."""
    clouds = list(clouds)
    wanted: dict = {}
    for k, c in enumerate(clouds):
        if c is None and samples is not None and samples[k] is not None:
            path, index = samples[k]
            wanted.setdefault(str(path), []).append((k, int(index)))
    for path, items in wanted.items():
        for (k, _), cloud in zip(items, load_clouds(path, [i for _, i in items])):
            clouds[k] = cloud
    return clouds


_CACHES: dict = {}


def _models(folder: str, params: Settings):
    """One catalogue and model cache per worker process and catalogue state (reused by the next batches)."""
    db = Path(folder) / "catalogue.sqlite"
    key = (folder, db.stat().st_mtime_ns if db.exists() else 0, repr(params))
    if key not in _CACHES:
        _CACHES.clear()
        cat = Catalogue(folder, create=False)
        _CACHES[key] = (cat, ModelCache(cat, params))
    return _CACHES[key]


def match_batch(batch: MatchBatch):
    """``(outcomes, stats)`` of :func:`~twinreg.matching.match.match_objects` on the batch."""
    cat, cache = _models(batch.folder, batch.params)
    return match_objects(batch.shapes, cat, labels=batch.labels, params=batch.params,
                         evidence=Evidence(batch_clouds(batch), batch.noise, batch.spacings), cache=cache,
                         leaders=batch.leaders)


def leader_indices(labels: np.ndarray) -> np.ndarray:
    """The first object of each cluster (its leader), in object order."""
    _, first = np.unique(np.asarray(labels), return_index=True)
    return np.sort(first)


def match_batches(objects: list, labels: np.ndarray, noise: np.ndarray, folder: str, params: Settings,
                  indices: np.ndarray, size=200, leaders: dict | None = None, samples: list | None = None
                  ) -> tuple[list[MatchBatch], list[np.ndarray]]:
    """The objects ``indices`` cut into batches of ``size`` (an int, or a list of sizes: see :func:`_cuts`; in
    label order, so that a batch holds few clusters); ``leaders``: the leaders' rankings when ``indices`` are
    members; ``samples``: where each object's point sample is when the objects do not hold it (see
    :class:`MatchBatch`). Returns the batches and, for each, the indices of its objects."""
    labels = np.asarray(labels)
    idx = np.asarray(indices, dtype=np.int64)
    idx = idx[np.lexsort((idx, labels[idx]))]
    members = [idx[a:b] for a, b in _cuts(len(idx), size)]
    batches = []
    for m in members:
        m = np.sort(m)
        batches.append(MatchBatch(folder, [objects[i].shape for i in m], labels[m], [objects[i].cloud for i in m],
                                  noise[m], [objects[i].spacing for i in m], params,
                                  None if leaders is None else {int(k): leaders[int(k)]
                                                                for k in np.unique(labels[m])},
                                  None if samples is None else [samples[i] for i in m]))
    return batches, [np.sort(m) for m in members]
