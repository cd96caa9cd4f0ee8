"""The city commands as users type them: simulate-city writes tiles with a CRS and a truth file into a folder it
may replace; build-twin refuses bad tiling options with one line and exit status 2."""

from __future__ import annotations

import json

import laspy
from typer.testing import CliRunner

from twinreg.cli import app

runner = CliRunner()


def test_simulate_city_writes_tiles_with_a_crs_and_the_truth(tmp_path, parametric_catalogue):
    out = tmp_path / "city"
    args = ["--library", str(parametric_catalogue.folder), "simulate-city", str(out), "--km2", "0.0064", "--tile",
            "40", "--density", "30", "--json"]
    res = runner.invoke(app, args)
    assert res.exit_code == 0, res.output
    doc = json.loads(res.stdout)
    assert doc["models"] == "catalogue" and doc["n_cars"] > 20 and len(doc["tiles"]) == 4
    truth = json.loads((out / "truth.json").read_text())
    names = {r.name for r in parametric_catalogue.list()}
    assert {c["model"] for c in truth["cars"]} <= names
    total = 0
    for name in truth["tiles"]:
        with laspy.open(out / name) as f:
            assert f.header.parse_crs().to_epsg() == 28992
            total += f.header.point_count
    assert total == truth["n_points"] and truth["n_points"] > 150_000
    # the same seed gives the same city, and the folder (marked as twinreg's) is replaced
    again = runner.invoke(app, args)
    assert again.exit_code == 0 and json.loads(again.stdout)["n_points"] == doc["n_points"]
    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "notes.txt").write_text("keep me")
    refused = runner.invoke(app, args[:3] + [str(tmp_path / "mine")] + args[4:])
    assert refused.exit_code == 1 and "did not write" in refused.stderr
    assert (tmp_path / "mine" / "notes.txt").read_text() == "keep me"


def test_bad_tiling_options_are_refused_with_one_line(tmp_path, parametric_catalogue):
    import numpy as np

    from tests.conftest import write_las

    tiles = tmp_path / "tiles"
    tiles.mkdir()
    write_las(tiles / "a.laz", np.random.default_rng(0).uniform([0, 0, 0], [50, 50, 2], (500, 3)) + [155000, 463000, 0], crs="EPSG:28992")
    base = ["--library", str(parametric_catalogue.folder), "build-twin", str(tiles), "--out", str(tmp_path / "o")]
    for extra, words in ((["--cell", "20"], "--cell must be more than"), (["--workers", "0"], "--workers must be"),
                         (["--buffer", "-1"], "--buffer must be")):
        res = runner.invoke(app, base + extra)
        assert res.exit_code == 2, (extra, res.output)
        assert words in res.stderr and len(res.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "o").exists()


def test_an_unreachable_scheduler_is_one_line(tmp_path, parametric_catalogue):
    import numpy as np

    from tests.conftest import write_las

    tiles = tmp_path / "tiles"
    tiles.mkdir()
    write_las(tiles / "a.laz", np.random.default_rng(0).uniform([0, 0, 0], [50, 50, 2], (500, 3)) + [155000, 463000, 0], crs="EPSG:28992")
    res = runner.invoke(app, ["--library", str(parametric_catalogue.folder), "build-twin", str(tiles), "--out",
                              str(tmp_path / "o"), "--scheduler", "tcp://127.0.0.1:9"])
    assert res.exit_code == 1
    assert "tcp://127.0.0.1:9: cannot start or reach the Dask cluster" in res.stderr
    assert len(res.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "o").exists()


def test_a_scheduler_without_workers_is_one_line(tmp_path, parametric_catalogue, monkeypatch):
    """A reachable scheduler that has no worker: the run stops (after ``WORKERS_WAIT_S``, shortened here) with one
    line saying so and how to start one, exit 1, no output folder; before, its tasks waited forever."""
    import numpy as np
    from distributed import LocalCluster

    from tests.conftest import write_las
    from twinreg.city import engine

    monkeypatch.setattr(engine, "WORKERS_WAIT_S", 2.0)
    tiles = tmp_path / "tiles"
    tiles.mkdir()
    write_las(tiles / "a.laz", np.random.default_rng(0).uniform([0, 0, 0], [50, 50, 2], (500, 3)) + [155000, 463000, 0], crs="EPSG:28992")
    with LocalCluster(n_workers=0, processes=False, dashboard_address=None, host="127.0.0.1", protocol="tcp://",
                      scheduler_port=0) as cluster:
        address = cluster.scheduler_address
        res = runner.invoke(app, ["--library", str(parametric_catalogue.folder), "build-twin", str(tiles), "--out",
                                  str(tmp_path / "o"), "--scheduler", address])
    assert res.exit_code == 1, res.output
    assert f"{address}: the scheduler has had no worker for 2 s; start workers" in res.stderr, res.stderr
    assert len(res.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "o").exists()


def test_epoch_of_a_folder_that_is_not_a_simulated_city_is_one_line(tmp_path, parametric_catalogue):
    (tmp_path / "stranger").mkdir()
    (tmp_path / "stranger" / "notes.txt").write_text("not a city")
    out = tmp_path / "later"
    r = CliRunner().invoke(app, ["--library", str(parametric_catalogue.folder), "simulate-city", str(out),
                                 "--epoch-of", str(tmp_path / "stranger")])
    assert r.exit_code == 1, r.output
    line = r.output.strip()
    assert line.startswith("error:") and "\n" not in line and "truth.json" in line and "simulate-city" in line
    assert not out.exists() and sorted(p.name for p in (tmp_path / "stranger").iterdir()) == ["notes.txt"]
