"""`compare` on two simulated surveys of one car park: every event right at 150 pts/m2, at least 95 % when the
later survey has 20 pts/m2, no car of the missing strip called left, the offset recovered within 3 cm, the
unchanged cars keeping their model; the outputs (changes.json in the contract's shape, GeoJSON, the report), N
epochs with tracks, and the date order."""

from __future__ import annotations

import json

import numpy as np
import pytest

from twinreg.change.compare import compare
from twinreg.sim.epochs import score


@pytest.fixture(scope="module")
def dense(surveys, tmp_path_factory):
    out = tmp_path_factory.mktemp("cmp") / "dense"
    # the later twin first: epochs go in survey-date order whatever the order given
    return compare([surveys.twins["after150"], surveys.twins["before"]], out), out


def test_every_event_right_at_150(surveys, dense):
    doc, _ = dense
    s = score(doc, surveys.pairs[150.0])
    assert s["wrong"] == [] and s["spurious"] == 0, s
    assert s["right"] >= 24
    statuses = {c["status"] for c in doc["changes"]}
    assert statuses == {"same", "moved", "replaced", "left", "arrived", "unobserved"}
    assert s["strip_left"] == 0
    assert s["shift_error_m"] < 0.03
    assert s["kept_model"] == s["stayed"] > 10


def test_sparse_later_survey(surveys, tmp_path):
    doc = compare([surveys.twins["before"], surveys.twins["after20"]], tmp_path / "sparse")
    s = score(doc, surveys.pairs[20.0])
    n = s["right"] + len(s["wrong"]) + s["spurious"]
    assert s["right"] >= 0.95 * n, s
    assert s["strip_left"] == 0
    assert s["shift_error_m"] < 0.03
    # a car that stayed keeps its model, or has none claimed in the sparse survey (its confidence under the floor):
    # never another model
    assert s["kept_model"] + s["unclaimed_once"] == s["stayed"] and s["kept_model"] >= 0.9 * s["stayed"], s


def test_contract_shape(surveys, dense):
    doc, out = dense
    on_disk = json.loads((out / "changes.json").read_text())
    assert on_disk["summary"] == doc["summary"]
    assert [e["date"] for e in doc["epochs"]] == ["2026-03-02", "2026-06-02"]
    assert doc["epochs"][0]["twin"].endswith("before") and doc["epochs"][0]["n_objects"] > 20
    al = doc["alignment"][0]
    assert al["from"] == 0 and al["to"] == 1 and al["n_pairs"] >= 3 and al["rms_m"] < 0.03
    s = doc["summary"][0]
    assert sum(s[k] for k in ("same", "moved", "replaced", "left", "arrived", "unobserved")) == len(doc["changes"])
    for c in doc["changes"]:
        assert 0.0 <= c["confidence"] <= 1.0
        if c["status"] == "arrived":
            assert c["before"] is None and c["after"] is not None
        if c["status"] == "left":
            assert c["after"] is None
        for side in ("before", "after"):
            if c[side] is not None:
                assert set(c[side]) >= {"id", "centroid", "lat", "lon", "heading_rad", "model"}
        if c["status"] == "moved":
            assert 0.4 < c["displacement_m"] < 1.1 and c["turn_rad"] < 0.15


def test_geojson_and_report(dense):
    doc, out = dense
    gj = json.loads((out / "changes.geojson").read_text())
    assert gj["type"] == "FeatureCollection"
    n_footprints = sum((c["before"] is not None) + (c["after"] is not None) for c in doc["changes"])
    assert len(gj["features"]) == n_footprints
    for f in gj["features"]:
        ring = np.array(f["geometry"]["coordinates"][0])
        assert ring.shape == (5, 2) and np.allclose(ring[0], ring[-1])
        assert np.allclose(ring.mean(0), [-6.26, 53.35], atol=0.001)
        assert f["properties"]["status"] in ("same", "moved", "replaced", "left", "arrived", "unobserved")
    page = (out / "changes.html").read_text()
    for img in ("changes_0.png", "occupancy.png"):
        assert f"src='{img}'" in page and (out / img).stat().st_size > 5000


def test_three_epochs_tracks(surveys, tmp_path):
    t = surveys.twins
    doc = compare([t["after20"], t["before"], t["after150"]], tmp_path / "three")
    assert [e["date"] for e in doc["epochs"]] == list(("2026-03-02", "2026-06-02", "2026-09-01"))
    assert len(doc["alignment"]) == 2 and len(doc["summary"]) == 2
    # the third survey saw the same cars as the second, at another density and along the same lines
    s = doc["summary"][1]
    assert s["moved"] == s["replaced"] == s["left"] == s["arrived"] == 0
    pair = surveys.pairs[150.0]
    stayed = sum(1 for b in pair.bays if b.event == "same" and b.expected == "same")
    whole = [v for v in doc["tracks"] if v["epochs"] == [0, 1, 2]]
    assert len(whole) >= stayed
    assert all(v["days"] == 183 for v in whole)
    occ = doc["occupancy"]
    assert len(occ["epochs"]) == 3 and occ["common_area_m2"] > 500
    assert occ["epochs"][1]["n_in_common_area"] == occ["epochs"][2]["n_in_common_area"]
