"""The sparse taxonomy: pairs from nearest neighbours only (each once), clusters equal to the full matrix's on
well-separated kinds, and a cost that grows with n, not n^2."""

from __future__ import annotations

import numpy as np

from cosco.params import DEFAULT
from cosco.sections import ObjectShape, Sections, Size
from cosco.taxonomy import candidate_pairs, descriptor, graph_clusters, taxonomy


def _shape(length, height, rng, kind=0):
    u = np.linspace(-length / 2, length / 2, int(length / 0.1) + 1)
    x = u / (length / 2)
    top = [height + 0 * x, height - 0.6 * x ** 2, np.where(x > 0, height, height - 0.6)][kind]
    lon = np.column_stack([u, top + rng.normal(0, 0.004, len(u))])
    v = np.linspace(-0.85, 0.85, 18)
    tra = np.column_stack([v, height - 0.1 * np.abs(v) + rng.normal(0, 0.004, len(v))])
    sec = Sections(lon, tra, 0.1)
    return ObjectShape(len(u), None, None, sec, Size(length, 1.8, height), np.zeros(3))


def test_sparse_taxonomy_finds_the_kinds_the_full_matrix_finds():
    rng = np.random.default_rng(0)
    kinds = [(3.6, 1.2), (4.4, 1.55), (5.1, 1.95)]  # a box, a rounded body, a pickup's step
    shapes = [_shape(length + rng.normal(0, 0.005), height, rng, k) for k, (length, height) in enumerate(kinds)
              for _ in range(14)]
    order = rng.permutation(len(shapes))
    shapes = [shapes[i] for i in order]
    truth = np.repeat(np.arange(3), 14)[order]
    full = taxonomy(shapes, DEFAULT.with_(taxonomy={"full_max": 100}))
    sparse = taxonomy(shapes, DEFAULT.with_(taxonomy={"full_max": 10}))
    assert full.method == "full" and sparse.method == "sparse"
    for tax in (full, sparse):
        assert tax.n_clusters == 3
        for k in range(3):  # each kind is one cluster, and each cluster one kind
            assert len(set(tax.labels[truth == k])) == 1
    assert sparse.n_comparisons <= len(shapes) * DEFAULT.taxonomy.neighbours
    assert full.n_comparisons == len(shapes) * (len(shapes) - 1) // 2


def test_candidate_pairs_are_each_nearest_neighbour_once():
    rng = np.random.default_rng(1)
    d = rng.normal(size=(500, 5))
    pairs = candidate_pairs(d, 4)
    assert (pairs[:, 0] < pairs[:, 1]).all() and len(np.unique(pairs, axis=0)) == len(pairs)
    assert 500 * 4 / 2 <= len(pairs) <= 500 * 4
    from scipy.spatial import cKDTree

    _, nn = cKDTree(d).query(d, k=5)
    have = {tuple(p) for p in pairs.tolist()}
    assert all(tuple(sorted((i, int(j)))) in have for i in range(500) for j in nn[i, 1:])


def test_descriptor_does_not_depend_on_which_end_is_front():
    rng = np.random.default_rng(2)
    s = _shape(4.2, 1.5, rng).sections
    flipped = s.longitudinal * [-1.0, 1.0]
    a = descriptor(np.array([4.2, 1.8, 1.5]), s.longitudinal)
    b = descriptor(np.array([4.2, 1.8, 1.5]), flipped)
    assert np.allclose(a, b)


def test_graph_clusters_are_connected_parts_below_the_threshold():
    labels = graph_clusters(6, np.array([[0, 1], [1, 2], [3, 4], [2, 5]]), np.array([0.01, 0.02, 0.03, 0.2]), 0.065)
    assert labels.tolist() == [1, 1, 1, 2, 2, 3]
