"""Heights at the right datum: a LAS in EPSG:7415 (RD New + NAP) and one in a NAVD88 compound CRS are built twice,
as stated and with the vertical datum dropped (heights then taken as ellipsoidal); each car's height in the tileset
(decoded to ECEF, then to ellipsoidal height) differs between the two by the geoid undulation at that point from
the transformation used (RDNAPTRANS2018 for NAP, EGM96 for NAVD88, evaluated here independently), within 2 cm.
twin.json states the datum and the transformation; an unknown datum is warned about, --vertical-crs fixes it; the
real AHN tiles (NAP, no CRS in the header) with --crs EPSG:28992 --vertical-crs EPSG:5709."""

from __future__ import annotations

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from tests.conftest import SHARED_DATA, need, write_las
from tests.twinreg.helpers import tileset_heights as _heights, undulation as _undulation
from twinreg.cli import app

SITES = {"nap": ("EPSG:7415", "EPSG:28992", np.array([121_200.0, 487_300.0, -1.2])),
         "navd88": ("EPSG:6339+5703", "EPSG:6339", np.array([492_000.0, 4_877_000.0, 130.0]))}


@pytest.fixture(scope="module")
def scans(tmp_path_factory):
    from twinreg.sim.parametric import LIBRARY, car_mesh
    from twinreg.sim.scan import car_park

    folder = tmp_path_factory.mktemp("heights")
    park = car_park([car_mesh(LIBRARY[k]) for k in (1, 2, 5)], n_cars=3, seed=2, distractors=False)
    out = {}
    for name, (compound, horizontal, at) in SITES.items():
        out[name] = write_las(folder / f"{name}.las", park.points + at, crs=compound, point_format=6)
        out[name + "_flat"] = write_las(folder / f"{name}_flat.las", park.points + at, crs=horizontal, point_format=6)
    return folder, out


def _build(lib, scan, out, *extra):
    r = CliRunner().invoke(app, ["--library", str(lib), "build-twin", str(scan), "--out", str(out), *extra])
    assert r.exit_code == 0, r.output
    return json.loads((out / "twin.json").read_text()), r.output


@pytest.mark.parametrize("site", ["nap", "navd88"])
def test_tileset_heights_are_orthometric_plus_the_undulation(site, scans, parametric_catalogue, tmp_path):
    folder, files = scans
    lib = parametric_catalogue.folder
    twin, said = _build(lib, files[site], tmp_path / "stated")
    g = twin["georef"]
    assert g["vertical_source"] == "file header" and g["vertical_crs"] == ("EPSG:5709" if site == "nap" else
                                                                          "EPSG:5703")
    assert ("RDNAPTRANS2018" if site == "nap" else "EGM96") in g["height_transformation"]
    assert g["height_accuracy_m"] == (0.001 if site == "nap" else 1.0)
    assert "vertical datum" not in said
    flat, said_flat = _build(lib, files[site + "_flat"], tmp_path / "flat")
    assert flat["georef"]["vertical_source"] is None and "vertical datum of the scan's heights is unknown" in said_flat
    stated, unknown = _heights(tmp_path / "stated"), _heights(tmp_path / "flat")
    assert len(stated) == len(unknown) == 3
    for oid, (lon, lat, h) in stated.items():
        n = _undulation(site, lon, lat)
        assert abs(n) > 20  # Amsterdam: about 43 m; Oregon: about -22 m
        assert abs(h - unknown[oid][2] - n) < 0.02, (oid, h, unknown[oid][2], n)
    # --vertical-crs on the flat file gives the stated heights
    fixed, said_fixed = _build(lib, files[site + "_flat"], tmp_path / "fixed", "--vertical-crs",
                               "EPSG:5709" if site == "nap" else "EPSG:5703")
    assert fixed["georef"]["vertical_source"] == "--vertical-crs" and "unknown" not in said_fixed
    for oid, p in _heights(tmp_path / "fixed").items():
        assert abs(p[2] - stated[oid][2]) < 0.005


def test_bad_vertical_crs_is_usage_error(scans, parametric_catalogue, tmp_path):
    _, files = scans
    for bad in ("EPSG:28992", "EPSG:99999999", "not a crs"):
        r = CliRunner().invoke(app, ["--library", str(parametric_catalogue.folder), "build-twin",
                                     str(files["nap_flat"]), "--out", str(tmp_path / "x"), "--vertical-crs", bad])
        assert r.exit_code == 1 and "--vertical-crs" in r.output and "vertical CRS" in r.output, r.output
        assert not (tmp_path / "x").exists()


def test_ahn_tiles_in_nap(catalogue16, tmp_path):
    tile = need(SHARED_DATA / "ahn_amsterdam") / "ahn_2386_9702.laz"
    r = CliRunner().invoke(app, ["--library", str(catalogue16.folder), "build-twin", str(tile), "--crs",
                                 "EPSG:28992", "--vertical-crs", "EPSG:5709", "--out", str(tmp_path / "ahn")])
    assert r.exit_code == 0, r.output
    twin = json.loads((tmp_path / "ahn" / "twin.json").read_text())
    g = twin["georef"]
    assert g["crs"] == "EPSG:28992" and g["vertical_crs"] == "EPSG:5709" and g["vertical_source"] == "--vertical-crs"
    found = _heights(tmp_path / "ahn")
    assert found
    for o in twin["objects"]:
        lon, lat, h = found[o["id"]]
        # a car on Amsterdam's streets: NAP about 0-3 m, so 40-48 m above the ellipsoid
        assert 40.0 < h < 48.0, (o["id"], h)
