"""What an object's surface is like at the scale of its point spacing: the local shape of each point's nearest
neighbours, summarised for the whole object.

A car, a bin or a lamp post is a shell: each point's neighbours lie on a smooth surface, so the smallest of their
covariance's eigenvalues is a small share of the sum (the *surface variation*, 0 on a plane, 1/3 for points spread
evenly in a volume). A bush or a tree is porous: the scanner's beams enter the foliage and return from inside it, so
the neighbours spread in depth and the variation is large. A fence, a railing or a hedge's scan lines seen from the
air are strings of points: the neighbours lie along a line (the *linearity*: the largest eigenvalue's lead over the
second). A car's roof and bonnet, a shelter's roof are horizontal: the share of points whose surface normal is near
vertical (*horizontal*).

Pure numpy and a KD-tree: points in, three numbers out, on at most ``surface.max_points`` points spread evenly
through the object (the neighbours are sought among all its points), so the cost is bounded per object.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .params import DEFAULT, CoscoParams


@dataclass(frozen=True)
class Surface:
    """One object's surface at the scale of its point spacing (see the module's text): the median ``variation``
    (0-1/3) and ``linearity`` (0-1) of its points' neighbourhoods and the share of its points on a ``horizontal``
    surface (0-1); ``n`` the points they were measured on."""

    variation: float
    linearity: float
    horizontal: float
    n: int


def neighbourhood_shapes(points: np.ndarray, k: int, at: np.ndarray | None = None) -> tuple:
    """Each of ``at``'s points' (all ``points`` when None) ``k`` nearest neighbours among ``points``: their
    covariance's eigenvalues, ascending (m, 3), and the eigenvector of the smallest, the normal (m, 3).

    >>> g = np.stack(np.meshgrid(np.arange(10.0), np.arange(10.0)), -1).reshape(-1, 2)
    >>> ev, normal = neighbourhood_shapes(np.c_[g, np.zeros(100)], 8)
    >>> float(ev[:, 0].max()), float(np.abs(normal[:, 2]).min())
    (0.0, 1.0)
    """
    from scipy.spatial import cKDTree  # deferred: the catalogue's listing imports the shapes, not scipy

    p = np.asarray(points, dtype=np.float64)
    q = p if at is None else np.asarray(at, dtype=np.float64)
    k = min(k, len(p))
    _, idx = cKDTree(p).query(q, k)
    nb = p[idx.reshape(len(q), k)]
    nb = nb - nb.mean(axis=1, keepdims=True)
    cov = np.einsum("nki,nkj->nij", nb, nb) / k
    ev, vec = np.linalg.eigh(cov)
    return np.maximum(ev, 0.0), vec[:, :, 0]


def surface_of(points, params: CoscoParams = DEFAULT) -> Surface:
    """The :class:`Surface` of one object's ``points`` ((n, 3) metres, n >= 3).

    >>> rng = np.random.default_rng(0)
    >>> a = rng.uniform(0, 2 * np.pi, 3000)
    >>> shell = np.c_[np.cos(a), np.sin(a), rng.uniform(0, 1.5, 3000)]  # a drum's side: a smooth shell
    >>> bush = rng.normal(0, 0.6, (3000, 3))  # returns from inside the foliage
    >>> surface_of(shell).variation < 0.02 < 0.1 < surface_of(bush).variation
    True
    """
    p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    sp = params.surface
    step = max(1, int(np.ceil(len(p) / sp.max_points)))
    at = p[::step]
    ev, normal = neighbourhood_shapes(p, sp.k, at)
    total = np.maximum(ev.sum(axis=1), 1e-18)
    variation = ev[:, 0] / total
    linearity = (ev[:, 2] - ev[:, 1]) / np.maximum(ev[:, 2], 1e-18)
    horizontal = np.abs(normal[:, 2]) >= np.cos(np.radians(sp.horizontal_deg))
    return Surface(variation=round(float(np.median(variation)), 6), linearity=round(float(np.median(linearity)), 6),
                   horizontal=round(float(horizontal.mean()), 6), n=len(at))
