"""twinreg coverage (issue 10): the objects of twins that got no model, grouped by size, and the sizes the
catalogue lacks."""

import json

from typer.testing import CliRunner

from twinreg.cli import app


def _obj(k, length, width, height, match=None):
    return {"id": f"obj{k}", "measured_size": {"length": length, "width": width, "height": height}, "match": match}


def test_small_cars_are_reported_as_missing_sizes(catalogue16, tmp_path):
    objs = [_obj(k, 3.3 + 0.02 * k, 1.55, 1.45) for k in range(6)]  # smaller than any shared car
    objs += [_obj(10, 4.9, 1.85, 1.30)]  # a Fusion-sized object that no model explained
    objs += [_obj(11, 4.6, 1.80, 1.50, {"name": "toyota_prius", "outside_tolerance": False})]
    twin = tmp_path / "twin.json"
    twin.write_text(json.dumps({"objects": objs}))
    res = CliRunner().invoke(app, ["coverage", str(twin), "--library", str(catalogue16.folder), "--json",
                                   "--plot", str(tmp_path / "cov.png")])
    assert res.exit_code == 0, res.output
    doc = json.loads(res.stdout)
    assert doc["n_objects"] == 8 and doc["n_lacking"] == 7
    small, fusion = doc["groups"]
    assert small["n_objects"] == 6 and small["models_within_tol"] == 0
    assert small["text"].startswith("6 cars 3.3-3.4 m long, 1.6-1.6 m wide: no model in the size window")
    assert small["kind"] == "car" and doc["per_kind"] == {"car": {"n_objects": 8, "n_lacking": 7}}
    assert fusion["models_within_tol"] >= 3  # Fusion, Mondeo, MKZ...: near in size, none accepted
    assert (tmp_path / "cov.png").stat().st_size > 10_000


def test_coverage_per_kind_names_the_nearest_model_of_the_kind(tmp_path):
    """Objects of other kinds are grouped apart and each group's nearest model is one of its kind."""
    import numpy as np

    from twinreg.catalogue.coverage import coverage

    objs = [_obj(k, 0.45, 0.42, 0.9) | {"kind": "hydrant"} for k in range(3)]
    objs += [_obj(5, 4.2, 1.7, 1.4) | {"kind": "car"}, _obj(6, 0.5, 0.45, 0.8) | {"kind": "unknown"}]
    models = np.array([[4.5, 1.8, 1.5], [0.6, 0.6, 1.0], [0.55, 0.55, 1.1]])
    doc = coverage(objs, models, ["golf", "hydrant_a", "cone_b"], ["car", "hydrant", "cone"])
    by_kind = {g["kind"]: g for g in doc["groups"]}
    assert set(by_kind) == {"hydrant", "car", "unknown"}
    assert by_kind["hydrant"]["nearest_model"]["name"] == "hydrant_a" and by_kind["hydrant"]["n_objects"] == 3
    assert by_kind["car"]["nearest_model"]["name"] == "golf"
    assert by_kind["unknown"]["nearest_model"]["name"] in ("hydrant_a", "cone_b")  # any kind, the nearest
    assert by_kind["hydrant"]["text"].startswith("3 hydrants") and by_kind["unknown"]["text"].startswith("1 object ")
    assert doc["per_kind"]["hydrant"] == {"n_objects": 3, "n_lacking": 3}


def test_a_file_that_is_not_a_twin_is_refused(tmp_path):
    bad = tmp_path / "twin.json"
    bad.write_text("{\"scene\": 1}")
    res = CliRunner().invoke(app, ["coverage", str(bad)])
    assert res.exit_code == 1 and "not a twin.json written by build-twin" in res.output
