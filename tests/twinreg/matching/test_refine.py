"""Pose refinement alone (twinreg/matching/refine.py): a small turn and shift is undone, a large one is refused, a
model seen on one slope stands on the ground."""

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


def _barrier_face(rng, n=3000):
    """The near face of a jersey-barrier-like wedge 4 m long (x), its face rising from y = -0.3 at the ground to
    y = -0.08 at 0.8 m (a 75-degree slope), then a 0.3 m upright to the top at 1.1 m; the far face not scanned."""
    x = rng.uniform(-2.0, 2.0, n)
    z = rng.uniform(0.0, 1.1, n)
    y = np.where(z < 0.8, -0.3 + 0.22 * z / 0.8, -0.08)
    return np.column_stack([x, y, z])


def test_a_model_seen_on_one_slope_stands_on_the_ground():
    """A barrier's one sloped face, placed 8 cm too low and 2 cm towards the scanner (the slope lets the model
    slide so and still fit): refined free, the height stays wrong (the control); refined on the object's ground
    (``ground``: where the ground lies in the model's frame), the model stands on it and the face fits."""
    rng = np.random.default_rng(3)
    face = _barrier_face(rng)
    back = np.column_stack([rng.uniform(-2.0, 2.0, 2000), np.full(2000, 0.3), rng.uniform(0.0, 1.1, 2000)])
    model = np.vstack([face, back, np.column_stack([rng.uniform(-2, 2, 500), rng.uniform(-0.08, 0.08, 500),
                                                     np.full(500, 1.1)])])
    slide = np.array([0.0, -0.022, 0.08])  # the points seen 8 cm higher and 2.2 cm nearer, in the model's frame
    obj = face[::2] + slide
    free = refine(obj, cKDTree(model), reach=0.3)
    assert abs((obj @ free[:3, :3].T + free[:3, 3])[:, 2].min() - face[:, 2].min()) > 0.04  # the control
    stood = refine(obj, cKDTree(model), reach=0.3, ground=slide[2])  # the ground measured under the object
    placed = obj @ stood[:3, :3].T + stood[:3, 3]
    assert np.median(np.linalg.norm(placed - face[::2], axis=1)) < 0.01
