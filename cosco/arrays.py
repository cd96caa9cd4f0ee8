"""Point arrays as every cosco stage takes them: coerced and checked once, column extremes, voxel keys, voxel
down-sampling. ``(n, 3)`` (or ``(n, 2)``) float64 arrays in metres.
"""

from __future__ import annotations

import numpy as np

from .kernels import fast, kernel


def as_points(points, dim: int = 3, min_points: int = 1) -> np.ndarray:
    """Coerce to a finite ``(n, dim)`` float64 array or raise ``ValueError`` naming the shape.

    >>> as_points([[0, 0, 1]]).dtype
    dtype('float64')
    """
    arr = np.asarray(points, dtype=np.float64)
    if arr.ndim != 2 or arr.shape[1] != dim:
        raise ValueError(f"expected an (n, {dim}) array of points, got shape {arr.shape}")
    if len(arr) < min_points:
        raise ValueError(f"expected at least {min_points} points, got {len(arr)}")
    if not np.isfinite(arr).all():
        raise ValueError("points contain NaN or infinite coordinates")
    return arr


def check_object(points, min_points: int = 10, min_extent: float = 0.01) -> np.ndarray:
    """Coerce one object's points and refuse a degenerate one with ``ValueError`` saying what it is: fewer than
    ``min_points`` distinct points, all points at one spot, on one vertical line, or collinear in plan (an extent
    under ``min_extent`` metres across).

    >>> check_object(np.zeros((5000, 3)))
    Traceback (most recent call last):
    ...
    ValueError: degenerate object: all 5000 points are at one spot (needs at least 10 distinct points)
    """
    arr = as_points(points)
    # distinct x values are distinct points: the full row-unique is needed only when there are few of them
    n_distinct = len(np.unique(arr[:, 0]))
    if n_distinct < min_points:
        n_distinct = len(np.unique(arr, axis=0))
    if n_distinct < min_points:
        what = (f"only {len(arr)} points" if n_distinct == len(arr) else
                f"all {len(arr)} points are at one spot" if n_distinct == 1 else
                f"its {len(arr)} points are at only {n_distinct} distinct positions")
        raise ValueError(f"degenerate object: {what} (needs at least {min_points} distinct points)")
    xy = arr[:, :2]
    if np.ptp(xy, axis=0).max() < min_extent:
        raise ValueError(f"degenerate object: its {len(arr)} points lie on one vertical line (no footprint)")
    centred = xy - xy.mean(0)
    spread = np.sqrt(np.linalg.eigvalsh(centred.T @ centred / len(xy)))
    if spread[0] * 4 < min_extent:
        raise ValueError(f"degenerate object: its {len(arr)} points are collinear in plan (a line {spread[1] * 3.5:.2f}"
                         " m long, no width)")
    return arr


def column_min(a: np.ndarray) -> np.ndarray:
    """The smallest value of each column of an (n, d) array (n >= 1): ``a.min(0)``, column by column (numpy reduces
    an (n, 3) array over its rows many times slower than each column: these bounds are taken on every cell's
    millions of points).

    >>> column_min(np.array([[3, 1], [2, 5]])).tolist(), column_max(np.array([[3, 1], [2, 5]])).tolist()
    ([2, 1], [3, 5])
    """
    a = np.asarray(a)
    return np.array([a[:, k].min() for k in range(a.shape[1])], dtype=a.dtype)


def column_max(a: np.ndarray) -> np.ndarray:
    """The largest value of each column of an (n, d) array: ``a.max(0)``, column by column (see
    :func:`column_min`)."""
    a = np.asarray(a)
    return np.array([a[:, k].max() for k in range(a.shape[1])], dtype=a.dtype)


def cell_keys(cells: np.ndarray) -> np.ndarray:
    """One int64 per row of (n, d) integer cell indices, ordered like the rows (lexicographically); 1-D
    ``np.unique`` on these is many times faster than ``np.unique(axis=0)``.

    >>> cell_keys(np.array([[0, 1], [1, 0], [0, 1]])).tolist()
    [1, 2, 1]
    """
    c = np.asarray(cells, dtype=np.int64)
    if len(c) == 0:
        return np.zeros(0, dtype=np.int64)
    c = c - column_min(c)
    dims = column_max(c) + 1
    key = np.zeros(len(c), dtype=np.int64)
    for k in range(c.shape[1]):
        key = key * dims[k] + c[:, k]
    return key


def first_in_voxels(points: np.ndarray, voxel: float) -> np.ndarray:
    """(m,) sorted rows of (n, d) ``points``: the first point of each occupied voxel of ``voxel`` m (a thinning that
    keeps the points themselves, in their order).

    >>> first_in_voxels(np.array([[0.01, 0, 0], [1.0, 0, 0], [0.02, 0, 0]]), 0.1).tolist()
    [0, 1]
    """
    p = np.asarray(points, dtype=np.float64)
    _, first = np.unique(cell_keys(np.floor(p / voxel).astype(np.int64)), return_index=True)
    return np.sort(first)


def voxel_downsample(points: np.ndarray, voxel: float) -> tuple[np.ndarray, np.ndarray]:
    """Centroids of the occupied voxels and their point counts.

    points : (n, d) float, metres. Returns ``(m, d)`` centroids and ``(m,)`` int counts.

    >>> c, w = voxel_downsample(np.array([[0.01, 0, 0], [0.02, 0, 0], [1.0, 0, 0]]), 0.1)
    >>> len(c), sorted(w.tolist())
    (2, [1, 2])
    """
    pts = np.asarray(points, dtype=np.float64)
    kernel_fn = fast(_voxel_sums_fast)
    if kernel_fn is not None and pts.ndim == 2 and len(pts):
        sums, counts = kernel_fn(np.ascontiguousarray(pts), float(voxel))
        return sums / counts[:, None], counts
    _, inverse, counts = np.unique(cell_keys(np.floor(pts / voxel).astype(np.int64)), return_inverse=True,
                                   return_counts=True)
    inverse = inverse.reshape(-1)
    sums = np.zeros((len(counts), pts.shape[1]))
    np.add.at(sums, inverse, pts)
    return sums / counts[:, None], counts


@kernel(entry="voxel_downsample", example="_voxel_example")
def _voxel_sums_fast(pts, voxel):
    """The occupied voxels' coordinate sums (m, d) and point counts (m,), the voxels in :func:`cell_keys` order and
    each sum taken in the points' order: :func:`voxel_downsample`'s ``np.unique`` and ``np.add.at``, to the bit."""
    n, d = pts.shape
    cells = np.empty((n, d), dtype=np.int64)
    for p in range(n):
        for a in range(d):
            cells[p, a] = np.int64(np.floor(pts[p, a] / voxel))
    key = np.zeros(n, dtype=np.int64)
    for a in range(d):
        lo = cells[0, a]
        hi = cells[0, a]
        for p in range(n):
            lo = min(lo, cells[p, a])
            hi = max(hi, cells[p, a])
        for p in range(n):
            key[p] = key[p] * (hi - lo + 1) + (cells[p, a] - lo)
    order = np.argsort(key, kind="mergesort")
    inverse = np.empty(n, dtype=np.int64)
    m = 0
    for j in range(n):
        if j > 0 and key[order[j]] != key[order[j - 1]]:
            m += 1
        inverse[order[j]] = m
    m = m + 1 if n else 0
    sums = np.zeros((m, d))
    counts = np.zeros(m, dtype=np.int64)
    for p in range(n):
        counts[inverse[p]] += 1
        for a in range(d):
            sums[inverse[p], a] += pts[p, a]
    return sums, counts


def _voxel_example(rng) -> tuple:
    return rng.normal(0, 1, (500, 3)) * [2.0, 0.9, 0.6], 0.1


def point_spacing(local: np.ndarray, cell: float = 0.5) -> float:
    """Typical point spacing (m) from the density over the occupied footprint (O(n), no tree).

    >>> g = np.mgrid[0:10:0.1, 0:10:0.1].reshape(2, -1).T
    >>> round(point_spacing(np.c_[g, np.zeros(len(g))]), 3)
    0.1
    """
    if len(local) < 3:
        return 0.0
    density = len(local) / (n_cells(local, cell) * cell * cell)
    return float(1.0 / np.sqrt(density))


def n_cells(points: np.ndarray, cell: float) -> int:
    """How many ``cell`` squares (m) of the x/y grid anchored at 0 the (n, 2+) points occupy.

    >>> n_cells(np.array([[0.05, 0.0], [0.09, 0.01], [-0.01, 0.0], [0.3, 0.2]]), 0.1)
    3
    """
    return len(np.unique(cell_keys(np.floor(np.asarray(points)[:, :2] / cell).astype(np.int64))))


def box_rows(x: np.ndarray, y: np.ndarray, boxes: np.ndarray) -> list[np.ndarray]:
    """The rows of the points (``x``, ``y``) inside each closed box ``boxes[k]`` = (x0, y0, x1, y1), in order, a
    box at a time (compiled: every box in two passes over the points).

    >>> [r.tolist() for r in box_rows(np.array([0.0, 1.0, 2.0]), np.zeros(3), np.array([[0.0, 0.0, 1.0, 0.0]]))]
    [[0, 1]]
    """
    boxes = np.asarray(boxes, dtype=np.float64).reshape(-1, 4)
    kern = fast(_box_rows_fast)
    if kern is not None:
        rows, starts = kern(np.ascontiguousarray(x, dtype=np.float64), np.ascontiguousarray(y, dtype=np.float64),
                            boxes)
        return [rows[starts[k]:starts[k + 1]] for k in range(len(boxes))]
    out = []
    for x0, y0, x1, y1 in boxes:
        inside = x >= x0
        inside &= x <= x1
        inside &= y >= y0
        inside &= y <= y1
        out.append(np.flatnonzero(inside))
    return out


def _boxes_example(rng) -> tuple:
    xy = rng.uniform(0, 10, (2000, 2))
    return xy[:, 0].copy(), xy[:, 1].copy(), np.array([[0.0, 0.0, 5.0, 5.0], [4.0, 2.0, 10.0, 6.0], [20, 20, 21, 21]])


@kernel(entry="box_rows", example="_boxes_example", helper=True)
def _box_rows_fast(x, y, boxes):
    """The rows of the points (``x``, ``y``) inside each closed box ``boxes[k]`` = (x0, y0, x1, y1), in order:
    box k's are ``rows[starts[k]:starts[k + 1]]`` (two passes over the points for every box)."""
    n, m = x.shape[0], boxes.shape[0]
    starts = np.zeros(m + 1, dtype=np.int64)
    for rnd in range(2):
        if rnd == 1:
            for k in range(m):
                starts[k + 1] += starts[k]
            rows = np.empty(starts[m], dtype=np.int64)
            fill = starts[:m].copy()
        for p in range(n):
            for k in range(m):
                if x[p] >= boxes[k, 0] and x[p] <= boxes[k, 2] and y[p] >= boxes[k, 1] and y[p] <= boxes[k, 3]:
                    if rnd == 0:
                        starts[k + 1] += 1
                    else:
                        rows[fill[k]] = p
                        fill[k] += 1
    return rows, starts
