"""What an object's surface is like at the scale of its point spacing: the local shape of each point's nearest
neighbours, summarised for the whole object.

A car, a bin or a lamp post is a shell: each point's neighbours lie on a smooth surface, so the smallest of their
covariance's eigenvalues is a small share of the sum (the *surface variation*, 0 on a plane, 1/3 for points spread
evenly in a volume). A bush or a tree is porous: the scanner's beams enter the foliage and return from inside it, so
the neighbours spread in depth and the variation is large. A fence, a railing or a hedge's scan lines seen from the
air are strings of points: the neighbours lie along a line (the *linearity*: the largest eigenvalue's lead over the
second). A car's roof and bonnet, a shelter's roof are horizontal: the share of points whose surface normal is near
vertical (*horizontal*).

A scanner on the ground (a mobile survey's profilers, issue 50) strings its points along scan lines, centimetres
apart along a line and up to decimetres between lines: each point's nearest neighbours lie on its own line, so the
linearity is the scan's and not the object's, and the variation is the range noise's over a few centimetres, not
the surface's curvature. For such points (``lines``) the object's *thickness* is measured as well: how far its points
lie from the one plane that fits them best (an upright board or a wall: centimetres; the side and roof of a car
seen from the street: decimetres).

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
    surface (0-1); ``n`` the points they were measured on; ``thickness`` (m) the 90th percentile of the points'
    distances from their best-fitting plane, for points along a ground scanner's lines (else None)."""

    variation: float
    linearity: float
    horizontal: float
    n: int
    thickness: float | None = None

    @property
    def along_lines(self) -> bool:
        """Whether the points lie along a ground scanner's lines (their neighbourhoods are the scan's)."""
        return self.thickness is not None


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


def thickness_of(points: np.ndarray, share: float = 0.9) -> float:
    """The ``share`` quantile of (n, 3) ``points``' distances (m) from the plane that fits them best (through their
    mean, normal to their covariance's least direction).

    >>> rng = np.random.default_rng(0)
    >>> board = np.c_[rng.uniform(0, 2, 500), rng.normal(0, 0.01, 500), rng.uniform(0, 1, 500)]
    >>> round(thickness_of(board), 2)
    0.02
    """
    q = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    q = q - q.mean(axis=0)
    normal = np.linalg.eigh(q.T @ q)[1][:, 0]
    return float(np.quantile(np.abs(q @ normal), share))


def surface_of(points, params: CoscoParams = DEFAULT, lines: bool = False) -> Surface:
    """The :class:`Surface` of one object's ``points`` ((n, 3) metres, n >= 3); ``lines``: the points lie along a
    ground scanner's lines (the thickness measured too).

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
                   horizontal=round(float(horizontal.mean()), 6), n=len(at),
                   thickness=round(thickness_of(p), 6) if lines else None)
