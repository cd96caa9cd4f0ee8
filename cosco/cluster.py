"""Hierarchical clustering of a dissimilarity matrix (paper 3.3, Figure 7b)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .params import DEFAULT, CoscoParams


@dataclass(frozen=True)
class Clustering:
    """``labels`` (n,) int cluster ids from 1, ``linkage`` the scipy (n - 1, 4) linkage matrix, ``threshold`` m."""

    labels: np.ndarray
    linkage: np.ndarray
    threshold: float

    @property
    def n_clusters(self) -> int:
        return int(len(np.unique(self.labels))) if len(self.labels) else 0


def check_matrix(matrix) -> np.ndarray:
    """Coerce a dissimilarity matrix: square, symmetric, zero diagonal, finite, non-negative."""
    m = np.asarray(matrix, dtype=np.float64)
    if m.ndim != 2 or m.shape[0] != m.shape[1]:
        raise ValueError(f"expected a square (n, n) dissimilarity matrix, got shape {m.shape}")
    if not np.all(np.isfinite(m)) or (m < 0).any():
        raise ValueError("dissimilarity matrix has negative or non-finite entries")
    if not np.allclose(m, m.T) or not np.allclose(np.diag(m), 0):
        raise ValueError("dissimilarity matrix must be symmetric with a zero diagonal")
    return m


def cluster(matrix, params: CoscoParams = DEFAULT, threshold: float | None = None) -> Clustering:
    """Cluster objects whose dissimilarity is below ``threshold`` (default ``params.taxonomy.threshold``, m).

    >>> d = np.array([[0, .01, .3], [.01, 0, .3], [.3, .3, 0]])
    >>> cluster(d).labels.tolist()
    [1, 1, 2]
    """
    from scipy.cluster.hierarchy import fcluster, linkage  # imported here: 0.25 s that most commands never need
    from scipy.spatial.distance import squareform

    m = check_matrix(matrix)
    t = params.taxonomy.threshold if threshold is None else float(threshold)
    n = len(m)
    if n == 0:
        return Clustering(np.zeros(0, dtype=int), np.zeros((0, 4)), t)
    if n == 1:
        return Clustering(np.ones(1, dtype=int), np.zeros((0, 4)), t)
    z = linkage(squareform(m, checks=False), method=params.taxonomy.linkage)
    labels = fcluster(z, t=t, criterion="distance").astype(int)
    return Clustering(labels=labels, linkage=z, threshold=t)
