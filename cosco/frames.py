"""Turns about the vertical axis: the one yaw rotation every stage builds its poses from.

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
