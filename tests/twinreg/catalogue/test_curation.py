"""Curating the catalogue (issue 10, first part): near-duplicate warnings on add-model and import-models, and
list-models' filters, order and CSV."""

import csv
import io
import json

import pytest
from typer.testing import CliRunner

from twinreg.cli import app


@pytest.fixture(scope="module")
def small_library(tmp_path_factory, cars):
    """Fusion, Prius and Patrol added through the API, then the Mondeo and the MKZ added by the CLI."""
    from twinreg.catalogue.repository import Catalogue

    rows = {r["slug"]: r for r in cars}
    folder = tmp_path_factory.mktemp("curation")
    cat = Catalogue(folder)
    for slug in ("ford_fusion_2013", "toyota_prius", "nissan_patrol"):
        cat.add(rows[slug]["path"], name=slug, make=rows[slug]["make"], body_class=rows[slug]["body_class"],
                tags=("dublin",) if slug != "nissan_patrol" else ())
    out = {}
    for slug in ("ford_mondeo_2015", "generic_pickup_gazebo"):
        res = CliRunner().invoke(app, ["add-model", str(rows[slug]["path"]), "--name", slug, "--body-class",
                                       rows[slug]["body_class"], "--library", str(folder), "--json"])
        assert res.exit_code == 0, res.output
        out[slug] = res
    return folder, out


def test_a_near_duplicate_is_added_with_a_warning(small_library):
    _, out = small_library
    res = out["ford_mondeo_2015"]
    doc = json.loads(res.stdout)
    assert doc["name"] == "ford_mondeo_2015"  # stored all the same
    (dup,) = doc["near_duplicates"]
    assert dup["name"] == "ford_fusion_2013" and 0 < dup["surface_distance_m"] < 0.03
    assert doc["warnings"] and "ford_fusion_2013" in doc["warnings"][0]
    assert "near-duplicate of ford_fusion_2013" in res.stderr


def test_a_different_body_is_not_a_near_duplicate(small_library):
    doc = json.loads(small_library[1]["generic_pickup_gazebo"].stdout)
    assert doc["near_duplicates"] == [] and doc["warnings"] == []


def test_surface_distance_tells_prius_from_patrol(prepared_cars):
    from twinreg.catalogue.duplicates import NEAR_DUPLICATE_M, surface_distance

    far = surface_distance(prepared_cars["toyota_prius"].points, prepared_cars["nissan_patrol"].points)
    twin = surface_distance(prepared_cars["ford_fusion_2013"].points, prepared_cars["ford_mondeo_2015"].points)
    assert twin < NEAR_DUPLICATE_M < far and far > 0.15


def test_list_models_filters_sorts_and_writes_csv(small_library):
    folder, _ = small_library
    res = CliRunner().invoke(app, ["list-models", "--class", "SEDAN", "--tag", "dublin", "--library", str(folder),
                                   "--json"])
    assert res.exit_code == 0, res.output
    assert [m["name"] for m in json.loads(res.stdout)] == ["ford_fusion_2013"]  # the Mondeo has no tag
    res = CliRunner().invoke(app, ["list-models", "--sort", "length", "--csv", "--library", str(folder)])
    rows = list(csv.DictReader(io.StringIO(res.stdout)))
    lengths = [float(r["length"]) for r in rows]
    assert len(rows) == 5 and lengths == sorted(lengths)
    assert {r["name"] for r in rows if "dublin" in r["tags"].split(";")} == {"ford_fusion_2013", "toyota_prius"}
    res = CliRunner().invoke(app, ["list-models", "--sort", "colour", "--library", str(folder)])
    assert res.exit_code == 1 and "--sort colour" in res.output
