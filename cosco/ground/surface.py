"""The ground surface and heights above it: a dense window's (:class:`_Grid`) and a scan's, stored by blocks
(:class:`Ground`), each height bilinear under its point; the compiled heights beside their references."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..kernels import fast, kernel


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

        pts = np.ascontiguousarray(points, dtype=np.float64)
        kern = fast(_grid_heights_fast)
        if kern is not None:  # compiled: the same heights bit for bit, no (2, n) positions
            return kern(pts, np.asarray(self.origin, dtype=np.float64), float(self.cell),
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
        kern = fast(_ground_heights_fast)
        if kern is None:
            return self.height_numpy(points)
        pts = np.ascontiguousarray(points, dtype=np.float64)
        # compiled: the points inside a stored block's cells, bit for bit the reference's heights;
        # the few whose cells straddle a block's edge, the reference's
        h, done = kern(pts, np.asarray(self.origin, dtype=np.float64), float(self.cell), int(self.block),
                       int(self.n_block_cols), np.ascontiguousarray(self.keys, dtype=np.int64),
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


def _grid_example(rng) -> tuple:
    """A window's surface and points over it and beyond (the registry's example for :meth:`_Grid.height`)."""
    return _Grid(np.array([3.0, -2.0]), 0.5, rng.normal(0, 0.3, (40, 30))), rng.uniform(-5, 25, (3000, 3))


def _ground_example(rng) -> tuple:
    """A ground of four stored blocks of six cells and points over them, across their edges and beyond (the
    registry's example for :meth:`Ground.height`)."""
    keys = np.array([0, 1, 3, 4], dtype=np.int64)
    ground = Ground(np.array([1.0, 2.0]), 0.5, 6, 3, keys, rng.normal(0, 0.3, (4, 6, 6)))
    return ground, rng.uniform(-2, 12, (3000, 3))


@kernel(helper=True)
def _linear(values, x, y):
    """scipy.ndimage.map_coordinates(values, [[x], [y]], order=1, mode="nearest", prefilter=False): its weights
    and its sum in its order (bit for bit)."""
    nx, ny = values.shape
    fx, fy = np.floor(x), np.floor(y)
    wx1 = x - fx
    wx0 = 1.0 - wx1
    wx1 = 1.0 - wx0
    wy1 = y - fy
    wy0 = 1.0 - wy1
    wy1 = 1.0 - wy0
    i0, j0 = np.int64(fx), np.int64(fy)
    i1, j1 = min(max(i0 + 1, 0), nx - 1), min(max(j0 + 1, 0), ny - 1)
    i0, j0 = min(max(i0, 0), nx - 1), min(max(j0, 0), ny - 1)
    t = 0.0
    t += values[i0, j0] * wx0 * wy0
    t += values[i0, j1] * wx0 * wy1
    t += values[i1, j0] * wx1 * wy0
    t += values[i1, j1] * wx1 * wy1
    return t


@kernel(entry="_Grid.height", example="_grid_example")
def _grid_heights_fast(pts, origin, cell, values):
    """:meth:`_Grid.height`: each point's z minus the bilinear surface under it (the edge cells'
    values beyond the window)."""
    n = pts.shape[0]
    out = np.empty(n)
    for p in range(n):
        x = (pts[p, 0] - origin[0]) / cell - 0.5
        y = (pts[p, 1] - origin[1]) / cell - 0.5
        out[p] = pts[p, 2] - _linear(values, x, y)
    return out


@kernel(entry="Ground.height", example="_ground_example")
def _ground_heights_fast(pts, origin, cell, block, n_cols, keys, tiles):
    """:meth:`Ground.height` for the points whose four surrounding cells lie in one stored block:
    their heights, and a mask of those (the others, at block edges, are the caller's)."""
    n = pts.shape[0]
    out = np.empty(n)
    done = np.zeros(n, dtype=np.bool_)
    nk = keys.shape[0]
    for p in range(n):
        x = (pts[p, 0] - origin[0]) / cell - 0.5
        y = (pts[p, 1] - origin[1]) / cell - 0.5
        i, j = np.int64(np.floor(x)), np.int64(np.floor(y))
        if i < 0 or j < 0:
            continue
        bi, bj = i // block, j // block
        if bj >= n_cols:
            continue
        if i - bi * block >= block - 1 or j - bj * block >= block - 1:
            continue
        key = bi * n_cols + bj
        lo, hi = 0, nk
        while lo < hi:
            mid = (lo + hi) // 2
            if keys[mid] < key:
                lo = mid + 1
            else:
                hi = mid
        if lo == nk or keys[lo] != key:
            continue
        out[p] = pts[p, 2] - _linear(tiles[lo], x - bi * block, y - bj * block)
        done[p] = True
    return out, done
