"""Turns about the vertical axis and object frames: the one yaw rotation every stage builds its poses from, an
object's frame (u along its heading, v to its left), and undirected axes.

Angles are radians, counter-clockwise from +X seen from above (+Z up).
"""

from __future__ import annotations

import numpy as np


def yaw(angle: float) -> np.ndarray:
    """(3, 3) float64 rotation by ``angle`` about +Z.

    >>> np.round(yaw(np.pi / 2) @ [1.0, 0.0, 0.0], 12)
    array([0., 1., 0.])
    """
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def yaw_pose(angle: float, translation=(0.0, 0.0, 0.0)) -> np.ndarray:
    """(4, 4) float64 transform: the turn :func:`yaw`, then ``translation`` (3,).

    >>> yaw_pose(0.0, (1.0, 2.0, 3.0))[:3, 3]
    array([1., 2., 3.])
    """
    m = np.eye(4)
    m[:3, :3] = yaw(angle)
    m[:3, 3] = translation
    return m


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


def reflect(points: np.ndarray, phi: float, rho: float) -> np.ndarray:
    """Mirror (n, 3) points in the vertical plane (phi, rho).

    >>> np.round(reflect(np.array([[3.0, 1.0, 2.0]]), 0.0, 1.0), 9).tolist()
    [[-1.0, 1.0, 2.0]]
    """
    pts = np.asarray(points, dtype=np.float64)
    n = np.array([np.cos(phi), np.sin(phi)])
    d = pts[:, :2] @ n - rho
    out = pts.copy()
    out[:, :2] -= 2.0 * d[:, None] * n[None, :]
    return out
