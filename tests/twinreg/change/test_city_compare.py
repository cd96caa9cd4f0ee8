"""Two surveys of a city compared as one twin each (cells handled as one): simulate-city --epoch-of writes the
later survey (other lines, 50 pts/m2, offset, a strip without returns, the events in truth.json), both are built
cell by cell, and compare gets the events right and the offset within 3 cm."""

from __future__ import annotations

import json

from typer.testing import CliRunner

from tests.conftest import CELL
from twinreg.cli import app
from twinreg.sim.city_epoch import score_city


def test_city_pair(small_city, city_twin, parametric_catalogue, tmp_path):
    from twinreg.city.build import build_city_twin

    root, _ = small_city
    r = CliRunner().invoke(app, ["--library", str(parametric_catalogue.folder), "--json", "simulate-city",
                                 str(tmp_path / "later"), "--epoch-of", str(root / "laz"), "--density", "50",
                                 "--date", "2026-06-02", "--seed", "2"])
    assert r.exit_code == 0, r.output
    made = json.loads(r.stdout[r.stdout.index("{"):])
    assert made["date"] == "2026-06-02" and min(made["events"].values()) >= 1, made
    later = build_city_twin([tmp_path / "later"], parametric_catalogue, None, tmp_path / "later_twin", cell=CELL,
                            workers=2)
    assert later["survey_date"] == "2026-06-02" and later["observation"]["rasters"] >= 4
    r = CliRunner().invoke(app, ["--json", "compare", str(tmp_path / "later_twin"), str(root / "out"), "--out",
                                 str(tmp_path / "changes")])
    assert r.exit_code == 0, r.output
    doc = json.loads(r.stdout[r.stdout.index("{"):])
    assert [e["date"] for e in doc["epochs"]] == ["2026-03-02", "2026-06-02"]
    truth = json.loads((tmp_path / "later" / "truth.json").read_text())
    s = score_city(doc, truth)
    n = s["right"] + s["n_wrong"] + s["spurious"]
    assert n >= 60 and s["right"] >= 0.95 * n, s
    assert not any(k.startswith("unobserved ->") and k.endswith("left") for k in s["wrong"]), s
    assert abs(doc["alignment"][0]["shift"][0] - 0.1) < 0.03 and abs(doc["alignment"][0]["shift"][2] - 0.1) < 0.03
