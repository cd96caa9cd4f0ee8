"""twin.geojson and sections.json are written an object at a time, so that a survey's tens of thousands of
objects do not sit in memory as one document: the bytes are those of ``json.dumps`` of the whole document."""

from __future__ import annotations

import json
from types import SimpleNamespace

import numpy as np

from twinreg.export.formats import _section_item, write_sections
from twinreg.export.geojson import _feature, write_geojson


def _docs(n: int, rng) -> list[dict]:
    return [{"id": f"obj_{k:04d}", "centroid": rng.normal(size=3).tolist(), "size": {"length": 4.2, "width": 1.8},
             "match": ({"name": "Škoda Octavia \"estate\"", "confidence": float(rng.random())} if k % 3 else None),
             "heading_rad": float(rng.random())} for k in range(n)]


def test_geojson_written_a_feature_at_a_time_is_the_whole_document(tmp_path):
    rng = np.random.default_rng(3)
    for n in (0, 1, 7):
        docs = _docs(n, rng)
        ll = rng.normal(size=(4 * n, 2)) + [-6.26, 53.35]
        path = write_geojson(tmp_path / f"{n}.geojson", docs, ll)
        whole = {"type": "FeatureCollection",
                 "features": [_feature(d, ll[4 * k:4 * k + 4]) for k, d in enumerate(docs)]}
        assert path.read_text(encoding="utf-8") == json.dumps(whole)
        assert len(json.loads(path.read_text(encoding="utf-8"))["features"]) == n


def test_sections_written_an_object_at_a_time_are_the_whole_document(tmp_path):
    rng = np.random.default_rng(4)
    for n in (0, 1, 5):
        outputs = []
        for k, doc in enumerate(_docs(n, rng)):
            sections = {"object": {"lon": rng.normal(size=(200, 2)), "tra": rng.normal(size=(30, 2))}}
            if k % 2:
                sections["model"] = {"lon": rng.normal(size=(90, 2)), "tra": rng.normal(size=(10, 2))}
            outputs.append(SimpleNamespace(doc=doc, sections=sections))
        path = write_sections(tmp_path / f"{n}.json", outputs)
        whole = {o.doc["id"]: _section_item(o.sections) for o in outputs}
        assert path.read_text(encoding="utf-8") == json.dumps(whole, separators=(",", ":"))
        back = json.loads(path.read_text(encoding="utf-8"))
        assert list(back) == [o.doc["id"] for o in outputs]
        assert [("model_lon" in back[o.doc["id"]]) for o in outputs] == [k % 2 == 1 for k in range(n)]
