"""twin.ply in the scan's own coordinates: a CRS in feet gives feet, a local frame its metres; header lines short
enough for any PLY reader; the CRS's WKT in twin.prj."""

from __future__ import annotations

import numpy as np

from twinreg.export.twin_ply import COMMENT_VALUE, write_prj, write_twin_ply
from twinreg.geo.georef import Georef, georef_from_options
from twinreg.io.points import read_points


def _box():
    v = np.array([[x, y, z] for z in (0.0, 1.5) for x, y in ((-2, -1), (2, -1), (2, 1), (-2, 1))], dtype=float)
    f = np.array([[0, 1, 2], [0, 2, 3], [4, 5, 6], [4, 6, 7]])
    return v, f


def test_a_crs_in_feet_gives_feet_and_a_short_header(tmp_path):
    g = georef_from_options(crs="EPSG:2994", required=False)
    g = g.identified(-123.07, 44.06)
    v, f = _box()
    offset = np.array([194200.0, 259880.0, 0.0])  # metres of the scene frame (feet times 0.3048)
    path = write_twin_ply(tmp_path / "twin.ply", [(v, f, 1)], offset, g, "autzen.las " + "x" * 500)
    got = read_points(path).points
    assert np.allclose(got, (v + offset) / 0.3048, atol=1e-6)
    header = path.read_bytes().split(b"end_header")[0].decode()
    assert max(len(line) for line in header.splitlines()) <= len("comment ") + COMMENT_VALUE + 60
    assert "comment crs EPSG:2994" in header and "crs_unit_m 0.3048" in header
    prj = write_prj(tmp_path / "twin.prj", g)
    assert prj.read_text().startswith("PROJCS[") and "Oregon" in prj.read_text()
    from pyproj import CRS  # read back as GIS tools read a .prj: the same CRS

    assert CRS.from_wkt(prj.read_text()).equals(CRS("EPSG:2994"), ignore_axis_order=True)


def test_a_local_frame_keeps_its_metres_and_names_its_anchor(tmp_path):
    g = georef_from_options(lat=53.35, lon=-6.26)
    v, f = _box()
    path = write_twin_ply(tmp_path / "twin.ply", [(v, f, 2)], np.array([100.0, 200.0, 0.0]), g, "park.ply")
    assert np.allclose(read_points(path).points, v + [100.0, 200.0, 0.0])
    header = path.read_bytes().split(b"end_header")[0].decode()
    assert "anchor_latlon 53.35 -6.26" in header and "local east/north/up" in header
    assert write_prj(tmp_path / "twin.prj", Georef(53.35, -6.26, 0.0, (0.0, 0.0), None)) is None
