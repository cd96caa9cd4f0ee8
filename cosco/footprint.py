"""Footprint geometry: point coercion, voxel down-sampling, minimum-area rectangle, object frames.

All functions take ``(n, 3)`` (or ``(n, 2)``) float64 arrays in metres; angles are radians counter-clockwise
from +X.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


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


def voxel_downsample(points: np.ndarray, voxel: float) -> tuple[np.ndarray, np.ndarray]:
    """Centroids of the occupied voxels and their point counts.

    points : (n, d) float, metres. Returns ``(m, d)`` centroids and ``(m,)`` int counts.

    >>> c, w = voxel_downsample(np.array([[0.01, 0, 0], [0.02, 0, 0], [1.0, 0, 0]]), 0.1)
    >>> len(c), sorted(w.tolist())
    (2, [1, 2])
    """
    pts = np.asarray(points, dtype=np.float64)
    _, inverse, counts = np.unique(cell_keys(np.floor(pts / voxel).astype(np.int64)), return_inverse=True,
                                   return_counts=True)
    inverse = inverse.reshape(-1)
    sums = np.zeros((len(counts), pts.shape[1]))
    np.add.at(sums, inverse, pts)
    return sums / counts[:, None], counts


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
    if lv > lu:
        a, lu, lv = a + np.pi / 2, lv, lu
    return Rectangle(centre=centre, angle=float(np.mod(a, np.pi)), length=float(lu), width=float(lv))


def to_frame(points: np.ndarray, origin_xy, heading: float) -> np.ndarray:
    """Express points in an object frame: u along ``heading``, v to its left, z unchanged.

    points : (n, 3) metres; origin_xy : (2,) metres; heading : radians. Returns (n, 3) as (u, v, z).

    >>> (np.round(to_frame(np.array([[1.0, 1.0, 0.5]]), [1.0, 0.0], np.pi / 2), 9) + 0.0).tolist()
    [[1.0, 0.0, 0.5]]
    """
    pts = np.asarray(points, dtype=np.float64)
    c, s = np.cos(heading), np.sin(heading)
    dx = pts[:, 0] - origin_xy[0]
    dy = pts[:, 1] - origin_xy[1]
    return np.column_stack([c * dx + s * dy, -s * dx + c * dy, pts[:, 2]])


def from_frame(uvz: np.ndarray, origin_xy, heading: float) -> np.ndarray:
    """Inverse of :func:`to_frame`: (n, 3) frame coordinates back to the scene.

    >>> p = np.array([[3.0, -2.0, 1.0]])
    >>> np.allclose(from_frame(to_frame(p, [1, 2], 0.7), [1, 2], 0.7), p)
    True
    """
    uvz = np.asarray(uvz, dtype=np.float64)
    c, s = np.cos(heading), np.sin(heading)
    x = origin_xy[0] + c * uvz[:, 0] - s * uvz[:, 1]
    y = origin_xy[1] + s * uvz[:, 0] + c * uvz[:, 1]
    return np.column_stack([x, y, uvz[:, 2]])


def wrap_axis(angle: float) -> float:
    """An undirected axis angle in [0, pi).

    >>> round(wrap_axis(-np.pi / 4), 6) == round(3 * np.pi / 4, 6)
    True
    """
    return float(np.mod(angle, np.pi))


def axis_difference(a: float, b: float) -> float:
    """Smallest angle (radians, in [0, pi/2]) between two undirected axes.

    >>> round(float(np.degrees(axis_difference(0.0, np.pi - 0.1))), 3)
    5.73
    """
    d = np.mod(a - b, np.pi)
    return float(min(d, np.pi - d))
