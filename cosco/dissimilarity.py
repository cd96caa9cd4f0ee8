"""Dissimilarity of two objects' symmetric cross-sections (paper 3.3, Eq. 1-2) and the N x N matrix.

Each section is matched against a precomputed Euclidean distance field of the other (chamfer matching), so that
evaluating hundreds of candidate shifts is a handful of vectorised array look-ups. The search covers the discrete
rotations rz in {0, pi/2, pi, 3pi/2}, a continuous vertical shift tz and, beyond the paper, a small shift du along
the axis; the score is the symmetric RMSE over both sections, in both directions.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage
from scipy.spatial import cKDTree

from .params import DEFAULT, CoscoParams
from .sections import Sections

ROTATIONS = (0.0, np.pi / 2, np.pi, 3 * np.pi / 2)


@dataclass(frozen=True)
class DistanceField:
    """Distances (m) from a 2D point set, sampled on a grid: ``values[i, j]`` at ``origin + (i, j) * cell``."""

    origin: np.ndarray
    cell: float
    values: np.ndarray

    def __call__(self, pts: np.ndarray) -> np.ndarray:
        """Bilinear distances at (..., 2) points; outside the grid, the edge value plus the distance to the grid."""
        g = (pts - self.origin) / self.cell
        hi = np.array(self.values.shape, dtype=np.float64) - 1.0
        gc = np.clip(g, 0.0, hi - 1e-9)
        i0 = gc.astype(np.int64)
        f = gc - i0
        v = self.values
        a = v[i0[..., 0], i0[..., 1]]
        b = v[i0[..., 0] + 1, i0[..., 1]]
        c = v[i0[..., 0], i0[..., 1] + 1]
        d = v[i0[..., 0] + 1, i0[..., 1] + 1]
        fx, fy = f[..., 0], f[..., 1]
        out = (a * (1 - fx) + b * fx) * (1 - fy) + (c * (1 - fx) + d * fx) * fy
        outside = np.linalg.norm((g - gc) * self.cell, axis=-1)
        return out + outside


def distance_field(points2d: np.ndarray, cell: float, pad: float) -> DistanceField:
    """The distance field of a 2D point set on a ``cell`` grid padded by ``pad`` metres.

    >>> f = distance_field(np.array([[0.0, 0.0]]), 0.01, 0.5)
    >>> round(float(f(np.array([[0.3, 0.4]]))[0]), 3)
    0.5
    """
    pts = np.asarray(points2d, dtype=np.float64)
    if len(pts) == 0:
        pts = np.zeros((1, 2))
    origin = pts.min(0) - pad
    shape = np.ceil((pts.max(0) + pad - origin) / cell).astype(int) + 2
    occupied = np.zeros(shape, dtype=bool)
    idx = np.round((pts - origin) / cell).astype(int)
    occupied[idx[:, 0], idx[:, 1]] = True
    dist = ndimage.distance_transform_edt(~occupied) * cell
    return DistanceField(origin=origin, cell=cell, values=dist.astype(np.float32))


class SectionPair:
    """Sections of one object with their distance fields, built once and reused across comparisons."""

    def __init__(self, sections: Sections, params: CoscoParams = DEFAULT):
        self.lon = np.asarray(sections.longitudinal, dtype=np.float64)
        self.tra = np.asarray(sections.transverse, dtype=np.float64)
        pad = max(params.tz_max, params.du_max) + 0.5
        self.lon_field = distance_field(self.lon, params.field_cell, pad)
        self.tra_field = distance_field(self.tra, params.field_cell, pad)
        self.trees = {"lon": cKDTree(self.lon if len(self.lon) else np.zeros((1, 2))),
                      "tra": cKDTree(self.tra if len(self.tra) else np.zeros((1, 2)))}


@dataclass(frozen=True)
class Registration:
    """Best alignment of B's sections to A's: B's frame point (u, v, z) maps to ``Rz(rz) (u, v) + (du, 0)``,
    ``z + tz`` in A's frame. ``rmse`` in metres."""

    rmse: float
    rz: float
    tz: float
    du: float


def _moved(b: SectionPair, rz_index: int, du: np.ndarray, tz: np.ndarray):
    """B's sections moved into A's section planes for each (du, tz): returns two (s, n, 2) arrays and which of
    A's sections each lands on."""
    s = 1.0 if rz_index in (0, 1) else -1.0
    if rz_index in (0, 2):  # B's longitudinal stays longitudinal; u -> s*u + du
        lon = np.stack([s * b.lon[:, 0], b.lon[:, 1]], axis=-1)
        tra = np.stack([s * b.tra[:, 0], b.tra[:, 1]], axis=-1)
        lon = lon[None] + np.stack([du, tz], axis=-1)[:, None, :]
        tra = tra[None] + np.stack([np.zeros_like(tz), tz], axis=-1)[:, None, :]
        return lon, "lon", tra, "tra"
    # quarter turns: B's longitudinal becomes A's transverse and vice versa
    lon = np.stack([s * b.lon[:, 0], b.lon[:, 1]], axis=-1)
    tra = np.stack([-s * b.tra[:, 0], b.tra[:, 1]], axis=-1)
    lon = lon[None] + np.stack([np.zeros_like(tz), tz], axis=-1)[:, None, :]
    tra = tra[None] + np.stack([du, tz], axis=-1)[:, None, :]
    return lon, "tra", tra, "lon"


def _inverse_moved(a: SectionPair, rz_index: int, du: np.ndarray, tz: np.ndarray):
    """A's sections moved into B's frame (the inverse transform), for the reverse direction of the chamfer."""
    inverse = {0: 0, 1: 3, 2: 2, 3: 1}[rz_index]
    if rz_index in (0, 2):
        s = 1.0 if rz_index == 0 else -1.0
        # u_b = s * (u_a - du)
        lon = np.stack([s * (a.lon[None, :, 0] - du[:, None]), a.lon[None, :, 1] - tz[:, None]], axis=-1)
        tra = np.stack([np.broadcast_to(s * a.tra[None, :, 0], (len(tz), len(a.tra))),
                        a.tra[None, :, 1] - tz[:, None]], axis=-1)
        return lon, "lon", tra, "tra"
    s = 1.0 if inverse in (0, 1) else -1.0
    lon = np.stack([s * (a.lon[None, :, 0] - du[:, None]), a.lon[None, :, 1] - tz[:, None]], axis=-1)
    tra = np.stack([np.broadcast_to(-s * a.tra[None, :, 0], (len(tz), len(a.tra))),
                    a.tra[None, :, 1] - tz[:, None]], axis=-1)
    return lon, "tra", tra, "lon"


def _sq_sums(a: SectionPair, b: SectionPair, rz_index: int, du: np.ndarray, tz: np.ndarray) -> np.ndarray:
    """Sum of squared chamfer distances, both directions, for each candidate (du, tz): shape (s,).

    Looks up the distance fields (fast, about 1 cm of quantisation)."""
    fields_a = {"lon": a.lon_field, "tra": a.tra_field}
    fields_b = {"lon": b.lon_field, "tra": b.tra_field}
    total = np.zeros(len(tz))
    p1, k1, p2, k2 = _moved(b, rz_index, du, tz)
    total += (fields_a[k1](p1) ** 2).sum(1) + (fields_a[k2](p2) ** 2).sum(1)
    q1, j1, q2, j2 = _inverse_moved(a, rz_index, du, tz)
    total += (fields_b[j1](q1) ** 2).sum(1) + (fields_b[j2](q2) ** 2).sum(1)
    return total


def _exact_sq_sum(a: SectionPair, b: SectionPair, rz_index: int, du: float, tz: float) -> float:
    """The same sum at one candidate with exact nearest-neighbour distances (KD-trees)."""
    du_, tz_ = np.array([du]), np.array([tz])
    total = 0.0
    for moved, target in ((_moved(b, rz_index, du_, tz_), a), (_inverse_moved(a, rz_index, du_, tz_), b)):
        p1, k1, p2, k2 = moved
        for pts, key in ((p1[0], k1), (p2[0], k2)):
            if len(pts):
                d, _ = target.trees[key].query(pts)
                total += float((d ** 2).sum())
    return total


def _grid(center: float, half: float, step: float) -> np.ndarray:
    n = int(round(half / step)) if step > 0 else 0
    return center + step * np.arange(-n, n + 1)


def register_sections(a: SectionPair, b: SectionPair, params: CoscoParams = DEFAULT,
                      rotations: tuple[int, ...] = (0, 1, 2, 3)) -> Registration:
    """Minimal symmetric RMSE of B's sections against A's over rz, tz and du (Eq. 1-2 of the paper).

    The shift search is a coarse grid followed by two finer grids around the best cell, all vectorised.
    """
    n_total = len(a.lon) + len(a.tra) + len(b.lon) + len(b.tra)
    best = (np.inf, 0, 0.0, 0.0)
    for r in rotations:
        tz_c, du_c = 0.0, 0.0
        tz_half, du_half = params.tz_max, params.du_max
        tz_step, du_step = params.tz_step * 2, params.du_step
        for _ in range(3):
            tzs = _grid(tz_c, tz_half, tz_step)
            dus = _grid(du_c, du_half, du_step) if params.du_max > 0 else np.array([0.0])
            T, D = np.meshgrid(tzs, dus, indexing="ij")
            sq = _sq_sums(a, b, r, D.ravel(), T.ravel())
            k = int(np.argmin(sq))
            tz_c, du_c = float(T.ravel()[k]), float(D.ravel()[k])
            tz_half, du_half = tz_step, du_step
            tz_step, du_step = tz_step / 4, du_step / 4
        exact = _exact_sq_sum(a, b, r, du_c, tz_c)
        if exact < best[0]:
            best = (exact, r, tz_c, du_c)
    val, r, tz, du = best
    rmse = float(np.sqrt(val / max(n_total, 1)))
    return Registration(rmse=rmse, rz=ROTATIONS[r], tz=tz, du=du)


def dissimilarity(a: Sections, b: Sections, params: CoscoParams = DEFAULT) -> float:
    """Dissimilarity (m, RMSE) of two objects' sections.

    >>> from cosco.sections import Sections
    >>> lon = np.array([[u, 1.2] for u in np.linspace(-2, 2, 41)] + [[-2, 0.5], [2, 0.6]])
    >>> tra = np.array([[v, 1.2] for v in np.linspace(-0.9, 0.9, 19)])
    >>> s = Sections(lon, tra, 0.1)
    >>> moved = Sections(lon * [-1, 1] + [0, 0.13], tra + [0, 0.13], 0.1)
    >>> round(dissimilarity(s, moved), 3)
    0.0
    """
    return register_sections(SectionPair(a, params), SectionPair(b, params), params).rmse


def dissimilarity_matrix(sections: list[Sections], params: CoscoParams = DEFAULT, progress=None) -> np.ndarray:
    """The N x N dissimilarity matrix (m): symmetric, zero diagonal, (N - 1) N / 2 comparisons.

    progress : optional callable advanced by one per comparison.
    """
    pairs = [SectionPair(s, params) for s in sections]
    n = len(pairs)
    out = np.zeros((n, n))
    for i in range(n):
        for j in range(i + 1, n):
            out[i, j] = out[j, i] = register_sections(pairs[i], pairs[j], params).rmse
            if progress is not None:
                progress(1)
    return out
