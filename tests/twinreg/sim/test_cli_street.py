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


def test_build_twin_reads_the_drive_s_trajectory(parametric_catalogue, tmp_path):
    """A van's street built with its trajectory: twin.json says where the scanners were; every car found, the
    box-like ones (seen from one side) measured along their length."""
    lib = ["--library", str(parametric_catalogue.folder)]
    street = tmp_path / "street"
    assert CliRunner().invoke(app, [*lib, "simulate-street", str(street), "--cars", "4", "--seed", "1"]).exit_code == 0
    out = tmp_path / "twin"
    r = CliRunner().invoke(app, [*lib, "build-twin", str(street / "scan.laz"), "--trajectory",
                                 str(street / "trajectory.csv"), "--out", str(out), "--no-ply"])
    assert r.exit_code == 0, r.output
    doc = json.loads((out / "twin.json").read_text())
    assert doc["viewpoints"]["source"] == "trajectory" and doc["viewpoints"]["n_points"] == doc["n_points"]
    truth = json.loads((street / "truth.json").read_text())
    cars = [i for i in truth["items"] if i["kind"] == "car"]
    centres = np.array([o["position_crs"][:2] for o in doc["objects"]])
    for car in cars:
        d = np.hypot(*(centres - [car["x"], car["y"]]).T)
        o = doc["objects"][int(d.argmin())]
        assert d.min() < 1.0, car
        assert o["measured_size"]["length"] > o["measured_size"]["width"], (car, o["measured_size"])


def test_a_trajectory_the_scan_cannot_use_is_refused_in_one_line(parametric_catalogue, tmp_path):
    lib = ["--library", str(parametric_catalogue.folder)]
    street = tmp_path / "street"
    assert CliRunner().invoke(app, [*lib, "simulate-street", str(street), "--cars", "2", "--seed", "1"]).exit_code == 0
    other = tmp_path / "other.csv"
    other.write_text("time,x,y,z\n5000,0,0,0\n5001,1,1,1\n")
    air = tmp_path / "air"
    assert CliRunner().invoke(app, [*lib, "simulate-street", str(air), "--cars", "2", "--platform", "airborne",
                                    "--density", "50"]).exit_code == 0
    tiled = CliRunner().invoke(app, [*lib, "build-twin", str(street / "scan.laz"), str(air / "scan.laz"),
                                     "--trajectory", str(street / "trajectory.csv"), "--out", str(tmp_path / "t")])
    assert tiled.exit_code != 0 and "a tiled run" in tiled.output.strip().splitlines()[-1]
    assert not (tmp_path / "t").exists()
    cases = [(street / "scan.laz", other, "outside the trajectory"),
             (air / "scan.laz", street / "trajectory.csv", "no GPS time"),
             (street / "scan.laz", tmp_path / "none.csv", "no such trajectory")]
    for scan, traj, what in cases:
        out = tmp_path / "out"
        r = CliRunner().invoke(app, [*lib, "build-twin", str(scan), "--trajectory", str(traj), "--out", str(out)])
        assert r.exit_code != 0
        line = r.output.strip().splitlines()[-1]
        assert line.startswith("error:") and what in line, r.output
        assert not out.exists()
