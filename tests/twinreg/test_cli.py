"""The command line as users and scripts see it: exit codes, one JSON document on stdout, files written."""

import json
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


def test_cluster_a_scene_file(tmp_path):
    """Objects detected in a scan cluster by model: two cars of each of three parametric models (no tree: a car
    half hidden by a canopy has other sections and may stand alone)."""
    from twinreg.io.ply import write_ply
    from twinreg.parametric import LIBRARY, car_mesh
    from twinreg.simulate import car_park

    specs = [LIBRARY[0], LIBRARY[2], LIBRARY[5]]  # supermini, sedan, van
    models = [car_mesh(s) for s in specs]
    park = car_park(models, n_cars=6, seed=4, distractors=False)
    write_ply(tmp_path / "park.ply", park.points)
    res = run("cluster", tmp_path / "park.ply", "--threshold", "0.045", "--json")
    assert res.exit_code == 0, res.output
    doc = json.loads(res.stdout)
    assert len(doc["objects"]) == 6
    by_model = {}
    for o in doc["objects"]:
        by_model.setdefault(o["cluster"], []).append(o["id"])
    assert doc["n_clusters"] == 3 and sorted(len(v) for v in by_model.values()) == [2, 2, 2]
