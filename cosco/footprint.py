"""Footprints: an object's plan hull and its minimum-area rectangle.

All functions take ``(n, 2)`` float64 arrays in metres; angles are radians counter-clockwise from +X. Point coercion
and voxels live in :mod:`cosco.arrays`, object frames and axes in :mod:`cosco.frames`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .arrays import as_points


@dataclass(frozen=True)
class Rectangle:
    """An oriented rectangle in the XY plane.

    centre : (2,) metres; angle : radians of the long side from +X, in [0, pi); length >= width, metres.
    """

    centre: np.ndarray
    angle: float
    length: float
    width: float

    def corners(self) -> np.ndarray:
        """(4, 2) corner coordinates, counter-clockwise."""
        u = np.array([np.cos(self.angle), np.sin(self.angle)])
        v = np.array([-u[1], u[0]])
        hl, hw = self.length / 2, self.width / 2
        return np.array([self.centre + su * hl * u + sv * hw * v for su, sv in ((-1, -1), (1, -1), (1, 1), (-1, 1))])


def hull_rows(xy: np.ndarray) -> np.ndarray:
    """The rows of (n, 2) points on their convex hull, in order around it; every row for a degenerate (collinear)
    input, whose every point is on the "hull".

    >>> hull_rows(np.array([[0.0, 0.0], [2.0, 0.0], [1.0, 0.5], [1.0, 2.0]])).tolist()
    [0, 1, 3]
    """
    from scipy.spatial import ConvexHull, QhullError

    try:
        return ConvexHull(xy).vertices
    except (QhullError, ValueError):
        return np.arange(len(xy))


def min_area_rectangle(xy: np.ndarray) -> Rectangle:
    """Minimum-area enclosing rectangle of 2D points (rotating calipers over hull edges, vectorised).

    xy : (n, 2) float, metres.

    >>> r = min_area_rectangle(np.array([[0, 0], [4, 0], [4, 2], [0, 2], [2, 1]]))
    >>> round(r.length, 6), round(r.width, 6), round(r.angle % np.pi, 6) in (0.0, round(np.pi, 6))
    (4.0, 2.0, True)
    """
    xy = as_points(xy, dim=2)
    from .kernels import jit

    mod = jit()
    if mod is not None and len(xy) >= 3:  # compiled (cosco.kernels): the same rectangle, a tenth of the time
        a, lu, lv, cx, cy, ok = mod.min_area_rectangle(np.ascontiguousarray(xy, dtype=np.float64))
        if ok:
            return _rectangle(np.array([cx, cy]), a, lu, lv)
    return min_area_rectangle_numpy(xy)


def min_area_rectangle_numpy(xy: np.ndarray) -> Rectangle:
    """The numpy reference of :func:`min_area_rectangle` (scipy's hull)."""
    xy = as_points(xy, dim=2)
    hull = xy[hull_rows(xy)]
    edges = np.roll(hull, -1, axis=0) - hull
    angles = np.unique(np.mod(np.arctan2(edges[:, 1], edges[:, 0]), np.pi / 2))
    if len(angles) == 0:
        angles = np.array([0.0])
    c, s = np.cos(angles), np.sin(angles)
    # coordinates of every hull point in every candidate frame: (k, m)
    u = hull[:, 0][None, :] * c[:, None] + hull[:, 1][None, :] * s[:, None]
    v = -hull[:, 0][None, :] * s[:, None] + hull[:, 1][None, :] * c[:, None]
    du = u.max(1) - u.min(1)
    dv = v.max(1) - v.min(1)
    best = int(np.argmin(du * dv))
    a, lu, lv = angles[best], du[best], dv[best]
    cu = (u[best].max() + u[best].min()) / 2
    cv = (v[best].max() + v[best].min()) / 2
    centre = np.array([cu * np.cos(a) - cv * np.sin(a), cu * np.sin(a) + cv * np.cos(a)])
    return _rectangle(centre, a, lu, lv)


def _rectangle(centre: np.ndarray, a: float, lu: float, lv: float) -> Rectangle:
    """The rectangle of extents ``lu`` along the angle ``a`` and ``lv`` across, its long side the length."""
    if lv > lu:
        a, lu, lv = a + np.pi / 2, lv, lu
    return Rectangle(centre=centre, angle=float(np.mod(a, np.pi)), length=float(lu), width=float(lv))
