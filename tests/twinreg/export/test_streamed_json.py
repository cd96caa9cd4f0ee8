"""twin.geojson and sections.json are written an object at a time, so that a survey's tens of thousands of
objects do not sit in memory as one document: each file is the text ``json.dumps`` gives of the whole document,
and each object's entry says what the object is (checked here from the inputs, not with the writers' helpers)."""

from __future__ import annotations

import json
from types import SimpleNamespace

import numpy as np

from twinreg.export.sections import write_sections
from twinreg.export.geojson import PROPERTIES, write_geojson


def _docs(n: int, rng) -> list[dict]:
    return [{"id": f"obj_{k:04d}", "centroid": rng.normal(size=3).tolist(), "size": {"length": 4.2, "width": 1.8},
             "match": ({"name": "Škoda Octavia \"estate\"", "confidence": float(rng.random())} if k % 3 else None),
             "heading_rad": float(rng.random())} for k in range(n)]


def _signed_area(ring) -> float:
    r = np.asarray(ring, dtype=np.float64)
    return float(np.sum(r[:-1, 0] * r[1:, 1] - r[1:, 0] * r[:-1, 1]) / 2)


def test_geojson_written_a_feature_at_a_time_is_the_whole_document(tmp_path):
    rng = np.random.default_rng(3)
    for n in (0, 1, 7):
        docs = _docs(n, rng)
        ll = rng.normal(scale=1e-4, size=(4 * n, 2)) + [-6.26, 53.35]
        path = write_geojson(tmp_path / f"{n}.geojson", docs, ll)
        text = path.read_text(encoding="utf-8")
        back = json.loads(text)
        assert text == json.dumps(back)  # json.dumps' own text of the whole document, nothing else
        assert back["type"] == "FeatureCollection" and len(back["features"]) == n
        for k, (doc, f) in enumerate(zip(docs, back["features"])):
            assert f["id"] == doc["id"] and f["geometry"]["type"] == "Polygon"
            ring = f["geometry"]["coordinates"][0]
            assert ring[0] == ring[-1] and len(ring) == 5 and _signed_area(ring) > 0  # closed, counter-clockwise
            corners = {(round(x, 9), round(y, 9)) for x, y in ll[4 * k:4 * k + 4]}
            assert {tuple(p) for p in ring} == corners
            props = f["properties"]
            assert list(props) == [name for name, _ in PROPERTIES]
            assert props["matched"] is (doc["match"] is not None)
            assert props["model"] == (doc["match"]["name"] if doc["match"] else None)
            assert props["length"] == 4.2 and props["heading_rad"] == doc["heading_rad"]


def _expected_polyline(a, n: int = 80) -> list:
    """At most ``n`` points picked evenly from a polyline, in millimetres: what sections.json promises."""
    a = np.asarray(a, dtype=np.float64)
    rows = np.unique(np.linspace(0, len(a) - 1, min(n, len(a))).astype(int))
    return [[round(float(u), 3), round(float(z), 3)] for u, z in a[rows]]


def _placed(doc: dict, lon, tra, model: dict | None) -> SimpleNamespace:
    """What sections.json reads of a placed object: its id, its shape's sections, its match and its model's
    registered sections."""
    shape = SimpleNamespace(sections=SimpleNamespace(longitudinal=lon, transverse=tra))
    match = SimpleNamespace(name="m", rmse=0.02) if model is not None else None
    return SimpleNamespace(id=doc["id"], outcome=SimpleNamespace(shape=shape, reason="no model of this size"),
                           match=match, model_sections=model or {})


def test_sections_written_an_object_at_a_time_are_the_whole_document(tmp_path):
    rng = np.random.default_rng(4)
    for n in (0, 1, 5):
        placed = []
        for k, doc in enumerate(_docs(n, rng)):
            model = {"lon": rng.normal(size=(90, 2)), "tra": rng.normal(size=(10, 2))} if k % 2 else None
            placed.append(_placed(doc, rng.normal(size=(200, 2)), rng.normal(size=(30, 2)), model))
        path = write_sections(tmp_path / f"{n}.json", placed)
        text = path.read_text(encoding="utf-8")
        back = json.loads(text)
        assert text == json.dumps(back, separators=(",", ":"))
        assert list(back) == [p.id for p in placed]
        for p in placed:
            item = back[p.id]
            assert item["lon"] == _expected_polyline(p.outcome.shape.sections.longitudinal)
            assert item["tra"] == _expected_polyline(p.outcome.shape.sections.transverse)
            if p.match is not None:
                assert item["model_lon"] == _expected_polyline(p.model_sections["lon"])
                assert item["model_tra"] == _expected_polyline(p.model_sections["tra"])
            else:
                assert set(item) == {"lon", "tra"}
