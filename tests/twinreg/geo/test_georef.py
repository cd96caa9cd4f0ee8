import numpy as np
import pytest

from twinreg.errors import GeorefError
from twinreg.geo.georef import georef_from_options


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


# ---- scenes in a projected CRS: positions land where pyproj says -----------------------------------------------

from tests.conftest import SHARED_DATA, need, write_las  # noqa: E402

AUTZEN_STADIUM = (44.0583, -123.0686)


@pytest.fixture(scope="module")
def small_park():
    from twinreg.sim.parametric import LIBRARY, car_mesh
    from twinreg.sim.scan import car_park

    return car_park([car_mesh(LIBRARY[k]) for k in (1, 2, 4)], n_cars=4, seed=11, distractors=False)


def _geod_m(lat1, lon1, lat2, lon2):
    from pyproj import Geod

    return abs(Geod(ellps="WGS84").inv(lon1, lat1, lon2, lat2)[2])


def _run_twin(args, out):
    import json

    from typer.testing import CliRunner

    from twinreg.cli import app

    res = CliRunner().invoke(app, ["build-twin", *map(str, args), "--out", str(out), "--json"])
    assert res.exit_code == 0, res.output
    return json.loads(res.stdout)


@pytest.mark.parametrize("epsg, lat, lon, fmt", [("EPSG:2157", 53.34980, -6.26030, "las"),
                                                 ("EPSG:2227", 37.80440, -122.27110, "laz"),
                                                 ("EPSG:2227", 37.80440, -122.27110, "ply")])
def test_scene_in_its_crs_lands_where_pyproj_says(small_park, parametric_catalogue, tmp_path, epsg, lat, lon, fmt):
    """A car park written in Irish Transverse Mercator (metres) or California zone 3 (US survey feet), with the
    CRS in the LAS/LAZ header (or given by --crs for a PLY): every car lands within 0.3 m of pyproj's position of
    its true footprint centre (the unit bug put feet-based scans 200 km away)."""
    from pyproj import CRS, Transformer

    from twinreg.io.ply import write_ply

    unit = CRS(epsg).axis_info[0].unit_conversion_factor
    e0, n0 = Transformer.from_crs("EPSG:4326", epsg, always_xy=True).transform(lon, lat)
    file_xyz = np.c_[e0 + small_park.points[:, 0] / unit, n0 + small_park.points[:, 1] / unit,
                     30.0 + small_park.points[:, 2] / unit]
    path = tmp_path / f"park.{fmt}"
    if fmt == "ply":
        write_ply(path, file_xyz)
        args = [path, "--crs", epsg]
    else:
        write_las(path, file_xyz, crs=epsg)
        args = [path]
    doc = _run_twin([*args, "--library", parametric_catalogue.folder], tmp_path / "out")
    assert doc["georef"]["crs"] == epsg and doc["georef"]["crs_unit_m"] == pytest.approx(unit)
    assert doc["unit"] == ("m" if unit == 1.0 else "us-ft")
    back = Transformer.from_crs(epsg, "EPSG:4326", always_xy=True)
    assert len(doc["objects"]) == 4
    for o in doc["objects"]:
        x, y = np.array(o["centroid"][:2]) / unit - [e0, n0]  # back to metres in the car park's own frame
        car = min(small_park.cars, key=lambda c: np.hypot(c.x - x * unit, c.y - y * unit))
        true_lon, true_lat = back.transform(e0 + car.x / unit, n0 + car.y / unit)
        assert _geod_m(o["lat"], o["lon"], true_lat, true_lon) < 0.3, o["id"]
    centre = doc["georef"]["scan_centre"]
    assert _geod_m(centre["lat"], centre["lon"], lat, lon) < 60


def test_autzen_lands_at_autzen_stadium(parametric_catalogue, tmp_path):
    """The real Autzen LAS (international feet, Oregon GIC Lambert, CRS in its header) with no georeferencing
    option and with --crs EPSG:2994: the scan centre is where pyproj puts the header's bounding box centre, by
    the stadium (44.058 N, 123.069 W), not 225 km south-west of it."""
    import laspy
    from pyproj import Transformer

    las = need(SHARED_DATA / "autzen_parking") / "autzen_parking_north.las"
    header = laspy.open(las).header
    cx, cy = (header.mins[:2] + header.maxs[:2]) / 2
    lon, lat = Transformer.from_crs("EPSG:2994", "EPSG:4326", always_xy=True).transform(cx, cy)
    for k, extra in enumerate(([], ["--crs", "EPSG:2994"])):
        doc = _run_twin([las, *extra, "--library", parametric_catalogue.folder], tmp_path / f"out{k}")
        c = doc["georef"]["scan_centre"]
        assert _geod_m(c["lat"], c["lon"], lat, lon) < 1.0
        assert _geod_m(c["lat"], c["lon"], *AUTZEN_STADIUM) < 1000
        assert doc["unit"] == "ft" and doc["georef"]["crs_unit_m"] == 0.3048
        assert doc["georef"]["crs_source"] == ("file header" if not extra else "--crs")
        lats = [o["lat"] for o in doc["objects"]]
        assert len(lats) > 50 and 44.05 < min(lats) and max(lats) < 44.07


def test_crs_problems_are_one_line_errors(tmp_path, small_park):
    import laspy

    from twinreg.errors import SceneReadError
    from twinreg.io.points import read_points

    pts = np.c_[-6.26 + small_park.points[:, 0] * 1e-5, 53.35 + small_park.points[:, 1] * 1e-5,
                small_park.points[:, 2]]
    geographic = write_las(tmp_path / "wgs84.las", pts, crs="EPSG:4326")
    with pytest.raises(SceneReadError, match="wgs84.las: the CRS WGS 84 is not projected") as info:
        read_points(geographic)
    assert "\n" not in str(info.value)
    feet = small_park.points / 0.3048 + [4_200_000.0, 800_000.0, 0.0]
    broken = write_las(tmp_path / "broken.las", feet,
                       vlr=laspy.vlrs.known.WktCoordinateSystemVlr('PROJCS["broken", UNIT["foot",0.3048]'))
    with pytest.raises(SceneReadError, match="cannot be parsed.*--crs EPSG:NNNN"):
        read_points(broken)
    ok = read_points(broken, crs="EPSG:2994")  # the fix the message gives
    assert ok.unit == "ft" and np.allclose(ok.points[:, :2], feet[:, :2] * 0.3048, atol=1e-3)
    with pytest.raises(SceneReadError, match="disagrees with the unit of the CRS"):
        read_points(broken, unit="m", crs="EPSG:2994")
    assert read_points(broken, unit="ft").crs is None  # told the unit: readable, georeferenced by options


AHN = SHARED_DATA / "ahn_amsterdam" / "ahn_2397_9705.laz"
AUTZEN = SHARED_DATA / "autzen_parking" / "autzen_parking_north.las"


@pytest.mark.parametrize("scan,args,words", [
    (AHN, ["--crs", "EPSG:2157"], ["ahn_2397_9705.laz: in IRENET95 / Irish Transverse Mercator (EPSG:2157) the scan "
                                   "would lie at 50.9 N, 14.8 W, outside the CRS's area of use (Ireland"]),
    (AUTZEN, ["--crs", "EPSG:2157"], ["--crs EPSG:2157 (IRENET95 / Irish Transverse Mercator) differs from the CRS "
                                      "the file's header states (NAD_1983_HARN_Lambert_Conformal_Conic",
                                      "--override-crs"]),
    # (read as ITM metres, Autzen's feet happen to fall in Ireland: an override is the user's word)
    (AUTZEN, ["--crs", "EPSG:28992", "--override-crs"], ["outside the CRS's area of use (Netherlands"]),
    (AUTZEN, ["--override-crs"], ["--override-crs says that --crs replaces"]),
])
def test_a_wrong_crs_is_refused_before_the_detection(parametric_catalogue, tmp_path, scan, args, words):
    """A valid but wrong CRS puts a real scan elsewhere on Earth: refused in one line naming the CRS, its area
    and where the scan would land, at once and with nothing written; a --crs other than the header's needs
    --override-crs."""
    import time

    from typer.testing import CliRunner

    from twinreg.cli import app

    need(scan)
    out = tmp_path / "out"
    t = time.monotonic()
    r = CliRunner().invoke(app, ["build-twin", str(scan), *args, "--library", str(parametric_catalogue.folder),
                                 "--out", str(out)])
    assert time.monotonic() - t < 20
    assert r.exit_code in (1, 2), r.output
    line = r.output.strip()
    assert line.startswith("error:") and "\n" not in line, line
    for w in words:
        assert w in line, line
    assert not out.exists() and list(tmp_path.iterdir()) == []
