"""The command line as users and scripts see it: exit codes, one JSON document on stdout, files written."""

import json
import re
import shutil

import numpy as np
import pytest
from typer.testing import CliRunner

from tests.conftest import CARS, need
from twinreg.cli import app

runner = CliRunner()


def run(*args):
    return runner.invoke(app, [str(a) for a in args])


def test_add_list_show_models_json(tmp_path):
    lib = tmp_path / "lib"
    res = run("add-model", need(CARS / "toyota_prius" / "Hybrid.obj"), "--name", "prius", "--make", "Toyota",
              "--model", "Prius", "--body-class", "hatchback", "--tag", "hybrid", "--library", lib, "--json")
    assert res.exit_code == 0, res.output
    doc = json.loads(res.stdout)
    for key in ("id", "name", "make", "model", "body_class", "size", "symmetry", "n_points", "sha256"):
        assert key in doc
    assert doc["name"] == "prius" and doc["size"]["length"] == pytest.approx(4.6, abs=0.1)
    assert doc["symmetry"]["found"] is True and doc["unit"] == "cm"

    res = run("list-models", "--library", lib, "--json")
    assert res.exit_code == 0 and [m["name"] for m in json.loads(res.stdout)] == ["prius"]
    res = run("list-models", "--library", lib, "--near", 4.6, 1.8, 1.5, "--json")
    assert len(json.loads(res.stdout)) == 1
    res = run("list-models", "--library", lib, "--near", 3.0, 1.5, 1.4, "--json")
    assert json.loads(res.stdout) == []

    png = tmp_path / "prius.png"
    res = run("show-model", "prius", "--library", lib, "--plot", png, "--json")
    assert res.exit_code == 0, res.output
    shown = json.loads(res.stdout)
    assert png.stat().st_size > 10_000 and len(shown["sections"]["longitudinal"]) > 20

    res = run("update-model", "prius", "--body-class", "liftback", "--library", lib, "--json")
    assert json.loads(res.stdout)["body_class"] == "liftback"
    res = run("remove-model", "prius", "--yes", "--library", lib)
    assert res.exit_code == 0
    res = run("show-model", "prius", "--library", lib)
    assert res.exit_code == 1 and "error: no model 'prius'" in res.output


def test_import_models_skips_bad_files(tmp_path):
    src = tmp_path / "in"
    src.mkdir()
    shutil.copy(need(CARS / "uaz_469" / "uaz469_chassis.obj"), src / "uaz.obj")
    shutil.copy(CARS / "generic_pickup_gazebo" / "pickup.dae", src / "pickup.dae")
    (src / "broken.stl").write_text("solid nothing\nendsolid\n")
    res = run("import-models", src, "--library", tmp_path / "lib", "--json")
    assert res.exit_code == 0, res.output
    doc = json.loads(res.stdout)
    assert sorted(m["name"] for m in doc["added"]) == ["pickup", "uaz"]
    assert [s["file"] for s in doc["skipped"]] == [str(src / "broken.stl")]


def test_inspect_dales_car_json(dales):
    f = dales / "car" / "100.xyz"
    res = run("inspect", f, "--json")
    assert res.exit_code == 0, res.output
    doc = json.loads(res.stdout)
    for key in ("n_points", "centroid", "heading_rad", "symmetry", "size", "sections"):
        assert key in doc
    pts = np.loadtxt(f)
    assert doc["n_points"] == len(pts)
    assert np.hypot(*(np.array(doc["centroid"][:2]) - pts[:, :2].mean(0))) < 1.0
    assert 3.5 < doc["size"]["length"] < 6 and doc["symmetry"]["found"]


def test_inspect_unreadable_file(tmp_path):
    bad = tmp_path / "bad.xyz"
    bad.write_text("these are not numbers\n")
    res = run("inspect", bad)
    assert res.exit_code == 1 and res.output.startswith("error:") and "bad.xyz" in res.output


def test_cluster_folder_with_plots(tmp_path, dales):
    objs = tmp_path / "objs"
    objs.mkdir()
    for name in ("100", "101", "102", "103"):
        shutil.copy(dales / "car" / f"{name}.xyz", objs)
    for name in ("300", "301"):
        shutil.copy(dales / "pole" / f"{name}.xyz", objs / f"p{name}.xyz")
    res = run("cluster", objs, "--plot", tmp_path / "plots", "--json")
    assert res.exit_code == 0, res.output
    doc = json.loads(res.stdout)
    m = np.array(doc["dissimilarity"])
    assert m.shape == (6, 6) and np.allclose(m, m.T)
    assert (tmp_path / "plots" / "heatmap.png").stat().st_size > 5000
    assert (tmp_path / "plots" / "dendrogram.png").stat().st_size > 5000
    # at the default threshold (the paper's 6.5 cm) no pole shares a cluster with a car
    assert doc["threshold_m"] == 0.065
    cluster_of = {o["id"]: o["cluster"] for o in doc["objects"]}
    cars = {cluster_of[n] for n in ("100", "101", "102", "103")}
    assert cluster_of["p300"] not in cars and cluster_of["p301"] not in cars


def test_cluster_a_scene_file(tmp_path):
    """Objects detected in a scan cluster by model: two cars of each of three parametric models (no tree: a car
    half hidden by a canopy has other sections and may stand alone)."""
    from twinreg.io.ply import write_ply
    from twinreg.sim.parametric import LIBRARY, car_mesh
    from twinreg.sim.scan import car_park

    specs = [LIBRARY[0], LIBRARY[2], LIBRARY[5]]  # supermini, sedan, van
    models = [car_mesh(s) for s in specs]
    park = car_park(models, n_cars=6, seed=4, distractors=False)
    write_ply(tmp_path / "park.ply", park.points)

    def clusters_by_model(*options):
        res = run("cluster", tmp_path / "park.ply", *options, "--json")
        assert res.exit_code == 0, res.output
        doc = json.loads(res.stdout)
        assert len(doc["objects"]) == 6
        groups = {}
        for o in doc["objects"]:  # objects are ordered by x then y: the truth is the nearest simulated car
            c = min(park.cars, key=lambda car: np.hypot(car.x - o_x(o), car.y - o_y(o)))
            groups.setdefault(o["cluster"], []).append(specs[c.model].body_class)
        return sorted(sorted(g) for g in groups.values())

    centres = {}

    def o_x(o):
        return centres[o["id"]][0]

    def o_y(o):
        return centres[o["id"]][1]

    det = json.loads(run("detect", tmp_path / "park.ply", "--json").stdout)
    centres.update({o["id"]: o["centroid"] for o in det["objects"]})
    # 4.5 cm tells the three models apart; the default (the paper's 6.5 cm) groups body types: the two vans
    # alone, the low cars (superminis and saloons) together
    assert clusters_by_model("--threshold", "0.045") == [["sedan", "sedan"], ["supermini", "supermini"],
                                                         ["van", "van"]]
    assert clusters_by_model() == [["sedan", "sedan", "supermini", "supermini"], ["van", "van"]]


@pytest.mark.parametrize("args, code, words", [
    (["list-models", "--near", "4", "2", "1", "--tol", "-1"], 2, "--tol -1.0: must be a positive length"),
    (["cluster", "{tmp}", "--threshold", "-1"], 2, "--threshold -1.0: must be a positive length"),
    (["detect", "{tmp}"], 1, "is a folder; pass one point file"),
    (["inspect", "{tmp}"], 1, "is a folder; pass one point file"),
    (["build-twin", "{tmp}", "--lat", "90", "--lon", "0"], 1, "strictly between -90 and 90"),
    (["inspect", "{same}"], 1, "degenerate object: all 5000 points are at one spot"),
    (["inspect", "{line}"], 1, "degenerate object: its 300 points are collinear in plan"),
    (["inspect", "{few}"], 1, "degenerate object: only 6 points"),
])
def test_bad_arguments_are_one_line_errors(tmp_path, args, code, words):
    np.savetxt(tmp_path / "same.xyz", np.tile([1.0, 2.0, 3.0], (5000, 1)))
    t = np.linspace(0, 4, 300)
    np.savetxt(tmp_path / "line.xyz", np.c_[t, 0.5 * t, np.random.default_rng(0).random(300)])
    np.savetxt(tmp_path / "few.xyz", np.random.default_rng(1).random((6, 3)))
    files = {"tmp": tmp_path, "same": tmp_path / "same.xyz", "line": tmp_path / "line.xyz",
             "few": tmp_path / "few.xyz"}
    res = run(*[a.format(**files) for a in args], "--library", tmp_path / "lib") if args[0] in (
        "list-models", "build-twin") else run(*[a.format(**files) for a in args])
    assert res.exit_code == code, res.output
    assert res.output.startswith("error:") and words in res.output and "\n" not in res.output.strip()
    assert "Warning" not in res.output and "RuntimeWarning" not in res.output


def test_library_and_json_before_the_sub_command(tmp_path, parametric_objs, monkeypatch):
    # the global options set $TWINREG_LIBRARY / $TWINREG_JSON for the sub-command: restored after this test
    monkeypatch.delenv("TWINREG_LIBRARY", raising=False)
    monkeypatch.delenv("TWINREG_JSON", raising=False)
    res = run("--library", tmp_path / "lib", "add-model", parametric_objs["demo_van"])
    assert res.exit_code == 0, res.output
    res = run("--library", tmp_path / "lib", "--json", "list-models")
    assert res.exit_code == 0 and [m["name"] for m in json.loads(res.stdout)] == ["demo_van"]


def test_the_command_line_imports_no_heavy_library_until_a_command_needs_it():
    import subprocess
    import sys
    from pathlib import Path

    heavy = ("scipy", "sqlalchemy", "open3d", "matplotlib", "laspy", "trimesh", "pyproj", "dask")
    # the command line itself; then what the catalogue's listing needs (SQLAlchemy, not the geometry)
    for module, allowed in (("twinreg.cli", ()), ("twinreg.catalogue.repository", ("sqlalchemy",))):
        code = f"import sys, {module}; print([m for m in {heavy!r} if m in sys.modules and m not in {allowed!r}])"
        done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120,
                              cwd=Path(__file__).resolve().parents[2])
        assert done.returncode == 0 and done.stdout.strip() == "[]", module + done.stdout + done.stderr[-2000:]


def test_help_renders_flags_as_flags_and_shows_defaults():
    """--help as users read it: arguments as NAME..., flags without a type, every default shown (square brackets
    in a help text are not eaten as markup)."""
    import re

    for command in ("build-twin", "compare", "library-report", "add-model", "list-models", "detect", "view"):
        res = runner.invoke(app, [command, "--help"], terminal_width=120)
        assert res.exit_code == 0, res.output
        assert "<bool>" not in res.output and "{" not in res.output.splitlines()[0], res.output[:400]
        assert not re.search(r"<list\[", res.output), res.output[:400]
    text = runner.invoke(app, ["build-twin", "--help"], terminal_width=120).output
    assert text.startswith("Usage: twinreg build-twin [OPTIONS] PATH...")
    for default in ("[default: 0.065]", "[default: 10]", "[default: the cores]", "[default: about 6M",
                    "[default: twin.ply"):
        assert default in text, default
    assert re.search(r"--restart\s+Tiled runs", text)
    report = runner.invoke(app, ["library-report", "--help"], terminal_width=120).output
    assert "[default: 20.0]" in report


def test_progress_as_plain_lines_when_stderr_is_a_log(parametric_catalogue, tmp_path):
    """stderr redirected to a file (a log, a CI job): the run says its stages with the elapsed time and the
    matching's count and time left, then every file written and the objects by outcome."""
    import os
    import subprocess
    import sys
    from pathlib import Path

    from twinreg.sim.parametric import LIBRARY, car_mesh
    from twinreg.io.ply import write_ply
    from twinreg.sim.scan import car_park

    park = car_park([car_mesh(s) for s in LIBRARY[:4]], n_cars=8, seed=3)
    write_ply(tmp_path / "park.ply", park.points)
    out = tmp_path / "out"
    with open(tmp_path / "log.txt", "w") as log:
        proc = subprocess.run([str(Path(sys.executable).parent / "twinreg"), "--library",
                               str(parametric_catalogue.folder), "build-twin", str(tmp_path / "park.ply"), "--lat",
                               "53.35", "--lon", "-6.26", "--out", str(out)], stderr=log, timeout=300,
                              env={**os.environ, "TWINREG_PROGRESS_QUIET": "0"})
    text = (tmp_path / "log.txt").read_text()
    assert proc.returncode == 0, text
    assert re.search(r"^\[\d+ s\] park\.ply: matching \d+/\d+ \(100 %\), \d+ s$", text, re.M), text
    objects = next(line for line in text.splitlines() if line.startswith("objects: "))
    assert re.match(r"objects: \d+ with a model \(\d+ at confidence 0\.5 or more\)", objects), objects
    written = next(line for line in text.splitlines() if line.startswith(f"written to {out}: "))
    for name in sorted(p.name for p in out.iterdir() if not p.name.startswith(".")):
        assert name in written, name
    assert "tiles/ (" in written and "twin.gpkg" in written


def test_a_missing_scan_or_catalogue_is_said_as_it_is(tmp_path, parametric_objs):
    missing_lib = tmp_path / "no_such_library"
    scene = tmp_path / "scene.xyz"
    np.savetxt(scene, np.random.default_rng(0).uniform(0, 10, (500, 3)))
    res = run("build-twin", tmp_path / "nothing.laz", "--library", missing_lib, "--lat", 53.3, "--lon", -6.2)
    assert res.exit_code == 1 and "nothing.laz: no such file" in res.output, res.output  # the scan first
    res = run("build-twin", scene, "--library", missing_lib, "--lat", 53.3, "--lon", -6.2, "--out", tmp_path / "o")
    assert res.exit_code == 1 and "no catalogue there (the folder does not exist)" in res.output, res.output
    (tmp_path / "empty").mkdir()
    res = run("build-twin", scene, "--library", tmp_path / "empty", "--lat", 53.3, "--lon", -6.2, "--out",
              tmp_path / "o")
    assert res.exit_code == 1 and "holds no catalogue (no catalogue.sqlite)" in res.output, res.output
    assert not missing_lib.exists() and not (tmp_path / "o").exists()
