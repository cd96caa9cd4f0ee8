"""The taxonomy of many objects without the N x N matrix (beyond the paper, for city scale).

Up to ``params.taxonomy.full_max`` objects (32: a car park like the paper's) the paper's way is kept: every pair
compared, average-linkage dendrogram cut at ``params.taxonomy.threshold``. Beyond, the work must not grow with the
square of the objects:

1. each object gets a cheap descriptor: its length, width and height, and the height of its longitudinal
   section's top at two stations each side of the middle (averaged over both sides, so a car seen front-first
   or back-first has the same descriptor);
2. each object is compared (section registration, as in the matrix) with only its ``taxonomy.neighbours``
   nearest objects by descriptor (a KD-tree): O(n k) comparisons, each pair once;
3. clusters are the connected parts of the graph whose edges are the pairs closer than the threshold (single
   linkage on the sparse graph), numbered by their first object.

Objects of one model are each other's nearest neighbours by size and profile, so they end up in one cluster;
a cluster that chains two models only costs the matcher more trials (members fall back to their own
candidates), never a wrong match, because every object is still registered and verified on its own.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from .cluster import cluster
from .dissimilarity import SectionPair, dissimilarity_matrix, register_sections
from .params import DEFAULT, CoscoParams

#: stations of the top profile, as fractions of the half-length from the middle
STATIONS = (0.25, 0.75)


@dataclass(frozen=True)
class Taxonomy:
    """Cluster ``labels`` (n,) int from 1; ``method`` "full" (``matrix``, ``linkage``) or "sparse" (``pairs``
    (m, 2) int, ``distances`` (m,) metres); ``threshold`` m."""

    labels: np.ndarray
    method: str
    threshold: float
    matrix: np.ndarray | None = None
    linkage: np.ndarray | None = None
    pairs: np.ndarray | None = None
    distances: np.ndarray | None = None

    @property
    def n_clusters(self) -> int:
        return int(len(np.unique(self.labels))) if len(self.labels) else 0

    @property
    def n_comparisons(self) -> int:
        n = len(self.labels)
        return n * (n - 1) // 2 if self.method == "full" else int(len(self.pairs))


def descriptor(size: np.ndarray, longitudinal: np.ndarray) -> np.ndarray:
    """(5,) metres: length, width, height and the top of the longitudinal section (u, z) at :data:`STATIONS`.

    >>> lon = np.array([[u, 1.0 + 0.1 * abs(u)] for u in np.linspace(-2, 2, 41)])
    >>> descriptor(np.array([4.0, 1.8, 1.2]), lon).round(2).tolist()
    [4.0, 1.8, 1.2, 1.06, 1.16]
    """
    size = np.asarray(size, dtype=np.float64)
    lon = np.asarray(longitudinal, dtype=np.float64).reshape(-1, 2)
    half = max(size[0] / 2, 1e-6)
    tops = []
    for s in STATIONS:
        both = []
        for sign in (-1.0, 1.0):
            near = np.abs(lon[:, 0] / half - sign * s) < 0.1 if len(lon) else np.zeros(0, bool)
            both.append(float(lon[near, 1].max()) if near.any() else np.nan)
        tops.append(np.nanmean(both) if np.isfinite(both).any() else 0.0)
    return np.concatenate([size, tops])


def candidate_pairs(descriptors: np.ndarray, k: int) -> np.ndarray:
    """(m, 2) int pairs ``i < j``, each once: every object with its ``k`` nearest by descriptor."""
    from scipy.spatial import cKDTree

    d = np.asarray(descriptors, dtype=np.float64)
    n = len(d)
    if n < 2:
        return np.zeros((0, 2), dtype=np.int64)
    k = min(k, n - 1)
    _, nn = cKDTree(d).query(d, k=k + 1)
    i = np.repeat(np.arange(n), k + 1)
    j = nn.ravel()
    keep = i != j
    pairs = np.sort(np.column_stack([i[keep], j[keep]]), axis=1)
    return np.unique(pairs, axis=0)


def graph_clusters(n: int, pairs: np.ndarray, distances: np.ndarray, threshold: float) -> np.ndarray:
    """(n,) int labels from 1: connected parts of the graph of ``pairs`` closer than ``threshold``, numbered in
    the order of their first object.

    >>> graph_clusters(4, np.array([[0, 2], [1, 3]]), np.array([0.01, 0.5]), 0.065).tolist()
    [1, 2, 1, 3]
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    pairs = np.asarray(pairs, dtype=np.int64).reshape(-1, 2)
    close = np.asarray(distances, dtype=np.float64) < threshold
    e = pairs[close]
    g = coo_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])), shape=(n, n))
    _, comp = connected_components(g, directed=False)
    _, first = np.unique(comp, return_index=True)
    rank = np.empty(len(first), dtype=np.int64)
    rank[np.argsort(np.argsort(first))] = np.arange(len(first))
    return rank[comp] + 1


def pair_distances(sections: list, pairs: np.ndarray, params: CoscoParams = DEFAULT) -> np.ndarray:
    """Section dissimilarity (m) of each pair (as in the matrix); each object's sections are prepared once."""
    prepared: dict[int, SectionPair] = {}

    def get(i):
        if i not in prepared:
            prepared[i] = SectionPair(sections[i], params)
        return prepared[i]

    return np.array([register_sections(get(int(i)), get(int(j)), params).rmse for i, j in pairs], dtype=np.float64)


def taxonomy(shapes: list, params: CoscoParams = DEFAULT, distances_of=None) -> Taxonomy:
    """The taxonomy of objects' :class:`~cosco.sections.ObjectShape`: full (matrix and dendrogram) up to
    ``params.taxonomy.full_max`` objects, sparse beyond. ``distances_of(pairs) -> (m,)`` computes the pairs'
    dissimilarities (default :func:`pair_distances` here; a caller may spread them over workers)."""
    n = len(shapes)
    t = params.taxonomy.threshold
    if n <= params.taxonomy.full_max:
        if distances_of is None:
            m = dissimilarity_matrix([s.sections for s in shapes], params)
        else:
            i, j = np.triu_indices(n, 1)
            m = np.zeros((n, n))
            m[i, j] = m[j, i] = np.asarray(distances_of(np.column_stack([i, j])), dtype=np.float64)
        c = cluster(m, params)
        return Taxonomy(c.labels, "full", t, matrix=m, linkage=c.linkage)
    desc = np.array([descriptor(s.size.as_array(), s.sections.longitudinal) for s in shapes])
    pairs = candidate_pairs(desc, params.taxonomy.neighbours)
    if distances_of is None:
        d = pair_distances([s.sections for s in shapes], pairs, params)
    else:
        d = np.asarray(distances_of(pairs), dtype=np.float64)
    return Taxonomy(graph_clusters(n, pairs, d, t), "sparse", t, pairs=pairs, distances=d)


def taxonomy_of(shapes: list, params: CoscoParams = DEFAULT, timing: dict | None = None, say=None,
                distances_of=None, spacing=None) -> Taxonomy:
    """The objects' taxonomy as a run takes it: the paper's matrix and dendrogram up to
    ``params.taxonomy.full_max`` objects (timed in ``timing`` as "matrix" and "clustering"), the sparse graph of
    :func:`taxonomy` beyond (timed as "matrix": its comparisons and its components); ``say(text)`` as each part
    starts. ``spacing``: the objects' point spacings (m): the threshold is at least ``params.taxonomy.spacing_k``
    times their median (a sparse scan's sections differ by their sampling)."""
    if spacing is not None and len(spacing):
        floor = params.taxonomy.spacing_k * float(np.median(spacing))
        if floor > params.taxonomy.threshold:
            params = params.with_(taxonomy={"threshold": floor})
    timing = {} if timing is None else timing
    t = time.perf_counter()
    if len(shapes) > params.taxonomy.full_max or distances_of is not None:
        if say:
            say(f"taxonomy of {len(shapes)} objects")
        tax = taxonomy(shapes, params, distances_of=distances_of)
        timing["matrix"] = time.perf_counter() - t
        timing["clustering"] = 0.0
        return tax
    if say:
        say("dissimilarity matrix")
    matrix = dissimilarity_matrix([s.sections for s in shapes], params)
    timing["matrix"] = time.perf_counter() - t
    t = time.perf_counter()
    c = cluster(matrix, params)
    timing["clustering"] = time.perf_counter() - t
    return Taxonomy(c.labels, "full", c.threshold, matrix=matrix, linkage=c.linkage)
