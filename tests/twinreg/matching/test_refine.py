"""Pose refinement alone (twinreg/matching/refine.py): a small turn and shift is undone, a large one is refused."""

import numpy as np
from scipy.spatial import cKDTree

from twinreg.settings import DEFAULT
from twinreg.matching.refine import refine


def _turned(points, angle, shift):
    c, s = np.cos(angle), np.sin(angle)
    return points @ np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]]).T + shift


def test_a_small_turn_and_shift_is_undone():
    rng = np.random.default_rng(1)
    model = np.column_stack([rng.uniform(-2.2, 2.2, 4000), rng.uniform(-0.9, 0.9, 4000), rng.uniform(0, 1.4, 4000)])
    model[:, 2] *= 1 - 0.3 * (np.abs(model[:, 0]) / 2.2)  # not a box: lower ends
    obj = _turned(model[::3], np.radians(2.0), [0.05, -0.03, 0.01])
    c = refine(obj, cKDTree(model), reach=0.3)
    back = obj @ c[:3, :3].T + c[:3, 3]
    assert np.median(np.linalg.norm(back - model[::3], axis=1)) < 0.01


def test_a_correction_beyond_the_bounds_is_refused():
    rng = np.random.default_rng(2)
    model = rng.uniform([-2, -1, 0], [2, 1, 1.5], (3000, 3))
    obj = _turned(model, DEFAULT.matching.refine_max_turn * 3, [0.0, 0.0, 0.0])
    assert np.allclose(refine(obj, cKDTree(model), reach=2.0), np.eye(4))
