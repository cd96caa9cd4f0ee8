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
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .footprint import as_points
from .params import DEFAULT, CoscoParams


@dataclass(frozen=True)
class Ground:
    """A ground surface on a grid: ``z[i, j]`` at ``origin + (i + 0.5, j + 0.5) * cell`` (metres)."""

    origin: np.ndarray
    cell: float
    z: np.ndarray

    def height(self, points: np.ndarray) -> np.ndarray:
        """Height above ground (m) of (n, 3) points, bilinear under each point."""
        pts = np.asarray(points, dtype=np.float64)
        g = (pts[:, :2] - self.origin) / self.cell - 0.5
        gx = np.clip(g[:, 0], 0.0, self.z.shape[0] - 1.000001)
        gy = np.clip(g[:, 1], 0.0, self.z.shape[1] - 1.000001)
        if self.z.shape[0] == 1 or self.z.shape[1] == 1:
            return pts[:, 2] - self.z[np.clip(gx.astype(int), 0, self.z.shape[0] - 1),
                                      np.clip(gy.astype(int), 0, self.z.shape[1] - 1)]
        i, j = gx.astype(np.int64), gy.astype(np.int64)
        fx, fy = gx - i, gy - j
        z = self.z
        top = z[i, j] * (1 - fx) + z[i + 1, j] * fx
        bottom = z[i, j + 1] * (1 - fx) + z[i + 1, j + 1] * fx
        return pts[:, 2] - (top * (1 - fy) + bottom * fy)


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


def estimate_ground(points, params: CoscoParams = DEFAULT) -> Ground:
    """The ground surface under a scene.

    points : (n, 3) float, metres (large projected coordinates are fine: the grid is relative to the minimum).
    """
    from scipy import ndimage

    pts = as_points(points)
    cell = params.ground_cell
    origin = np.floor(pts[:, :2].min(0) / cell) * cell
    ij = np.floor((pts[:, :2] - origin) / cell).astype(np.int64)
    shape = tuple(ij.max(0) + 1)
    flat = ij[:, 0] * shape[1] + ij[:, 1]
    zmin = np.full(shape[0] * shape[1], np.inf)
    np.minimum.at(zmin, flat, pts[:, 2])
    zmin = zmin.reshape(shape)
    occupied = np.isfinite(zmin)
    surface = _fill_nearest(np.where(occupied, zmin, 0.0), occupied)

    ground = occupied.copy()
    raw = surface
    previous = 0.0
    for window in params.ground_windows:
        size = max(1, int(round(window / cell)))
        opened = ndimage.grey_opening(surface, size=(size, size), mode="nearest")
        threshold = min(params.ground_dh_max, params.ground_dh0 + params.ground_slope * (window - previous))
        ground &= surface - opened <= threshold
        surface = opened
        previous = window
    # an opening keeps planar slopes exactly, so a strict last test against the widest opening drops the edges
    # of cars (bumpers, sills) that the growing thresholds let through, and keeps ramps
    ground &= raw - surface <= params.ground_dh_final
    if not ground.any():
        ground = occupied
    z = _fill_smooth(np.where(ground, zmin, 0.0), ground, sigma_cells=max(1.0, 2.0 / cell))
    # the lowest point of a cell sits a few range-noise sigmas under the true ground: a second pass takes the
    # median of the points near that first surface in each ground cell
    first = Ground(origin=origin.astype(np.float64), cell=cell, z=z)
    near = np.abs(first.height(pts)) < params.ground_tol
    near &= ground.ravel()[flat]
    if near.any():
        zmed = np.full(shape[0] * shape[1], np.nan)
        order = np.lexsort((pts[near, 2], flat[near]))
        keys, zs = flat[near][order], pts[near, 2][order]
        starts = np.flatnonzero(np.r_[True, keys[1:] != keys[:-1]])
        ends = np.r_[starts[1:], len(keys)]
        zmed[keys[starts]] = 0.5 * (zs[(starts + ends - 1) // 2] + zs[(starts + ends) // 2])
        zmed = zmed.reshape(shape)
        known = np.isfinite(zmed)
        z = _fill_smooth(np.where(known, zmed, 0.0), known, sigma_cells=max(1.0, 2.0 / cell))
    return Ground(origin=origin.astype(np.float64), cell=cell, z=z)


def remove_ground(points, params: CoscoParams = DEFAULT) -> tuple[np.ndarray, np.ndarray, Ground]:
    """Split a scene into ground and the rest.

    Returns ``(is_ground (n,) bool, height_above_ground (n,) float m, ground)``.
    """
    pts = as_points(points)
    ground = estimate_ground(pts, params)
    hag = ground.height(pts)
    return hag < params.ground_tol, hag, ground
