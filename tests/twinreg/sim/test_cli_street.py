"""simulate-street as users type it: a van's survey of a street (scan.laz with GPS times, trajectory.csv,
truth.json) that build-twin reads, and bad options refused in one line."""

import json

import numpy as np
from typer.testing import CliRunner

from twinreg.cli import app


def test_a_mobile_street_survey_is_written_and_read_back(parametric_catalogue, tmp_path):
    import laspy

    from twinreg.io.trajectory import read_trajectory

    out = tmp_path / "street"
    r = CliRunner().invoke(app, ["--library", str(parametric_catalogue.folder), "simulate-street", str(out),
                                 "--cars", "3", "--seed", "2", "--json"])
    assert r.exit_code == 0, r.output
    doc = json.loads(r.stdout)
    assert doc["platform"] == "mobile" and doc["n_points"] > 100_000
    truth = json.loads((out / "truth.json").read_text())
    assert [i["kind"] for i in truth["items"]].count("car") == 3 and truth["scan"] == "scan.laz"
    las = laspy.read(out / "scan.laz")
    assert len(las.points) == doc["n_points"] and las.header.parse_crs().to_epsg() == 28992
    traj = read_trajectory(out / "trajectory.csv")
    pos = traj.positions(np.asarray(las.gps_time))
    # every return within the scanners' range of where the van was when it came back
    d = np.linalg.norm(np.c_[las.x, las.y, las.z] - pos, axis=1)
    assert d.max() < 60.1
    # each car got returns
    for item in (i for i in truth["items"] if i["kind"] == "car"):
        assert item["points"] > 500


def test_bad_options_are_refused_in_one_line(parametric_catalogue, tmp_path):
    for extra in (["--platform", "boat"], ["--speed", "0"], ["--cars", "0"]):
        r = CliRunner().invoke(app, ["--library", str(parametric_catalogue.folder), "simulate-street",
                                     str(tmp_path / "s"), *extra])
        assert r.exit_code != 0
        line = r.output.strip().splitlines()[-1]
        assert line.startswith("error:"), r.output
    assert not (tmp_path / "s").exists()
