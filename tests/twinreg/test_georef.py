import numpy as np
import pytest

from twinreg.errors import GeorefError
from twinreg.georef import georef_from_options


def test_local_tangent_plane_anchor_and_directions():
    g = georef_from_options(53.35116, -6.261601, alt=10.0, anchor=(500.0, 200.0))
    lon, lat, h = g.to_wgs84([[500.0, 200.0, 0.0]])[0]
    assert lat == pytest.approx(53.35116, abs=1e-9) and lon == pytest.approx(-6.261601, abs=1e-9)
    assert h == pytest.approx(10.0, abs=1e-6)
    east = g.to_wgs84([[600.0, 200.0, 0.0]])[0]
    north = g.to_wgs84([[500.0, 300.0, 0.0]])[0]
    assert east[0] > lon and abs(east[1] - lat) < 1e-6
    assert north[1] > lat and abs(north[0] - lon) < 1e-6
    assert g.bearing([500, 200, 0], 0.0) == pytest.approx(90.0, abs=1e-3)
    assert g.bearing([500, 200, 0], np.pi / 2) == pytest.approx(0.0, abs=1e-3)
    assert g.bearing([500, 200, 0], np.pi) == pytest.approx(270.0, abs=1e-3)


def test_projected_crs_bearing_includes_grid_convergence():
    from pyproj import CRS, Proj

    # UTM zone 29N far from its central meridian (-9): grid north is not true north
    g = georef_from_options(crs="EPSG:32629")
    x, y = 700_000.0, 5_900_000.0
    lon, lat, _ = g.to_wgs84([[x, y, 0.0]])[0]
    conv = Proj(CRS("EPSG:32629")).get_factors(lon, lat).meridian_convergence
    # east of the central meridian in the north, grid north lies clockwise of true north by the convergence,
    # about atan(tan(dlon) sin(lat))
    approx = np.degrees(np.arctan(np.tan(np.radians(lon + 9.0)) * np.sin(np.radians(lat))))
    assert conv == pytest.approx(approx, abs=0.05) and conv > 1.0
    assert g.bearing([x, y, 0], np.pi / 2) == pytest.approx(conv, abs=0.01)


@pytest.mark.parametrize("kwargs, match", [({"lat": 91, "lon": 0}, "--lat"), ({"lat": 0, "lon": 181}, "--lon"),
                                           ({"lat": 90, "lon": 0}, "strictly between"),
                                           ({"lat": -90, "lon": 10}, "strictly between"),
                                           ({}, "--lat and --lon"), ({"crs": "EPSG:4326"}, "is not projected"),
                                           ({"crs": "EPSG:999999"}, "cannot be parsed"),
                                           ({"crs": "EPSG:2157", "lat": 1, "lon": 1}, "either")])
def test_bad_options(kwargs, match):
    with pytest.raises(GeorefError, match=match):
        georef_from_options(**kwargs)
