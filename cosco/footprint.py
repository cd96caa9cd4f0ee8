"""Footprints: an object's plan hull and its minimum-area rectangle.

All functions take ``(n, 2)`` float64 arrays in metres; angles are radians counter-clockwise from +X. Point coercion
and voxels live in :mod:`cosco.arrays`, object frames and axes in :mod:`cosco.frames`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .arrays import as_points
from .kernels import fast, kernel


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

    def contains(self, xy: np.ndarray, margin: float = 0.0) -> np.ndarray:
        """(n,) bool: which of the (n, 2) points ``xy`` lie in the rectangle grown by ``margin`` m on every side.

        >>> r = Rectangle(np.zeros(2), 0.0, 4.0, 2.0)
        >>> r.contains(np.array([[1.9, 0.9], [2.1, 0.0], [0.0, 1.1]])).tolist(), r.contains(np.array([[2.1, 0]]), 0.2)
        ([True, False, False], array([ True]))
        """
        d = np.asarray(xy, dtype=np.float64) - self.centre
        u = np.array([np.cos(self.angle), np.sin(self.angle)])
        return (np.abs(d @ u) <= self.length / 2 + margin) & (np.abs(d @ [-u[1], u[0]]) <= self.width / 2 + margin)


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
    kern = fast(_min_area_rectangle_fast)
    if kern is not None and len(xy) >= 3:  # compiled: the same rectangle, a tenth of the time
        a, lu, lv, cx, cy, ok = kern(np.ascontiguousarray(xy, dtype=np.float64))
        if ok:
            return _rectangle(np.array([cx, cy]), a, lu, lv)
    return min_area_rectangle_numpy(xy)


#: rectangles whose areas differ by less than this share are tied, and the one at the smallest angle (mod pi/2) is
#: taken: a triangle or a square has several of equal area, which rounding alone would otherwise choose between
#: (the hull's start and turning sense differ between scipy's and the kernel's), giving one piece two lengths
TIE = 1e-9


def min_area_rectangle_numpy(xy: np.ndarray) -> Rectangle:
    """The numpy reference of :func:`min_area_rectangle` (scipy's hull); of tied rectangles (:data:`TIE`), the one
    at the smallest angle mod pi/2."""
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
    area = du * dv
    best = int(np.flatnonzero(area <= area.min() * (1.0 + TIE))[0])  # ties: the smallest angle
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


def _example(rng) -> tuple:
    """A car's plan, turned and far from the origin (the registry's example for :func:`min_area_rectangle`)."""
    xy = rng.uniform(-1, 1, (400, 2)) * [2.2, 0.9]
    c, s = np.cos(0.6), np.sin(0.6)
    return (xy @ np.array([[c, s], [-s, c]]) + [250.0, -80.0],)


@kernel(helper=True)
def _cross(o, a, b):
    return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])


@kernel(helper=True)
def _plan_hull(xy):
    """The convex hull of (n, 2) points, counter-clockwise from the leftmost (quickhull: a point on an edge is not
    a corner), without sorting the points: each step keeps only those outside the triangle it adds."""
    n = xy.shape[0]
    if n < 3:
        return np.zeros((0, 2))
    a, b = _extremes(xy)
    if a == b:
        return np.zeros((0, 2))
    nxt = np.full(n, -1, dtype=np.int64)  # the hull as a linked list, counter-clockwise
    nxt[a], nxt[b] = b, a
    buf = np.empty(n, dtype=np.int64)  # each task's points (strictly right of its edge), in one region
    spare = np.empty(n, dtype=np.int64)
    lo = 0
    hi = n
    for p in range(n):  # below a -> b from the front, below b -> a from the back
        c = _cross(xy[a], xy[b], xy[p])
        if c < 0.0:
            buf[lo] = p
            lo += 1
        elif c > 0.0:
            hi -= 1
            buf[hi] = p
    tasks = np.empty((2 * n + 2, 4), dtype=np.int64)  # (from, to, start, end)
    tasks[0, 0], tasks[0, 1], tasks[0, 2], tasks[0, 3] = a, b, 0, lo
    tasks[1, 0], tasks[1, 1], tasks[1, 2], tasks[1, 3] = b, a, hi, n
    top = 2
    while top > 0:
        top -= 1
        p, q, start, end = tasks[top, 0], tasks[top, 1], tasks[top, 2], tasks[top, 3]
        if end <= start:
            continue
        far = _farthest(xy, buf, p, q, start, end)
        if far < 0:
            continue
        nxt[p], nxt[far] = far, q
        k1, k2 = _split(xy, buf, spare, p, far, q, start, end)
        tasks[top, 0], tasks[top, 1], tasks[top, 2], tasks[top, 3] = p, far, start, k1
        tasks[top + 1, 0], tasks[top + 1, 1], tasks[top + 1, 2], tasks[top + 1, 3] = far, q, k1, k1 + k2
        top += 2
    return _walk(xy, nxt, a)


@kernel(helper=True)
def _extremes(xy):
    """The rows of the leftmost (lowest among them) and the rightmost (highest among them) points."""
    a, b = 0, 0
    for p in range(1, xy.shape[0]):
        if xy[p, 0] < xy[a, 0] or (xy[p, 0] == xy[a, 0] and xy[p, 1] < xy[a, 1]):
            a = p
        if xy[p, 0] > xy[b, 0] or (xy[p, 0] == xy[b, 0] and xy[p, 1] > xy[b, 1]):
            b = p
    return a, b


@kernel(helper=True)
def _farthest(xy, buf, p, q, start, end):
    """Of the points ``buf[start:end]`` (right of the edge p -> q), the farthest from it (-1 when none is off it)."""
    far, best = -1, 0.0
    for k in range(start, end):
        d = -_cross(xy[p], xy[q], xy[buf[k]])
        if d > best:
            best, far = d, buf[k]
    return far


@kernel(helper=True)
def _split(xy, buf, spare, p, far, q, start, end):
    """``buf[start:end]`` kept in place as the points right of p -> far, then those right of far -> q (the rest,
    inside the triangle, dropped): the two counts."""
    k1 = start
    k2 = 0
    for k in range(start, end):
        r = buf[k]
        if _cross(xy[p], xy[far], xy[r]) < 0.0:
            buf[k1] = r
            k1 += 1
        elif _cross(xy[far], xy[q], xy[r]) < 0.0:
            spare[k2] = r
            k2 += 1
    for k in range(k2):
        buf[k1 + k] = spare[k]
    return k1, k2


@kernel(helper=True)
def _walk(xy, nxt, a):
    """The hull's corners, following the linked list ``nxt`` from ``a``."""
    h = 1
    k = nxt[a]
    while k != a:
        h += 1
        k = nxt[k]
    hull = np.empty((h, 2))
    k = a
    for m in range(h):
        hull[m, 0], hull[m, 1] = xy[k, 0], xy[k, 1]
        k = nxt[k]
    return hull


@kernel(entry="min_area_rectangle", example="_example", tolerance=1e-9)
def _min_area_rectangle_fast(xy):
    """:func:`cosco.footprint.min_area_rectangle` on the hull of :func:`_plan_hull`: (angle, length along it,
    width across, centre x, centre y) before the long side is made the length, and False as the last value
    where the hull has fewer than three corners (the reference answers then)."""
    hull = _plan_hull(xy)
    h = hull.shape[0]
    if h < 3:
        return 0.0, 0.0, 0.0, 0.0, 0.0, False
    angles = np.empty(h)
    quarter = np.pi / 2
    for k in range(h):
        nxt = (k + 1) % h
        angles[k] = np.arctan2(hull[nxt, 1] - hull[k, 1], hull[nxt, 0] - hull[k, 0]) % quarter
    angles.sort()
    areas = np.full(h, np.inf)  # by angle, ascending (a repeated angle's stays inf)
    extents = np.empty((h, 4))  # u0, u1, v0, v1 of the hull in each angle's frame
    for k in range(h):
        a = angles[k]
        if k > 0 and a == angles[k - 1]:
            continue
        c, s = np.cos(a), np.sin(a)
        u0, u1, v0, v1 = np.inf, -np.inf, np.inf, -np.inf
        for q in range(h):
            u = hull[q, 0] * c + hull[q, 1] * s
            v = -hull[q, 0] * s + hull[q, 1] * c
            u0, u1, v0, v1 = min(u0, u), max(u1, u), min(v0, v), max(v1, v)
        areas[k] = (u1 - u0) * (v1 - v0)
        extents[k, 0], extents[k, 1], extents[k, 2], extents[k, 3] = u0, u1, v0, v1
    least = areas.min()
    k = 0
    while areas[k] > least * (1.0 + TIE):  # ties: the smallest angle
        k += 1
    a = angles[k]
    c, s = np.cos(a), np.sin(a)
    u0, u1, v0, v1 = extents[k, 0], extents[k, 1], extents[k, 2], extents[k, 3]
    cu, cv = (u1 + u0) / 2, (v1 + v0) / 2
    return a, u1 - u0, v1 - v0, cu * c - cv * s, cu * s + cv * c, True
