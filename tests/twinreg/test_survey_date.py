"""The survey's date (the contract's "twin over time"): twin.json's ``survey_date`` comes from ``--date``, else the
LAS/LAZ header's creation date, else it is null; a date that is not YYYY-MM-DD is a usage error."""

from __future__ import annotations

import datetime
import json

import numpy as np
import pytest
from typer.testing import CliRunner

from twinreg.cli import app
from twinreg.io.ply import write_ply

ITM = np.array([715_000.0, 734_000.0, 20.0])


@pytest.fixture(scope="module")
def scans(tmp_path_factory):
    import laspy
    import pyproj

    from twinreg.sim.parametric import LIBRARY, car_mesh
    from twinreg.sim.scan import car_park

    folder = tmp_path_factory.mktemp("dated")
    park = car_park([car_mesh(LIBRARY[2])], n_cars=2, seed=1, distractors=False)
    pts = park.points + ITM
    header = laspy.LasHeader(point_format=3, version="1.4")
    header.scales, header.offsets = [0.001] * 3, np.floor(pts.min(0))
    header.add_crs(pyproj.CRS("EPSG:2157"))
    header.creation_date = datetime.date(2026, 3, 2)
    las = laspy.LasData(header)
    las.x, las.y, las.z = pts[:, 0], pts[:, 1], pts[:, 2]
    las.write(folder / "march.las")
    write_ply(folder / "undated.ply", park.points)
    return folder


def _twin(scene, lib, out, *extra):
    args = ["build-twin", str(scene), "--library", str(lib), "--out", str(out), "--json", *extra]
    if scene.suffix == ".ply":
        args += ["--lat", "53.35", "--lon", "-6.26"]
    res = CliRunner().invoke(app, args)
    assert res.exit_code == 0, res.output
    return json.loads(res.stdout)


def test_the_date_comes_from_the_header_or_from_date(scans, parametric_catalogue, tmp_path):
    lib = parametric_catalogue.folder
    twin = _twin(scans / "march.las", lib, tmp_path / "a")
    assert (twin["survey_date"], twin["survey_date_source"]) == ("2026-03-02", "file header")
    twin = _twin(scans / "march.las", lib, tmp_path / "b", "--date", "2026-05-01")
    assert (twin["survey_date"], twin["survey_date_source"]) == ("2026-05-01", "--date")
    twin = _twin(scans / "undated.ply", lib, tmp_path / "c")
    assert twin["survey_date"] is None and twin["survey_date_source"] is None
    assert json.loads((tmp_path / "a" / "twin.json").read_text())["survey_date"] == "2026-03-02"


def test_a_tile_header_gives_its_date(scans):
    from twinreg.city.sources import read_source

    assert read_source(scans / "march.las").date == "2026-03-02"


@pytest.mark.parametrize("bad", ["2026-13-40", "02/03/2026", "soon"])
def test_a_date_that_is_not_a_date_is_a_usage_error(scans, parametric_catalogue, tmp_path, bad):
    res = CliRunner().invoke(app, ["build-twin", str(scans / "march.las"), "--library",
                                   str(parametric_catalogue.folder), "--out", str(tmp_path / "x"), "--date", bad])
    assert res.exit_code == 2 and not (tmp_path / "x").exists()
