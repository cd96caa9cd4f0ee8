"""Ground removal and height above ground (paper 3.1: "background removal").

A grid-based progressive morphological filter (after Zhang et al. 2003) instead of the paper's single RANSAC plane,
so that slopes, kerbs and ramps of real car parks stay ground:

1. the lowest point of every ``cell`` (empty cells take their nearest neighbour's value);
2. grey openings with growing windows; a cell whose surface stands above the opening by more than a threshold that
   grows with the window (``slope`` per metre of window growth, capped) is not ground: car roofs and walls go at
   the window that is wider than them; an opening leaves a planar ramp as it is, so a last strict test against the
   widest opening removes what is left of cars (bumpers, sills) and keeps ramps;
3. the ground surface is the lowest points of the ground cells, with holes (under cars, buildings) filled by
   normalised convolution so it bends smoothly under them; a second pass replaces each ground cell's lowest point
   by the median of the points near the surface (the lowest of noisy points lies a few sigmas too low);
4. every point's height above ground is its z minus the bilinear ground surface under it.

Memory goes by occupied cells, not by the bounding box: the grid is cut into blocks of ``ground.block`` cells and
only blocks holding points are processed, each as a dense window with a halo of ``ground.halo`` cells (more than
the widest opening window and the smoothing reach), of which the block's core is kept. A scan that fits in one
block is processed as one window, exactly as the steps above say; one stray point 30 km away adds one small block,
not a 60,000 x 60,000 grid.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .arrays import as_points, column_max, column_min
from .params import DEFAULT, CoscoParams
from .sorting import group_by_key, group_medians


@dataclass(frozen=True)
class _Grid:
    """A dense ground surface on one window: ``z[i, j]`` at ``origin + (i + 0.5, j + 0.5) * cell``."""

    origin: np.ndarray
    cell: float
    z: np.ndarray

    def height(self, points: np.ndarray) -> np.ndarray:
        """Height (m) of (n, 3) points above the surface, bilinear between cell centres (the edge cells' values
        beyond the window)."""
        from scipy import ndimage

        from .kernels import jit

        pts = np.ascontiguousarray(points, dtype=np.float64)
        mod = jit()
        if mod is not None:  # compiled (cosco.kernels): the same heights bit for bit, no (2, n) positions
            return mod.grid_heights(pts, np.asarray(self.origin, dtype=np.float64), float(self.cell),
                                    np.ascontiguousarray(self.z, dtype=np.float64))
        z = ndimage.map_coordinates(self.z, _grid_positions(pts, self.origin, self.cell), order=1, mode="nearest",
                                    prefilter=False)
        return np.subtract(pts[:, 2], z, out=z)


def _grid_positions(pts: np.ndarray, origin, cell: float, shift: float = 0.5) -> np.ndarray:
    """(2, n) positions of points on a grid of ``cell`` squares at ``origin``, in cells from the first cell's
    centre: ``(pts[:, :2] - origin) / cell - shift``, one row at a time (no (n, 2) temporaries)."""
    g = np.empty((2, len(pts)))
    for k in (0, 1):
        np.subtract(pts[:, k], origin[k], out=g[k])
        g[k] /= cell
        g[k] -= shift
    return g


def _cell_index(pts: np.ndarray, origin, cell: float, shape) -> np.ndarray:
    """(n,) int64 C-order index into a grid of ``shape`` cells at ``origin`` of points inside it (truncation is
    floor: the offsets are non-negative)."""
    flat = ((pts[:, 0] - origin[0]) / cell).astype(np.int64)
    flat *= shape[1]
    flat += ((pts[:, 1] - origin[1]) / cell).astype(np.int64)
    return flat


@dataclass(frozen=True)
class Ground:
    """A ground surface on a sparse grid of ``cell`` squares (metres): the cell (i, j) is centred at
    ``origin + (i + 0.5, j + 0.5) * cell``; only blocks of ``block`` x ``block`` cells holding points are stored,
    as ``tiles[k]`` for the block of key ``keys[k]`` (``bi * n_block_cols + bj``, sorted)."""

    origin: np.ndarray
    cell: float
    block: int
    n_block_cols: int
    keys: np.ndarray
    tiles: np.ndarray

    def shifted(self, dx: float, dy: float, dz: float) -> "Ground":
        """The same surface in a frame shifted by (dx, dy, dz) metres."""
        return Ground(self.origin + [dx, dy], self.cell, self.block, self.n_block_cols, self.keys, self.tiles + dz)

    def _z(self, i: np.ndarray, j: np.ndarray) -> np.ndarray:
        """Surface z at integer cells (NaN outside the stored blocks)."""
        b = self.block
        key = (i // b) * self.n_block_cols + (j // b)
        pos = np.clip(np.searchsorted(self.keys, key), 0, len(self.keys) - 1)
        ok = (self.keys[pos] == key) & (i >= 0) & (j >= 0) & (j // b < self.n_block_cols)  # (no wrap to the next row)
        out = np.full(len(i), np.nan)
        out[ok] = self.tiles[pos[ok], i[ok] % b, j[ok] % b]
        return out

    def height(self, points: np.ndarray) -> np.ndarray:
        """Height above ground (m) of (n, 3) points, bilinear under each point (nearest stored cell beyond the
        edges of the stored blocks)."""
        from .kernels import jit

        mod = jit()
        if mod is None:
            return self.height_numpy(points)
        pts = np.ascontiguousarray(points, dtype=np.float64)
        # compiled (cosco.kernels): the points inside a stored block's cells, bit for bit the reference's heights;
        # the few whose cells straddle a block's edge, the reference's
        h, done = mod.ground_heights(pts, np.asarray(self.origin, dtype=np.float64), float(self.cell),
                                     int(self.block), int(self.n_block_cols),
                                     np.ascontiguousarray(self.keys, dtype=np.int64),
                                     np.ascontiguousarray(self.tiles, dtype=np.float64))
        rest = np.flatnonzero(~done)
        if len(rest):
            h[rest] = self.height_numpy(pts[rest])
        return h

    def height_numpy(self, points: np.ndarray) -> np.ndarray:
        """The numpy reference of :meth:`height`."""
        from scipy import ndimage

        pts = np.asarray(points, dtype=np.float64)
        g = _grid_positions(pts, self.origin, self.cell)
        i, j = np.floor(g[0]).astype(np.int64), np.floor(g[1]).astype(np.int64)
        b = self.block
        key = (i // b) * self.n_block_cols + (j // b)
        pos = np.clip(np.searchsorted(self.keys, key), 0, len(self.keys) - 1)
        # a point whose four surrounding cells lie in one stored block: interpolated inside that block (C speed)
        inner = (self.keys[pos] == key) & (i >= 0) & (j >= 0) & (i % b < b - 1) & (j % b < b - 1)
        inner &= j // b < self.n_block_cols  # a point east of the last block column is not in the next row's first
        del key
        z = np.empty(len(pts))
        if len(self.keys) == 1 and inner.all():  # one block holds every point (a scene, a city cell)
            bi, bj = divmod(int(self.keys[0]), self.n_block_cols)
            g[0] -= bi * b
            g[1] -= bj * b
            ndimage.map_coordinates(self.tiles[0], g, order=1, prefilter=False, output=z)
            return np.subtract(pts[:, 2], z, out=z)
        idx = np.flatnonzero(inner)
        if len(idx):
            blocks = np.unique(pos[idx])
            if len(blocks) > 1:
                idx = idx[np.argsort(pos[idx], kind="stable")]
            bounds = np.searchsorted(pos[idx], blocks) if len(blocks) > 1 else np.array([0])
            for k, start in zip(blocks, bounds):
                end = np.searchsorted(pos[idx], k, side="right") if len(blocks) > 1 else len(idx)
                sel = idx[start:end]
                bi, bj = divmod(int(self.keys[k]), self.n_block_cols)
                local = g[:, sel] - np.array([[bi * b], [bj * b]])
                z[sel] = ndimage.map_coordinates(self.tiles[k], local, order=1, prefilter=False)
        rest = np.flatnonzero(~inner)
        if len(rest):
            z[rest] = self._bilinear(g[:, rest].T, i[rest], j[rest])
        return np.subtract(pts[:, 2], z, out=z)

    def _bilinear(self, g: np.ndarray, i: np.ndarray, j: np.ndarray) -> np.ndarray:
        """The surface under grid positions ``g`` near block edges: the known corners' weights renormalised."""
        fx, fy = g[:, 0] - i, g[:, 1] - j
        corners = np.column_stack([self._z(i, j), self._z(i + 1, j), self._z(i, j + 1), self._z(i + 1, j + 1)])
        w = np.column_stack([(1 - fx) * (1 - fy), fx * (1 - fy), (1 - fx) * fy, fx * fy])
        known = np.isfinite(corners)
        w = np.where(known, w, 0.0)
        total = w.sum(1)
        z = np.where(total > 1e-9, (np.where(known, corners, 0.0) * w).sum(1) / np.maximum(total, 1e-12), np.nan)
        lost = ~np.isfinite(z)
        if lost.any():  # no stored cell around the point: the nearest stored cell's value
            z[lost] = self._nearest(g[lost])
        return z

    def _nearest(self, g: np.ndarray) -> np.ndarray:
        from scipy.spatial import cKDTree

        b = self.block
        bi, bj = np.divmod(self.keys, self.n_block_cols)
        centres = np.column_stack([bi * b + b / 2, bj * b + b / 2])
        _, k = cKDTree(centres).query(g)
        ii = np.clip(np.floor(g[:, 0]).astype(np.int64) - bi[k] * b, 0, b - 1)
        jj = np.clip(np.floor(g[:, 1]).astype(np.int64) - bj[k] * b, 0, b - 1)
        return self.tiles[k, ii, jj]


#: up to this many blocks, each block's points are found by one pass over all of them (a few cheap comparisons);
#: beyond, by grouping the points by block once (a sort)
FEW_BLOCKS = 8


def _fill_nearest(values: np.ndarray, known: np.ndarray) -> np.ndarray:
    from scipy import ndimage

    if known.all():
        return values
    _, (ii, jj) = ndimage.distance_transform_edt(~known, return_indices=True)
    return values[ii, jj]


def _fill_smooth(values: np.ndarray, known: np.ndarray, sigma_cells: float) -> np.ndarray:
    """Holes filled by normalised convolution (a smooth membrane); known cells keep their values."""
    from scipy import ndimage

    if known.all():
        return values
    base = _fill_nearest(values, known)
    w = ndimage.gaussian_filter(known.astype(np.float64), sigma_cells, mode="nearest")
    s = ndimage.gaussian_filter(np.where(known, values, 0.0), sigma_cells, mode="nearest")
    smooth = np.where(w > 1e-3, s / np.maximum(w, 1e-12), base)
    return np.where(known, values, smooth)


def _window_ground(pts: np.ndarray, origin: np.ndarray, shape: tuple, params: CoscoParams) -> np.ndarray:
    """The filter on one dense window of ``shape`` cells at ``origin`` (every point inside it): the surface z."""
    from scipy import ndimage

    from .kernels import jit

    cell = params.ground.cell
    mod = jit()
    if mod is not None:  # compiled (cosco.kernels): the same cells and lowest points in one pass
        pts = np.ascontiguousarray(pts, dtype=np.float64)
        origin = np.asarray(origin, dtype=np.float64)
        flat, zmin = mod.cell_lowest(pts, origin, float(cell), int(shape[1]), int(shape[0] * shape[1]))
    else:
        flat = _cell_index(pts, origin, cell, shape)
        zmin = np.full(shape[0] * shape[1], np.inf)
        np.minimum.at(zmin, flat, pts[:, 2])
    zmin = zmin.reshape(shape)
    occupied = np.isfinite(zmin)
    surface = _fill_nearest(np.where(occupied, zmin, 0.0), occupied)

    ground = occupied.copy()
    raw = surface
    previous = 0.0
    for window in params.ground.windows:
        size = max(1, int(round(window / cell)))
        opened = ndimage.grey_opening(surface, size=(size, size), mode="nearest")
        threshold = min(params.ground.dh_max, params.ground.dh0 + params.ground.slope * (window - previous))
        ground &= surface - opened <= threshold
        surface = opened
        previous = window
    # an opening keeps planar slopes exactly, so a strict last test against the widest opening drops the edges
    # of cars (bumpers, sills) that the growing thresholds let through, and keeps ramps
    ground &= raw - surface <= params.ground.dh_final
    if not ground.any():
        ground = occupied
    z = _fill_smooth(np.where(ground, zmin, 0.0), ground, sigma_cells=max(1.0, 2.0 / cell))
    # the lowest point of a cell sits a few range-noise sigmas under the true ground: a second pass takes the
    # median of the points near that first surface in each ground cell
    if mod is not None:  # the same test, compiled: no (n,) heights
        near = mod.near_surface(pts, origin, float(cell), np.ascontiguousarray(z, dtype=np.float64), ground.ravel(),
                                flat, float(params.ground.tol))
    else:
        h = _Grid(origin=origin, cell=cell, z=z).height(pts)
        near = np.abs(h, out=h) < params.ground.tol
        del h
        near &= ground.ravel()[flat]
    if near.any():
        zmed = np.full(shape[0] * shape[1], np.nan)
        flat = flat[near]
        keys, medians = group_medians(flat, pts[near, 2])
        del flat
        zmed[keys] = medians
        zmed = zmed.reshape(shape)
        known = np.isfinite(zmed)
        z = _fill_smooth(np.where(known, zmed, 0.0), known, sigma_cells=max(1.0, 2.0 / cell))
    return z


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
    from .kernels import jit

    mod = jit()
    compiled = mod is not None and not (extent <= b).all()
    if (extent <= b).all():  # one block (a scene or a city cell of up to 512 m): no grouping of the points
        keys, ci, cj = np.zeros(1, dtype=np.int64), None, None
    elif compiled:  # (cosco.kernels) the blocks holding points counted in one pass, no (n,) cells kept
        pts = np.ascontiguousarray(pts)
        n_rows = int(extent[0] // b + 1)
        keys = np.flatnonzero(mod.block_counts(pts, origin, float(cell), int(b), n_cols, n_rows * n_cols))
        ci = cj = None
        bounds = []
        for key in keys:
            bi, bj = divmod(int(key), n_cols)
            lo = np.maximum(np.array([bi * b - h, bj * b - h]), 0)
            hi = np.minimum(np.array([(bi + 1) * b + h, (bj + 1) * b + h]), extent)
            bounds.append([lo[0], hi[0], lo[1], hi[1]])
        rows, starts = mod.window_rows(pts, origin, float(cell), np.array(bounds, dtype=np.int64))
    else:
        # every point's cell, once (32-bit: a grid of 2^31 cells is a million kilometres wide)
        ci = ((pts[:, 0] - origin[0]) / cell).astype(np.int32)
        cj = ((pts[:, 1] - origin[1]) / cell).astype(np.int32)
        bkey = (ci // b).astype(np.int64) * n_cols
        bkey += cj // b
        keys = np.flatnonzero(np.bincount(bkey))
        if len(keys) > FEW_BLOCKS:  # many blocks: each takes its points from its neighbours' groups
            order, _, starts = group_by_key(bkey)
            ends = np.r_[starts[1:], len(order)]
        del bkey
    tiles = np.empty((len(keys), b, b))
    for k, key in enumerate(keys):
        bi, bj = divmod(int(key), n_cols)
        lo = np.maximum(np.array([bi * b - h, bj * b - h]), 0)
        hi = np.minimum(np.array([(bi + 1) * b + h, (bj + 1) * b + h]), extent)
        if compiled:  # the window's points in one pass (their order kept, as below)
            window = pts[rows[starts[k]:starts[k + 1]]]
        elif ci is None:
            window = pts
        else:
            if len(keys) > FEW_BLOCKS:
                wanted = np.array([(bi + di) * n_cols + bj + dj for di in (-1, 0, 1) for dj in (-1, 0, 1)
                                   if 0 <= bi + di and 0 <= bj + dj < n_cols])
                pos = np.clip(np.searchsorted(keys, wanted), 0, len(keys) - 1)
                idx = np.concatenate([order[starts[n]:ends[n]] for n in pos[keys[pos] == wanted]])
                inside = (ci[idx] >= lo[0]) & (ci[idx] < hi[0]) & (cj[idx] >= lo[1]) & (cj[idx] < hi[1])
                idx = idx[inside]
            else:  # a few blocks (a city cell across the lattice's lines): one pass over the points each
                inside = ci >= lo[0]
                inside &= ci < hi[0]
                inside &= cj >= lo[1]
                inside &= cj < hi[1]
                idx = np.flatnonzero(inside)
            del inside
            window = pts[idx]
            del idx
        z = _window_ground(window, origin + lo * cell, tuple(hi - lo), params)
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


def remove_ground(points, params: CoscoParams = DEFAULT) -> tuple[np.ndarray, np.ndarray, Ground]:
    """Split a scene into ground and the rest.

    Returns ``(is_ground (n,) bool, height_above_ground (n,) float m, ground)``.
    """
    pts = as_points(points)
    ground = estimate_ground(pts, params)
    hag = ground.height(pts)
    return hag < params.ground.tol, hag, ground
