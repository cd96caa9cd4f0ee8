"""geo/earth: the twin's east-north-up frame: orthonormal axes, round trips to the ellipsoid to the millimetre,
the near-field affine map that converts a cell's millions of scan points, bearings to ENU angles."""

from __future__ import annotations

import numpy as np

from twinreg.geo.earth import EnuFrame, enu_angles, enu_axes
from twinreg.geo.georef import georef_from_options


def test_axes_are_orthonormal_and_up_points_away_from_the_centre():
    for lat, lon in ((53.35, -6.26), (-33.9, 151.2), (0.0, 0.0), (89.0, 45.0)):
        a = enu_axes(lat, lon)
        assert np.allclose(a.T @ a, np.eye(3), atol=1e-12)
        assert np.isclose(np.linalg.det(a), 1.0)  # right-handed: east x north = up
    f = EnuFrame(-6.26, 53.35, 60.0)
    assert np.dot(f.axes[:, 2], f.origin / np.linalg.norm(f.origin)) > 0.99


def test_round_trip_through_the_ellipsoid_to_a_millimetre():
    f = EnuFrame(-6.26, 53.35, 60.0)
    enu = np.array([[0.0, 0.0, 0.0], [1000.0, -500.0, 20.0], [-3000.0, 2500.0, -40.0]])
    back = f.from_geodetic(f.to_geodetic(enu))
    assert np.abs(back - enu).max() < 1e-3
    assert np.allclose(f.to_geodetic([[0.0, 0.0, 0.0]])[0], [-6.26, 53.35, 60.0], atol=1e-9)
    # a point 1 km east: its longitude grows, its latitude barely moves
    lon, lat, _ = f.to_geodetic([[1000.0, 0.0, 0.0]])[0]
    assert lon > -6.26 and abs(lat - 53.35) < 1e-3


def test_the_affine_map_near_a_cell_is_the_exact_conversion_to_a_millimetre():
    georef = georef_from_options(lat=53.35, lon=-6.26)
    f = EnuFrame.at(georef, [0.0, 0.0, 0.0])
    centre = np.array([150.0, -80.0, 5.0])
    a, b = f.affine_near(georef, centre)
    rng = np.random.default_rng(0)
    pts = centre + rng.uniform(-150, 150, size=(200, 3)) * [1, 1, 0.1]
    assert np.abs((pts - centre) @ a.T + b - f.from_scene(georef, pts)).max() < 1e-3


def test_bearings_become_counter_clockwise_angles_from_east():
    assert np.allclose(enu_angles([0.0, 90.0, 180.0, 270.0]), np.radians([90.0, 0.0, -90.0, -180.0]))
