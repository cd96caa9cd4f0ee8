"""The ground of a whole scan, block by block (the module text of :mod:`cosco.ground`): the blocks holding points,
each one's window of points with its halo, filtered (:mod:`.window`) and its core kept; the compiled passes
beside their references."""

from __future__ import annotations

import numpy as np

from ..arrays import _box_rows_fast, as_points, column_max, column_min
from ..kernels import fast, kernel
from ..params import DEFAULT, CoscoParams
from ..sorting import group_by_key
from .surface import Ground
from .window import _fill_nearest, _window_ground

#: up to this many blocks, each block's points are found by one pass over all of them (a few cheap comparisons);
#: beyond, by grouping the points by block once (a sort)
FEW_BLOCKS = 8


def estimate_ground(points, params: CoscoParams = DEFAULT) -> Ground:
    """The ground surface under a scene, block by block (see the module docstring).

    points : (n, 3) float, metres (large projected coordinates are fine, but a scene-local frame keeps the float
    arithmetic exact).
    """
    pts = as_points(points)
    cell, b, h = params.ground.cell, params.ground.block, params.ground.halo
    # blocks on a lattice anchored at the frame's origin: a tile of a larger scene (same frame) gets the same blocks
    origin = (np.floor(column_min(pts[:, :2]) / (cell * b)) * (cell * b)).astype(np.float64)
    # cell indices: truncation is floor (the offsets are non-negative) and monotonic, so the largest index is the
    # largest coordinate's
    extent = ((column_max(pts[:, :2]) - origin) / cell).astype(np.int64) + 1
    n_cols = int(extent[1] // b + 1)
    keys, window_of = _blocks(pts, origin, extent, n_cols, params)
    tiles = np.empty((len(keys), b, b))
    for k, key in enumerate(keys):
        bi, bj = divmod(int(key), n_cols)
        lo, hi = _window_bounds(bi, bj, b, h, extent)
        z = _window_ground(window_of(k, bi, bj, lo, hi), origin + lo * cell, tuple(hi - lo), params)
        core = np.full((b, b), np.nan)
        a0, a1 = bi * b - lo[0], bj * b - lo[1]
        part = z[a0:a0 + b, a1:a1 + b]
        core[:part.shape[0], :part.shape[1]] = part
        tiles[k] = core
    # cells beyond the scan's extent inside a block take their nearest known value (edges of the data)
    for k in range(len(keys)):
        known = np.isfinite(tiles[k])
        if not known.all():
            tiles[k] = _fill_nearest(np.where(known, tiles[k], 0.0), known)
    return Ground(origin, cell, b, n_cols, keys, tiles)


def _window_bounds(bi: int, bj: int, b: int, h: int, extent: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The cells (lo, hi; half-open) of block (bi, bj)'s window: the block and its halo, inside the extent."""
    lo = np.maximum(np.array([bi * b - h, bj * b - h]), 0)
    hi = np.minimum(np.array([(bi + 1) * b + h, (bj + 1) * b + h]), extent)
    return lo, hi


def _blocks(pts: np.ndarray, origin: np.ndarray, extent: np.ndarray, n_cols: int, params: CoscoParams):
    """The keys of the blocks holding points, and ``window_of(k, bi, bj, lo, hi)``: block k's window's points, in
    their order."""
    cell, b, h = params.ground.cell, params.ground.block, params.ground.halo
    if (extent <= b).all():  # one block (a scene or a city cell of up to 512 m): no grouping of the points
        return np.zeros(1, dtype=np.int64), lambda k, bi, bj, lo, hi: pts
    counts_fast, rows_fast = fast(_block_counts_fast), fast(_window_rows_fast)
    if counts_fast is None:
        return _blocks_numpy(pts, origin, n_cols, params)
    # compiled: the blocks holding points counted in one pass, no (n,) cells kept; the windows' points in one pass
    pts = np.ascontiguousarray(pts)
    n_rows = int(extent[0] // b + 1)
    keys = np.flatnonzero(counts_fast(pts, origin, float(cell), int(b), n_cols, n_rows * n_cols))
    bounds = []
    for key in keys:
        lo, hi = _window_bounds(*divmod(int(key), n_cols), b, h, extent)
        bounds.append([lo[0], hi[0], lo[1], hi[1]])
    rows, starts = rows_fast(pts, origin, float(cell), np.array(bounds, dtype=np.int64))
    return keys, lambda k, bi, bj, lo, hi: pts[rows[starts[k]:starts[k + 1]]]


def _blocks_numpy(pts: np.ndarray, origin: np.ndarray, n_cols: int, params: CoscoParams):
    """:func:`_blocks`' reference: every point's cell once (32-bit: a grid of 2^31 cells is a million kilometres
    wide); with many blocks, each takes its points from its neighbours' groups, else one pass over the points."""
    cell, b = params.ground.cell, params.ground.block
    ci = ((pts[:, 0] - origin[0]) / cell).astype(np.int32)
    cj = ((pts[:, 1] - origin[1]) / cell).astype(np.int32)
    bkey = (ci // b).astype(np.int64) * n_cols
    bkey += cj // b
    keys = np.flatnonzero(np.bincount(bkey))
    many = len(keys) > FEW_BLOCKS
    if many:
        order, _, starts = group_by_key(bkey)
        ends = np.r_[starts[1:], len(order)]
    del bkey

    def window_of(k, bi, bj, lo, hi):
        if many:
            wanted = np.array([(bi + di) * n_cols + bj + dj for di in (-1, 0, 1) for dj in (-1, 0, 1)
                               if 0 <= bi + di and 0 <= bj + dj < n_cols])
            pos = np.clip(np.searchsorted(keys, wanted), 0, len(keys) - 1)
            idx = np.concatenate([order[starts[n]:ends[n]] for n in pos[keys[pos] == wanted]])
            inside = (ci[idx] >= lo[0]) & (ci[idx] < hi[0]) & (cj[idx] >= lo[1]) & (cj[idx] < hi[1])
            return pts[idx[inside]]
        inside = ci >= lo[0]  # a few blocks (a city cell across the lattice's lines): one pass over the points each
        inside &= ci < hi[0]
        inside &= cj >= lo[1]
        inside &= cj < hi[1]
        return pts[np.flatnonzero(inside)]

    return keys, window_of


def remove_ground(points, params: CoscoParams = DEFAULT) -> tuple[np.ndarray, np.ndarray, Ground]:
    """Split a scene into ground and the rest.

    Returns ``(is_ground (n,) bool, height_above_ground (n,) float m, ground)``.
    """
    pts = as_points(points)
    ground = estimate_ground(pts, params)
    hag = ground.height(pts)
    return hag < params.ground.tol, hag, ground


def _blocks_example(rng) -> tuple:
    """A scan over several blocks of a small lattice (the registry's example for :func:`estimate_ground`)."""
    pts = np.c_[rng.uniform(0, 60, (6000, 2)), rng.normal(0, 0.05, 6000)]
    return pts, DEFAULT.with_(ground={"block": 24, "halo": 16})


@kernel(entry="estimate_ground", example="_blocks_example")
def _block_counts_fast(pts, origin, cell, block, n_cols, n_blocks):
    """Points in each block of ``block`` cells (key ``bi * n_cols + bj``, cells truncated as 32-bit integers like
    :func:`estimate_ground`'s)."""
    counts = np.zeros(n_blocks, dtype=np.int64)
    for p in range(pts.shape[0]):
        ci = np.int64(np.int32((pts[p, 0] - origin[0]) / cell))
        cj = np.int64(np.int32((pts[p, 1] - origin[1]) / cell))
        counts[(ci // block) * n_cols + cj // block] += 1
    return counts


@kernel(entry="estimate_ground", example="_blocks_example")
def _window_rows_fast(pts, origin, cell, bounds):
    """The rows of the points whose cell (i, j) (truncated as 32-bit integers) lies in each window ``bounds[k]`` =
    (i0, i1, j0, j1) (half-open), in order: window k's are ``rows[starts[k]:starts[k + 1]]``
    (:func:`~cosco.arrays.box_rows` on the cells' indices)."""
    n, m = pts.shape[0], bounds.shape[0]
    ci = np.empty(n)
    cj = np.empty(n)
    for p in range(n):
        ci[p] = np.float64(np.int32((pts[p, 0] - origin[0]) / cell))
        cj[p] = np.float64(np.int32((pts[p, 1] - origin[1]) / cell))
    boxes = np.empty((m, 4))
    for k in range(m):
        boxes[k, 0], boxes[k, 1] = bounds[k, 0], bounds[k, 2]
        boxes[k, 2], boxes[k, 3] = bounds[k, 1] - 1, bounds[k, 3] - 1
    return _box_rows_fast(ci, cj, boxes)
