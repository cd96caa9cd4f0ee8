"""The morphological filter on one dense window of cells (the module text of :mod:`cosco.ground`, steps 1-3):
its lowest points, openings, the surface filled under what is not ground, and the second pass's medians; the
compiled passes beside their references."""

from __future__ import annotations

import numpy as np

from ..kernels import fast, kernel
from ..params import DEFAULT, CoscoParams
from ..sorting import group_medians
from .surface import _Grid, _linear


def _cell_index(pts: np.ndarray, origin, cell: float, shape) -> np.ndarray:
    """(n,) int64 C-order index into a grid of ``shape`` cells at ``origin`` of points inside it (truncation is
    floor: the offsets are non-negative)."""
    flat = ((pts[:, 0] - origin[0]) / cell).astype(np.int64)
    flat *= shape[1]
    flat += ((pts[:, 1] - origin[1]) / cell).astype(np.int64)
    return flat


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

    cell = params.ground.cell
    lowest, near_fast = fast(_cell_lowest_fast), fast(_near_surface_fast)
    if lowest is not None:  # compiled: the same cells and lowest points in one pass
        pts = np.ascontiguousarray(pts, dtype=np.float64)
        origin = np.asarray(origin, dtype=np.float64)
        flat, zmin = lowest(pts, origin, float(cell), int(shape[1]), int(shape[0] * shape[1]))
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
    if near_fast is not None:  # the same test, compiled: no (n,) heights
        near = near_fast(pts, origin, float(cell), np.ascontiguousarray(z, dtype=np.float64), ground.ravel(), flat,
                         float(params.ground.tol))
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


def _window_example(rng) -> tuple:
    """A window of ground with a car-sized box on it (the registry's example for :func:`_window_ground`)."""
    ground = np.c_[rng.uniform(0, 20, (4000, 2)), rng.normal(0, 0.02, 4000)]
    car = np.c_[rng.uniform([6, 6], [10.5, 8], (800, 2)), rng.uniform(0.3, 1.5, 800)]
    return np.vstack([ground, car]), np.zeros(2), (40, 40), DEFAULT


@kernel(entry="_window_ground", example="_window_example")
def _cell_lowest_fast(pts, origin, cell, ny, n_cells):
    """:func:`_window_ground`'s first pass: each point's cell (C order, ``ny`` cells a row; truncation
    is floor) and each cell's lowest z (inf where empty)."""
    n = pts.shape[0]
    flat = np.empty(n, dtype=np.int64)
    zmin = np.full(n_cells, np.inf)
    for p in range(n):
        f = np.int64((pts[p, 0] - origin[0]) / cell) * ny + np.int64((pts[p, 1] - origin[1]) / cell)
        flat[p] = f
        if pts[p, 2] < zmin[f]:
            zmin[f] = pts[p, 2]
    return flat, zmin


@kernel(entry="_window_ground", example="_window_example")
def _near_surface_fast(pts, origin, cell, values, ground, flat, tol):
    """(n,) bool: the points within ``tol`` of the bilinear surface ``values`` (as
    :func:`~cosco.ground.surface._grid_heights_fast`) whose cell (``flat``) is ground."""
    n = pts.shape[0]
    out = np.empty(n, dtype=np.bool_)
    for p in range(n):
        if not ground[flat[p]]:
            out[p] = False
            continue
        x = (pts[p, 0] - origin[0]) / cell - 0.5
        y = (pts[p, 1] - origin[1]) / cell - 0.5
        out[p] = abs(pts[p, 2] - _linear(values, x, y)) < tol
    return out
