"""A placed model's pose refined on all of the object's points (beyond the paper; docs/METHOD.md, "Deciding
between candidates").

Section registration turns a model only by quarter turns about the object's axis: the axis itself comes from the
symmetry plane or, on sparse objects, the footprint's edges, and a degree or two off it moves the ends of a car by
several centimetres. Before a candidate is scored, a few iterations of trimmed point-to-point ICP with a turn about
the vertical only (yaw, and a shift in x, y, z: a parked car stands on the ground) bring the object's points onto
the model's sampled surface. The correction is bounded (``params.matching.refine_max_turn``,
``matching.refine_max_shift``): a pose the sections got wrong is not rescued here, only sharpened.
"""

from __future__ import annotations

import numpy as np

from cosco.frames import yaw_pose

from ..settings import DEFAULT, Settings


def yaw_fit(src: np.ndarray, dst: np.ndarray) -> np.ndarray:
    """(4, 4) rigid transform, a turn about z and a shift, taking (n, 3) ``src`` closest to ``dst`` (least squares).

    >>> a = np.random.default_rng(0).normal(size=(50, 3))
    >>> c, s = np.cos(0.1), np.sin(0.1)
    >>> b = a @ np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]]).T + [0.2, -0.1, 0.05]
    >>> np.allclose(yaw_fit(a, b)[:3, :3] @ a.T + yaw_fit(a, b)[:3, 3:], b.T)
    True
    """
    ms, md = src.mean(0), dst.mean(0)
    s, d = src - ms, dst - md
    theta = np.arctan2(np.sum(s[:, 0] * d[:, 1] - s[:, 1] * d[:, 0]), np.sum(s[:, 0] * d[:, 0] + s[:, 1] * d[:, 1]))
    m = yaw_pose(theta)
    m[:3, 3] = md - m[:3, :3] @ ms
    return m


def refine(points_in_model: np.ndarray, model_tree, reach: float, iterations: int = 6,
           params: Settings = DEFAULT, ground: float | None = None) -> np.ndarray:
    """(4, 4) correction ``c`` in the model's frame: ``c`` applied to the object's points (already in the model's
    frame) brings them onto the model's sampled points (``model_tree``, a cKDTree). Pairs farther than ``reach``
    (m) are left out. The identity when the fit does not converge within the bounds
    (``params.matching.refine_max_turn``, ``params.matching.refine_max_shift``).

    ``ground``: the object's ground level in the model's frame (m), to stand the model on: the points are first
    moved so that it is the model's lowest level (z = 0), then turned and shifted in plan only. An object seen from
    one side (a jersey barrier's one sloped face from a van) lets a model slide down its slope and towards the
    scanner and still fit; the ground under it, measured around it, holds the height."""
    q = np.asarray(points_in_model, dtype=np.float64)
    total = np.eye(4)
    if ground is not None:
        total[2, 3] = -float(ground)
        q = q + total[:3, 3]
    for _ in range(iterations):
        d, idx = model_tree.query(q, k=1, distance_upper_bound=reach)
        ok = np.isfinite(d)
        if ok.sum() < 10:
            break
        step = yaw_fit(q[ok], model_tree.data[idx[ok]])
        if ground is not None:
            step[2, 3] = 0.0
        q = q @ step[:3, :3].T + step[:3, 3]
        total = step @ total
        if np.abs(step[:3, 3]).max() < 1e-3 and abs(np.arctan2(step[1, 0], step[0, 0])) < 1e-4:
            break
    turn = abs(np.arctan2(total[1, 0], total[0, 0]))
    if turn > params.matching.refine_max_turn or np.linalg.norm(total[:3, 3]) > params.matching.refine_max_shift:
        return np.eye(4)
    return total
