import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cosco.arrays import voxel_downsample
from cosco.footprint import min_area_rectangle
from cosco.frames import axis_difference, from_frame, to_frame


def _brute_force_area(xy):
    best = np.inf
    for a in np.radians(np.arange(0, 90, 0.05)):
        c, s = np.cos(a), np.sin(a)
        u, v = xy @ [c, s], xy @ [-s, c]
        best = min(best, np.ptp(u) * np.ptp(v))
    return best


def test_min_area_rectangle_matches_brute_force():
    rng = np.random.default_rng(4)
    for _ in range(5):
        xy = rng.normal(size=(200, 2)) * [3, 1] @ np.array([[0.8, 0.6], [-0.6, 0.8]])
        r = min_area_rectangle(xy)
        assert r.length * r.width == pytest.approx(_brute_force_area(xy), rel=2e-3)
        assert r.length >= r.width


def test_min_area_rectangle_of_a_rotated_box():
    rng = np.random.default_rng(0)
    pts = rng.uniform([-2.25, -0.9], [2.25, 0.9], (500, 2))
    pts = np.vstack([pts, [[-2.25, -0.9], [2.25, 0.9], [-2.25, 0.9], [2.25, -0.9]]])
    a = np.radians(33)
    rot = pts @ np.array([[np.cos(a), np.sin(a)], [-np.sin(a), np.cos(a)]]) + [500, -20]
    r = min_area_rectangle(rot)
    assert r.length == pytest.approx(4.5, abs=1e-6) and r.width == pytest.approx(1.8, abs=1e-6)
    assert np.degrees(axis_difference(r.angle, a)) < 1e-4
    assert np.allclose(r.centre, [500, -20], atol=1e-6)


def test_voxel_downsample_weights_sum_to_n():
    pts = np.random.default_rng(1).uniform(0, 1, (1000, 3))
    c, w = voxel_downsample(pts, 0.25)
    assert w.sum() == 1000 and len(c) <= 64


@settings(max_examples=30, deadline=None)
@given(st.floats(-1e6, 1e6), st.floats(-1e6, 1e6), st.floats(0, 2 * np.pi))
def test_frame_round_trip(x, y, heading):
    p = np.array([[x + 1.5, y - 2.0, 3.0], [x, y, 0.0]])
    assert np.allclose(from_frame(to_frame(p, [x, y], heading), [x, y], heading), p, atol=1e-6)
