"""The survey's date (the contract's "twin over time"): twin.json's ``survey_date`` comes from ``--date``, else the
points' GPS times when the header says they are adjusted standard GPS time, else the LAS/LAZ header's creation date
(with a warning when that is about the day the file was written), else it is null; a date that is not YYYY-MM-DD is
a usage error."""

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
    assert (twin["survey_date"], twin["survey_date_source"]) == ("2026-03-02", "file header creation date")
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


def _dated_las(path, points, created, gps_day=None):
    """A LAS of ``points`` (ITM) created on ``created``; with ``gps_day``, point format 1 with adjusted standard GPS
    times of that day (a flight three hours long)."""
    import laspy
    import pyproj

    header = laspy.LasHeader(point_format=1 if gps_day else 0, version="1.4")
    header.scales, header.offsets = [0.001] * 3, np.floor(points.min(0))
    header.add_crs(pyproj.CRS("EPSG:2157"))
    header.creation_date = created
    if gps_day:
        header.global_encoding.gps_time_type = laspy.header.GpsTimeType.STANDARD
    las = laspy.LasData(header)
    las.x, las.y, las.z = points[:, 0], points[:, 1], points[:, 2]
    if gps_day:
        start = (datetime.datetime.combine(gps_day, datetime.time(9)) - datetime.datetime(1980, 1, 6)).total_seconds()
        las.gps_time = start - 1e9 + np.linspace(0, 3 * 3600, len(points))
    las.write(path)
    return path


def test_the_date_comes_from_gps_time_before_the_header(parametric_catalogue, tmp_path):
    """A file cropped on 2026-11-30 from a flight of 2019-05-14: the points' GPS times give the flight's day."""
    from twinreg.sim.parametric import LIBRARY, car_mesh
    from twinreg.sim.scan import car_park

    pts = car_park([car_mesh(LIBRARY[2])], n_cars=2, seed=1, distractors=False).points + ITM
    path = _dated_las(tmp_path / "flight.las", pts, datetime.date(2026, 11, 30), datetime.date(2019, 5, 14))
    twin = _twin(path, parametric_catalogue.folder, tmp_path / "a")
    assert (twin["survey_date"], twin["survey_date_source"]) == ("2019-05-14", "GPS time")
    assert "warnings" not in twin


def test_a_creation_date_like_the_files_own_day_is_warned(parametric_catalogue, tmp_path):
    """No GPS times (Autzen's case: point format 2, created the day it was cropped): the header's date is used,
    named so, with a warning on stderr and in twin.json when the file was written within a month of it."""
    import os

    from twinreg.sim.parametric import LIBRARY, car_mesh
    from twinreg.sim.scan import car_park

    pts = car_park([car_mesh(LIBRARY[2])], n_cars=2, seed=1, distractors=False).points + ITM
    path = _dated_las(tmp_path / "crop.las", pts, datetime.date(2026, 11, 22))
    written = datetime.datetime(2026, 11, 23, 12).timestamp()
    os.utime(path, (written, written))
    res = CliRunner().invoke(app, ["build-twin", str(path), "--library", str(parametric_catalogue.folder), "--out",
                                   str(tmp_path / "a"), "--json"])
    assert res.exit_code == 0, res.output
    twin = json.loads(res.stdout)
    assert (twin["survey_date"], twin["survey_date_source"]) == ("2026-11-22", "file header creation date")
    assert len(twin["warnings"]) == 1 and "--date" in twin["warnings"][0]
    assert "warning: crop.las: the survey date 2026-11-22 is the header's creation date" in res.stderr
    old = datetime.datetime(2027, 6, 1).timestamp()  # written long after: no warning
    os.utime(path, (old, old))
    assert "warnings" not in _twin(path, parametric_catalogue.folder, tmp_path / "b")
