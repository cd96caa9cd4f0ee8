"""The demo: parametric cars through add-model, a simulated scan, build-twin; deterministic by seed."""

import json
import sqlite3
import zipfile

import numpy as np
from typer.testing import CliRunner

from twinreg.cli import app
from twinreg.sim.parametric import LIBRARY, car_mesh


def test_parametric_cars_are_closed_and_real_sized():
    import trimesh

    classes = {s.body_class for s in LIBRARY}
    assert {"supermini", "hatchback", "sedan", "wagon", "SUV", "van"} <= classes
    for spec in LIBRARY:
        v, f = car_mesh(spec)
        parts = trimesh.Trimesh(v, f, process=True).split(only_watertight=False)
        assert all(p.is_watertight for p in parts)
        ext = np.ptp(v, axis=0)
        assert abs(ext[0] - spec.length) < 1e-6 and abs(ext[2] - spec.height) < 1e-6
        assert ext[1] > spec.width  # the mirrors stick out of the body


def test_demo_runs_and_is_deterministic(tmp_path):
    runner = CliRunner()
    res = runner.invoke(app, ["demo", "--out", str(tmp_path / "a"), "--seed", "3", "--json"])
    assert res.exit_code == 0, res.output
    a = json.loads(res.stdout)
    assert len(a["objects"]) == a["n_cars"] >= 12
    assert a["n_correct"] >= a["n_cars"] - 1
    assert max(o["position_error_m"] for o in a["objects"]) < 0.15
    assert max(o["heading_error_deg"] for o in a["objects"]) < 3.0
    kmz = zipfile.ZipFile(a["files"]["twin_kmz"])
    assert kmz.namelist()[0] == "doc.kml"
    res = runner.invoke(app, ["demo", "--out", str(tmp_path / "b"), "--seed", "3", "--json"])
    b = json.loads(res.stdout)
    strip = lambda d: [{k: v for k, v in o.items()} for o in d["objects"]]  # noqa: E731
    assert strip(a) == strip(b)
    # an earlier demo is replaced, after its catalogue was exported (which leaves nothing beside it) and opened by
    # a read-only reader (which leaves SQLite's -wal and -shm files: still the demo's own catalogue)
    lib = tmp_path / "a" / "library"
    res = runner.invoke(app, ["export-library", str(tmp_path / "lib.zip"), "--library", str(lib)])
    assert res.exit_code == 0, res.output
    assert not list(lib.glob("catalogue.sqlite-*"))
    ro = sqlite3.connect(f"file:{lib / 'catalogue.sqlite'}?mode=ro", uri=True)
    ro.execute("SELECT count(*) FROM ref_models").fetchall()
    ro.close()
    assert sorted(p.name for p in lib.glob("catalogue.sqlite-*")) == ["catalogue.sqlite-shm", "catalogue.sqlite-wal"]
    res = runner.invoke(app, ["demo", "--out", str(tmp_path / "a"), "--seed", "3"])
    assert res.exit_code == 0, res.output
    assert not list(lib.glob("catalogue.sqlite-*"))
    # a folder holding the user's own files is not touched
    mine = tmp_path / "mine"
    (mine / "library").mkdir(parents=True)
    (mine / "library" / "catalogue.sqlite").write_text("the user's catalogue")
    res = runner.invoke(app, ["demo", "--out", str(mine)])
    assert res.exit_code == 1 and "did not write" in res.output
    assert (mine / "library" / "catalogue.sqlite").read_text() == "the user's catalogue"
