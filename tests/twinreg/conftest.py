"""Fixtures of the twinreg tests: the simulated car park of the shared cars and its twin (module scope: each module
that uses them builds them once); the catalogue a user starts with (the shared cars and street furniture, built
once a session)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from tests.conftest import catalogue_models
from tests.twinreg.helpers import DUBLIN
from twinreg.cli import app
from twinreg.io.ply import write_ply
from twinreg.sim.scan import car_park


@pytest.fixture(scope="session")
def city_catalogue(catalogue16, tmp_path_factory):
    """The 16 shared cars and the 9 shared street-furniture models (its manifest): what a user starts with."""
    import shutil

    from tests.conftest import SHARED_DATA, need

    lib = tmp_path_factory.mktemp("city_catalogue") / "lib"
    shutil.copytree(catalogue16.folder, lib)
    folder = need(SHARED_DATA / "street_furniture")
    res = CliRunner().invoke(app, ["import-models", str(folder), "--manifest", str(folder / "catalogue.csv"),
                                   "--library", str(lib), "-q"])
    assert res.exit_code == 0, res.output
    return lib


@pytest.fixture(scope="module")
def park(catalogue16, tmp_path_factory):
    """12 cars of 12 different shared models, 0.4-1.0 m apart, oblique passes, 2 cm noise, distractors; the scene
    is shifted to Irish Grid-sized coordinates to exercise float64 precision."""
    names = sorted(r.name for r in catalogue16.list())
    models = catalogue_models(catalogue16, names)
    scene = car_park(models, n_cars=12, seed=23, gaps=(0.4, 1.0))
    offset = np.array([715_800.0, 734_600.0, 20.0])
    path = tmp_path_factory.mktemp("park") / "park.ply"
    write_ply(path, scene.points + offset)
    return {"scene": scene, "names": names, "path": path, "offset": offset}


@pytest.fixture(scope="module")
def twin(park, catalogue16, tmp_path_factory):
    out = tmp_path_factory.mktemp("twin") / "out"
    res = CliRunner().invoke(app, ["build-twin", str(park["path"]), *DUBLIN, "--anchor",
                                   str(park["offset"][0]), str(park["offset"][1]), "--library",
                                   str(catalogue16.folder), "--out", str(out), "--json"])
    assert res.exit_code == 0, res.output
    doc = json.loads(res.stdout)
    assert doc == json.loads((out / "twin.json").read_text())
    return doc, out
