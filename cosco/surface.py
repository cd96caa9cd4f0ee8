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

A bush's outer leaves can also be sampled as thinly as a shell: a single-return sweep 25 m from a hedge puts one point
a leaf, and the hedge's variation is a car's. Its points still stand in and out of the surface their neighbours
span: the *roughness* is the median distance of a point from the chord between its two nearest neighbours where
these lie on either side of it (along a scan line, as a profiler or a rotating scanner strings them). On a shell or
a road it is the range noise's; in foliage the depth between leaves. It is told in units of the scan's own smooth
surface, its ground (:func:`scan_smoothness`): a rotating scanner's range noise along its rings is millimetres, a
simulated scan's isotropic noise centimetres, and both measure their ground as they measure a car.

Pure numpy and a KD-tree: points in, a few numbers out, on at most ``surface.max_points`` points spread evenly
through the object (the neighbours are sought among all its points), so the cost is bounded per object. Where the
compiled kernels are in use (:mod:`cosco.kernels`: a city's cells, a scene of many objects) the neighbourhoods come
from :func:`_shapes_fast` (the nearest neighbours on a voxel grid, each covariance's eigenvalues by Jacobi turns),
beside this reference (tests/cosco/test_kernels.py: the same eigenvalues to 1e-12, the same normals).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .arrays import column_max, column_min
from .kernels import fast, kernel
from .nearest import _grid_build_fast
from .params import DEFAULT, CoscoParams

#: the least smoothness (m) a scan's roughness is told in units of (a noise-free simulated ground measures 0)
SMOOTH_FLOOR = 0.001
#: a point's two nearest neighbours lie on either side of it when the angle between them, seen from it, is wider
#: than 120 degrees (its cosine below this)
CHORD_MAX_COS = -0.5


@dataclass(frozen=True)
class Surface:
    """One object's surface at the scale of its point spacing (see the module's text): the median ``variation``
    (0-1/3) and ``linearity`` (0-1) of its points' neighbourhoods and the share of its points on a ``horizontal``
    surface (0-1); ``n`` the points they were measured on; ``thickness`` (m) the 90th percentile of the points'
    distances from their best-fitting plane, for points along a ground scanner's lines (else None); ``side``: the
    scan was made from the ground, where a sparse object's few points lie on the one face it turns to the scanner."""

    variation: float
    linearity: float
    horizontal: float
    n: int
    thickness: float | None = None
    roughness: float | None = None  # m, the points' median distance from their neighbours' chords (None: too few)
    smooth: float | None = None  # m, the scan's smooth surface's (its ground's) roughness, None: not known
    side: bool = False  # seen from the ground (a sweep, a mobile survey): from one side, not from above

    @property
    def rough(self) -> float | None:
        """The roughness in units of the scan's smooth surface (:data:`SMOOTH_FLOOR` m at least), None where either
        is not known: about 1 on a car's shell, several in foliage."""
        if self.roughness is None or self.smooth is None:
            return None
        return self.roughness / max(self.smooth, SMOOTH_FLOOR)

    @property
    def along_lines(self) -> bool:
        """Whether the points lie along a ground scanner's lines (their neighbourhoods are the scan's)."""
        return self.thickness is not None


def neighbourhood_shapes(points: np.ndarray, k: int, at: np.ndarray | None = None) -> tuple:
    """Each of ``at``'s points' (all ``points`` when None; ``at``'s points are among ``points``) ``k`` nearest
    neighbours among ``points``: their covariance's eigenvalues, ascending (m, 3), the eigenvector of the smallest,
    the normal (m, 3; its largest component positive), and the point's distance from the chord between its two
    nearest others (m, :func:`chord_distance`; NaN where they do not lie on either side of it, or k < 3).

    >>> g = np.stack(np.meshgrid(np.arange(10.0), np.arange(10.0)), -1).reshape(-1, 2)
    >>> ev, normal, chord = neighbourhood_shapes(np.c_[g, np.zeros(100)], 8)
    >>> float(ev[:, 0].max()), float(np.abs(normal[:, 2]).min()), float(np.nanmax(chord))
    (0.0, 1.0, 0.0)
    """
    p = np.ascontiguousarray(points, dtype=np.float64).reshape(-1, 3)
    q = p if at is None else np.ascontiguousarray(at, dtype=np.float64).reshape(-1, 3)
    k = min(k, len(p))
    kernel_fn = fast(_shapes_fast)
    if kernel_fn is not None and k >= 1 and len(q):
        cell = _neighbour_cell(p, k)
        grid_pts, _, starts, lo, shape = fast(_grid_build_fast)(p, cell)
        ev, normal, chord = kernel_fn(q, k, grid_pts, starts, lo, shape, cell)
    else:
        ev, normal, chord = _shapes_numpy(p, q, k)
    return np.maximum(ev, 0.0), _signed(normal), chord


def _shapes_numpy(p: np.ndarray, q: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The reference of :func:`_shapes_fast`: a KD-tree's ``k`` nearest, LAPACK's eigenvalues and vectors, and
    :func:`chord_distance` to the second and third nearest (the first is the point itself)."""
    from scipy.spatial import cKDTree  # deferred: the catalogue's listing imports the shapes, not scipy

    _, idx = cKDTree(p).query(q, k)
    idx = idx.reshape(len(q), k)
    nb = p[idx]
    a, b = (nb[:, 1], nb[:, 2]) if k >= 3 else (None, None)
    nb = nb - nb.mean(axis=1, keepdims=True)
    cov = np.einsum("nki,nkj->nij", nb, nb) / k
    ev, vec = np.linalg.eigh(cov)
    chord = chord_distance(q, a, b) if k >= 3 else np.full(len(q), np.nan)
    return ev, vec[:, :, 0], chord


def chord_distance(q: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(m,) each (m, 3) point ``q``'s distance (m) from the line through its neighbours ``a`` and ``b`` where they
    lie on either side of it (the angle a-q-b wider than 120 degrees), else NaN. Along a scan line the neighbours
    are the line's, and the distance is how far the point stands out of it: the range noise on a shell or a road,
    the depth between leaves in foliage.

    >>> q = np.array([[0.0, 0.0, 0.01], [0.0, 0.0, 0.0]])
    >>> chord_distance(q, np.array([[-1.0, 0, 0], [1.0, 0, 0]]), np.array([[1.0, 0, 0], [1.0, 0.1, 0]])).tolist()
    [0.01, nan]
    """
    u, v = a - q, b - q
    nu, nv = np.linalg.norm(u, axis=1), np.linalg.norm(v, axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        across = np.einsum("ij,ij->i", u, v) < CHORD_MAX_COS * nu * nv
        ab = b - a
        d = np.linalg.norm(np.cross(ab, q - a), axis=1) / np.linalg.norm(ab, axis=1)
    return np.where(across & (nu > 0) & (nv > 0), d, np.nan)


def _signed(normal: np.ndarray) -> np.ndarray:
    """Each (m, 3) unit vector turned so that its largest component is positive (an eigenvector's sign is free)."""
    big = np.take_along_axis(normal, np.abs(normal).argmax(axis=1)[:, None], axis=1)
    return np.where(big < 0, -normal, normal)


def _neighbour_cell(p: np.ndarray, k: int) -> float:
    """A voxel edge (m) for the ``k`` nearest neighbours of (n, 3) points: about the radius holding ``k`` of them
    on a surface of half the box's area (or along its longest side), the grid kept within ``4 n + 1024`` voxels.
    Only the speed depends on it: the search widens until the answer is sure."""
    n = len(p)
    ext = np.ptp(p, axis=0) if n else np.zeros(3)
    area = ext[0] * ext[1] + ext[0] * ext[2] + ext[1] * ext[2]
    cell = max(float(np.sqrt(k * area / (np.pi * max(n, 1)))), float(ext.max()) * k / (2.0 * max(n, 1)))
    if not cell > 0:
        return 1.0
    while float(np.prod(ext / cell + 1)) > 4 * n + 1024:
        cell *= 1.5
    return cell


@kernel(helper=True)
def _eigh3(a, v):
    """The (3, 3) symmetric ``a`` diagonalised in place by cyclic Jacobi turns (its diagonal the eigenvalues), ``v``
    set to the eigenvectors (columns)."""
    for i in range(3):
        for j in range(3):
            v[i, j] = 1.0 if i == j else 0.0
    for _ in range(50):
        off = a[0, 1] * a[0, 1] + a[0, 2] * a[0, 2] + a[1, 2] * a[1, 2]
        diag = a[0, 0] * a[0, 0] + a[1, 1] * a[1, 1] + a[2, 2] * a[2, 2]
        if off <= 1e-30 * diag:
            break
        for p in range(2):
            for q in range(p + 1, 3):
                apq = a[p, q]
                if apq == 0.0:
                    continue
                theta = (a[q, q] - a[p, p]) / (2.0 * apq)
                t = 1.0 / (abs(theta) + np.sqrt(theta * theta + 1.0))
                if theta < 0.0:
                    t = -t
                c = 1.0 / np.sqrt(t * t + 1.0)
                s = t * c
                for r in range(3):  # columns p and q, then rows p and q: a <- J^T a J
                    arp, arq = a[r, p], a[r, q]
                    a[r, p] = c * arp - s * arq
                    a[r, q] = s * arp + c * arq
                for r in range(3):
                    apr, aqr = a[p, r], a[q, r]
                    a[p, r] = c * apr - s * aqr
                    a[q, r] = s * apr + c * aqr
                a[p, q] = 0.0
                a[q, p] = 0.0
                for r in range(3):
                    vrp, vrq = v[r, p], v[r, q]
                    v[r, p] = c * vrp - s * vrq
                    v[r, q] = s * vrp + c * vrq


@kernel(helper=True)
def _k_nearest_into(best, rows, k, x, y, z, grid_pts, starts, lo, shape, cell) -> int:
    """The ``k`` nearest :func:`~cosco.nearest._grid_build_fast` points of (x, y, z) into ``best`` (squared
    distances, nearest first) and ``rows`` (grid rows); how many were found (fewer than ``k`` when the grid holds
    fewer). The voxels are searched ring by ring around (x, y, z)'s own until the ``k``-th nearest lies within the
    rings searched."""
    c0 = min(max(np.int64(np.floor((x - lo[0]) / cell)), 0), shape[0] - 1)
    c1 = min(max(np.int64(np.floor((y - lo[1]) / cell)), 0), shape[1] - 1)
    c2 = min(max(np.int64(np.floor((z - lo[2]) / cell)), 0), shape[2] - 1)
    # the query's distance to its own voxel's nearest face (0 outside the grid): beyond ring r, every point is
    # farther than margin + r cells
    margin = min(cell, max(x - (lo[0] + c0 * cell), 0.0), max(lo[0] + (c0 + 1) * cell - x, 0.0),
                 max(y - (lo[1] + c1 * cell), 0.0), max(lo[1] + (c1 + 1) * cell - y, 0.0),
                 max(z - (lo[2] + c2 * cell), 0.0), max(lo[2] + (c2 + 1) * cell - z, 0.0))
    found = 0
    r = 0
    while True:
        for i in range(max(c0 - r, 0), min(c0 + r + 1, shape[0])):
            for j in range(max(c1 - r, 0), min(c1 + r + 1, shape[1])):
                column = (i * shape[1] + j) * shape[2]
                for side in range(2):
                    if abs(i - c0) < r and abs(j - c1) < r:  # inside the last ring: its bottom and top voxels only
                        kz = c2 - r if side == 0 else c2 + r
                        if kz < 0 or kz >= shape[2]:
                            continue
                        s0, s1 = starts[column + kz], starts[column + kz + 1]
                    elif side == 0:  # the column's voxels in reach: one run of points
                        s0, s1 = starts[column + max(c2 - r, 0)], starts[column + min(c2 + r + 1, shape[2])]
                    else:
                        continue
                    for g in range(s0, s1):
                        dx = grid_pts[g, 0] - x
                        dy = grid_pts[g, 1] - y
                        dz = grid_pts[g, 2] - z
                        dd = dx * dx + dy * dy + dz * dz
                        if found < k:
                            slot = found
                            found += 1
                        elif dd < best[k - 1]:
                            slot = k - 1
                        else:
                            continue
                        while slot > 0 and best[slot - 1] > dd:  # kept sorted, nearest first
                            best[slot] = best[slot - 1]
                            rows[slot] = rows[slot - 1]
                            slot -= 1
                        best[slot] = dd
                        rows[slot] = g
        reach = r * cell + margin
        if found >= k and best[k - 1] <= reach * reach:
            return found
        if c0 - r <= 0 and c1 - r <= 0 and c2 - r <= 0 and c0 + r >= shape[0] - 1 and c1 + r >= shape[1] - 1 \
                and c2 + r >= shape[2] - 1:
            return found
        r += 1


@kernel(entry="neighbourhood_shapes", example="_example", tolerance=1e-12)
def _shapes_fast(at, k, grid_pts, starts, lo, shape, cell):
    """(m, 3) eigenvalues, ascending, and (m, 3) normals (the smallest's eigenvector) of the covariance of each of
    ``at``'s ``k`` nearest :func:`~cosco.nearest._grid_build_fast` points (:func:`_k_nearest_into`), and (m,) the
    point's :func:`chord_distance` to the second and third nearest."""
    m = at.shape[0]
    ev = np.empty((m, 3))
    normal = np.empty((m, 3))
    chord = np.full(m, np.nan)
    best = np.empty(k)
    rows = np.empty(k, dtype=np.int64)
    a = np.empty((3, 3))
    v = np.empty((3, 3))
    for qi in range(m):
        _k_nearest_into(best, rows, k, at[qi, 0], at[qi, 1], at[qi, 2], grid_pts, starts, lo, shape, cell)
        mx = 0.0
        my = 0.0
        mz = 0.0
        for t in range(k):
            mx += grid_pts[rows[t], 0]
            my += grid_pts[rows[t], 1]
            mz += grid_pts[rows[t], 2]
        mx /= k
        my /= k
        mz /= k
        for i in range(3):
            for j in range(3):
                a[i, j] = 0.0
        for t in range(k):
            d0 = grid_pts[rows[t], 0] - mx
            d1 = grid_pts[rows[t], 1] - my
            d2 = grid_pts[rows[t], 2] - mz
            a[0, 0] += d0 * d0
            a[0, 1] += d0 * d1
            a[0, 2] += d0 * d2
            a[1, 1] += d1 * d1
            a[1, 2] += d1 * d2
            a[2, 2] += d2 * d2
        for i in range(3):
            for j in range(i, 3):
                a[i, j] /= k
                a[j, i] = a[i, j]
        _eigh3(a, v)
        i0, i1, i2 = 0, 1, 2  # the eigenvalues' order, ascending
        if a[i0, i0] > a[i1, i1]:
            i0, i1 = i1, i0
        if a[i1, i1] > a[i2, i2]:
            i1, i2 = i2, i1
        if a[i0, i0] > a[i1, i1]:
            i0, i1 = i1, i0
        ev[qi, 0] = a[i0, i0]
        ev[qi, 1] = a[i1, i1]
        ev[qi, 2] = a[i2, i2]
        for t in range(3):
            normal[qi, t] = v[t, i0]
        if k >= 3:
            chord[qi] = _chord_one(at[qi], grid_pts[rows[1]], grid_pts[rows[2]])
    return ev, normal, chord


@kernel(helper=True)
def _chord_one(q, a, b) -> float:
    """:func:`chord_distance` of one point (the kernels' loop)."""
    u0, u1, u2 = a[0] - q[0], a[1] - q[1], a[2] - q[2]
    v0, v1, v2 = b[0] - q[0], b[1] - q[1], b[2] - q[2]
    nu = np.sqrt(u0 * u0 + u1 * u1 + u2 * u2)
    nv = np.sqrt(v0 * v0 + v1 * v1 + v2 * v2)
    if not (nu > 0.0 and nv > 0.0) or not (u0 * v0 + u1 * v1 + u2 * v2 < CHORD_MAX_COS * nu * nv):
        return np.nan
    w0, w1, w2 = b[0] - a[0], b[1] - a[1], b[2] - a[2]
    p0, p1, p2 = q[0] - a[0], q[1] - a[1], q[2] - a[2]
    c0, c1, c2 = w1 * p2 - w2 * p1, w2 * p0 - w0 * p2, w0 * p1 - w1 * p0
    return np.sqrt(c0 * c0 + c1 * c1 + c2 * c2) / np.sqrt(w0 * w0 + w1 * w1 + w2 * w2)


@kernel(entry="nearest_other", example="_spacing_example", tolerance=1e-12)
def _kth_distance_fast(points, k, grid_pts, starts, lo, shape, cell):
    """(n,) each point's distance to its ``k``-th nearest :func:`~cosco.nearest._grid_build_fast` point (itself the
    first, when indexed)."""
    n = points.shape[0]
    out = np.empty(n)
    best = np.empty(k)
    rows = np.empty(k, dtype=np.int64)
    for p in range(n):
        _k_nearest_into(best, rows, k, points[p, 0], points[p, 1], points[p, 2], grid_pts, starts, lo, shape, cell)
        out[p] = np.sqrt(best[k - 1])
    return out


def nearest_other(points) -> np.ndarray:
    """(n,) each of (n, 3) ``points``' distance to its nearest other point (n >= 2; a duplicate's is 0): a KD-tree's
    second neighbour, or the compiled grid's where the kernels are in use.

    >>> nearest_other(np.array([[0.0, 0, 0], [0, 0, 1], [0, 0, 3]])).tolist()
    [1.0, 1.0, 2.0]
    """
    p = np.ascontiguousarray(points, dtype=np.float64).reshape(-1, 3)
    kernel_fn = fast(_kth_distance_fast)
    if kernel_fn is not None:
        cell = _neighbour_cell(p, 2)
        grid_pts, _, starts, lo, shape = fast(_grid_build_fast)(p, cell)
        return kernel_fn(p, 2, grid_pts, starts, lo, shape, cell)
    from scipy.spatial import cKDTree

    return cKDTree(p).query(p, k=2)[0][:, 1]


def _spacing_example(rng) -> tuple:
    return (np.r_[rng.normal(0, 1, (400, 3)) * [2.0, 0.9, 0.6], rng.normal(0, 0.05, (5, 3)) + 20.0],)


def _example(rng) -> tuple:
    a = rng.uniform(0, 2 * np.pi, 700)
    shell = np.c_[2.0 * np.cos(a), 0.9 * np.sin(a), rng.uniform(0, 1.5, 700)] + rng.normal(0, 0.01, (700, 3))
    return np.r_[shell, rng.normal(0, 0.5, (200, 3))], 12, shell[::4]


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


def surface_of(points, params: CoscoParams = DEFAULT, lines: bool = False, smooth: float | None = None,
               side: bool = False) -> Surface:
    """The :class:`Surface` of one object's ``points`` ((n, 3) metres, n >= 3); ``lines``: the points lie along a
    ground scanner's lines (the thickness measured too); ``smooth``: the scan's smooth surface's roughness
    (:func:`scan_smoothness`), that the object's is told in units of; ``side``: the scan was made from the ground
    (:attr:`Surface.side`; ``lines`` implies it).

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
    ev, normal, chord = neighbourhood_shapes(p, sp.k, at)
    total = np.maximum(ev.sum(axis=1), 1e-18)
    variation = ev[:, 0] / total
    linearity = (ev[:, 2] - ev[:, 1]) / np.maximum(ev[:, 2], 1e-18)
    horizontal = np.abs(normal[:, 2]) >= np.cos(np.radians(sp.horizontal_deg))
    return Surface(variation=round(float(np.median(variation)), 6), linearity=round(float(np.median(linearity)), 6),
                   horizontal=round(float(horizontal.mean()), 6), n=len(at),
                   thickness=round(thickness_of(p), 6) if lines else None,
                   roughness=roughness_of(chord, sp.rough_min_points),
                   smooth=None if smooth is None else round(float(smooth), 6), side=bool(lines or side))


def roughness_of(chord: np.ndarray, min_points: int) -> float | None:
    """The median of the measured ``chord`` distances (m, :func:`neighbourhood_shapes`), None with fewer than
    ``min_points`` of them."""
    c = np.asarray(chord, dtype=np.float64)
    c = c[np.isfinite(c)]
    return round(float(np.median(c)), 6) if len(c) >= max(min_points, 1) else None


def scan_smoothness(ground: np.ndarray, params: CoscoParams = DEFAULT) -> float | None:
    """The roughness (m, as :class:`Surface` measures it) of a scan's smooth surface: its ``ground`` points ((n, 3),
    a road, a car park) in up to ``surface.smooth_windows`` squares ``surface.smooth_window`` m across, each measured
    on all of its points (a scan line's neighbours are the ground's own, at its density); the median of the squares'
    medians. None with too few measured (a square of fewer than ``surface.rough_min_points`` chords counts for
    nothing). The squares are drawn by their points: a grid's cells are taken in turn along the grid, and one is
    drawn every ``1 / smooth_windows`` of the points (where the scan is dense, as a scan line's neighbours are). The
    answer depends on the points, not on their order in the array (a tile read as LAZ or as COPC), and a few passes
    over the array whatever its size (a city's cell holds millions of ground points; a grid of more than 2^20 cells
    is drawn on coarser cells, each measured at its fullest square).

    >>> rng = np.random.default_rng(0)
    >>> x = np.repeat(np.arange(0.0, 20.0, 0.5), 400)  # scan lines across a road, 5 cm apart along each
    >>> road = np.c_[x, np.tile(np.arange(0.0, 20.0, 0.05), 40), rng.normal(0, 0.01, 16000)]
    >>> 0.005 < scan_smoothness(road) < 0.02
    True
    >>> scan_smoothness(road) == scan_smoothness(road[rng.permutation(len(road))])
    True
    """
    g = np.asarray(ground, dtype=np.float64).reshape(-1, 3)
    sp = params.surface
    if len(g) < sp.rough_min_points:
        return None
    w = float(sp.smooth_window)
    lo = column_min(g[:, :2])
    cells = np.floor((column_max(g[:, :2]) - lo) / w).astype(np.int64) + 1
    f = 1  # window squares to a counting cell's side
    while int(-(-cells[0] // f)) * int(-(-cells[1] // f)) > 1 << 20:
        f *= 2
    cx = np.floor((g[:, 0] - lo[0]) / (w * f)).astype(np.int64)
    cy = np.floor((g[:, 1] - lo[1]) / (w * f)).astype(np.int64)
    ny = int(cy.max()) + 1
    key = cx * ny + cy
    counts = np.bincount(key)
    occupied = np.flatnonzero(counts)
    cum = np.cumsum(counts[occupied])
    k = sp.smooth_windows
    picks = np.unique(occupied[np.searchsorted(cum, (np.arange(k) + 0.5) / k * cum[-1], side="right")])
    inside = np.flatnonzero(np.isin(key, picks))
    inside = inside[np.argsort(key[inside], kind="stable")]
    bounds = np.searchsorted(key[inside], np.r_[picks, picks[-1] + 1])
    found = []
    for a, b in zip(bounds[:-1], bounds[1:]):
        win = g[inside[a:b]]
        if f > 1:  # the counting cell's fullest window square
            sub = (np.floor((win[:, 0] - lo[0]) / w).astype(np.int64) % f) * f \
                + np.floor((win[:, 1] - lo[1]) / w).astype(np.int64) % f
            win = win[sub == int(np.argmax(np.bincount(sub)))]
        if len(win) < max(sp.rough_min_points, 3):
            continue
        win = win[np.lexsort((win[:, 2], win[:, 1], win[:, 0]))]  # its points in one order, whatever the array's
        step = max(1, int(np.ceil(len(win) / sp.max_points)))
        r = roughness_of(neighbourhood_shapes(win, sp.k, win[::step])[2], sp.rough_min_points)
        if r is not None:
            found.append(r)
    return round(float(np.median(found)), 6) if found else None
