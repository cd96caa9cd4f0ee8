"""A city built cell by cell with a catalogue of several kinds: every object on the ground detected on the workers,
each object's level of symmetry carried in its cell's file, the kinds and types as a scene's; the cars the same
as with the cars alone."""

from __future__ import annotations

import shutil

import pytest

from tests.conftest import CELL, furniture_rows


@pytest.mark.timeout(600)
def test_a_city_with_furniture_in_the_catalogue(small_city, parametric_catalogue, city_twin, tmp_path):
    from twinreg.catalogue.repository import Catalogue
    from twinreg.city.build import build_city_twin

    lib = tmp_path / "lib"
    shutil.copytree(parametric_catalogue.folder, lib)
    cat = Catalogue(lib)
    bin_row = next(r for r in furniture_rows() if r["slug"] == "first_2015_trash_can")
    cat.add(bin_row["path"], name="bin", category="bin")
    root, _ = small_city
    twin = build_city_twin([root / "laz"], cat, None, tmp_path / "out", cell=CELL, workers=2)
    objs = twin["objects"]
    assert len(objs) >= len(city_twin["objects"])  # every object on the ground: the cars and more
    for o in objs:
        assert o["symmetry"]["level"] in ("none", "mirror", "two_mirrors", "rotational")
        # the city's walls and trees are structure and vegetation (CONTRACT's background kinds), never modelled
        assert o["kind"] in ("car", "bin", "unknown", "vegetation", "structure") and isinstance(o["type"], int)
        if o["match"]:
            assert o["kind"] == ("bin" if o["match"]["name"] == "bin" else "car")
    # the cars found with the cars alone are found again, with the same models
    before = {(round(o["centroid"][0]), round(o["centroid"][1])): (o["match"] or {}).get("name")
              for o in city_twin["objects"]}
    after = {(round(o["centroid"][0]), round(o["centroid"][1])): (o["match"] or {}).get("name") for o in objs}
    same = sum(1 for k, v in before.items() if k in after and after[k] == v)
    assert same >= 0.95 * len(before), (same, len(before))


def test_simulate_city_puts_the_catalogues_furniture_on_the_pavements(parametric_catalogue, tmp_path):
    """``simulate-city --furniture``: the catalogue's cars park (never its furniture), its furniture stands on the
    pavements, each item in truth.json with its kind and model; without the flag, the same city as before."""
    import json

    from typer.testing import CliRunner

    from twinreg.catalogue.repository import Catalogue
    from twinreg.cli import app

    lib = tmp_path / "lib"
    shutil.copytree(parametric_catalogue.folder, lib)
    cat = Catalogue(lib)
    for r in furniture_rows():
        if r["slug"] in ("first_2015_trash_can", "fire_hydrant"):
            cat.add(r["path"], name=r["slug"], category=r["category"], scale=r["scale"])
    args = ["simulate-city", "--km2", "0.0025", "--tile", "50", "--density", "40", "--seed", "2", "--library", lib,
            "--json"]
    res = CliRunner().invoke(app, [str(a) for a in [*args[:1], tmp_path / "with", *args[1:], "--furniture"]])
    assert res.exit_code == 0, res.output
    doc = json.loads(res.stdout)
    truth = json.loads((tmp_path / "with" / "truth.json").read_text())
    items = [o for o in truth["others"] if o["kind"].startswith("furniture:")]
    assert doc["n_furniture"] == len(items) >= 4
    assert {o["kind"] for o in items} <= {"furniture:bin", "furniture:hydrant"}
    assert {o["model"] for o in items} <= {"first_2015_trash_can", "fire_hydrant"}
    assert {c["model"] for c in truth["cars"]} <= {r.name for r in cat.list() if r.category == "car"}
    res = CliRunner().invoke(app, [str(a) for a in [*args[:1], tmp_path / "without", *args[1:]]])
    plain = json.loads((tmp_path / "without" / "truth.json").read_text())
    assert res.exit_code == 0 and plain["cars"] == truth["cars"]  # the furniture changes nothing else
    assert not [o for o in plain["others"] if o["kind"].startswith("furniture:")]
    # a later survey of the furnished city: the same furniture, some of it taken away, each item an event with its
    # kind; with a catalogue whose furniture differs, refused in one line
    res = CliRunner().invoke(app, [str(a) for a in [*args[:1], tmp_path / "later", *args[1:], "--epoch-of",
                                                    tmp_path / "with"]])
    assert res.exit_code == 0, res.output
    later = json.loads((tmp_path / "later" / "truth.json").read_text())
    events = [e for e in later["events"] if e["before"] is not None and "kind" in e["before"]]
    assert len(events) == len(items) and {e["event"] for e in events} <= {"same", "left"}
    kept = [o for o in later["others"] if o["kind"].startswith("furniture:")]
    assert len(kept) == sum(e["event"] == "same" for e in events)
    assert {(round(o["x"], 3), round(o["y"], 3)) for o in kept} <= {(round(o["x"], 3), round(o["y"], 3)) for o in items}
    cat.remove("fire_hydrant")
    res = CliRunner().invoke(app, [str(a) for a in [*args[:1], tmp_path / "later2", *args[1:], "--epoch-of",
                                                    tmp_path / "with"]])
    assert res.exit_code != 0 and "catalogue the earlier one was made with" in res.output
    assert not (tmp_path / "later2").exists()
