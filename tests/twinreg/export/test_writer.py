"""One writer for a scene's and a city's files (export/formats.write_twin) over placed objects: every format of
the two tables written, a city's per-group KMZ folders and PLY files, and a format added to a table is written
with no other change."""

from __future__ import annotations

import json
import zipfile

import numpy as np
import pytest

from twinreg.settings import DEFAULT
from tests.twinreg.helpers import toy_shapes
from twinreg.export import formats
from twinreg.export.formats import TwinFiles, write_twin
from twinreg.stages import place


@pytest.fixture(scope="module")
def placed(parametric_catalogue):
    from twinreg.geo.georef import georef_from_options
    from twinreg.matching.match import ModelCache, ObjectMatch, match_objects

    shapes = toy_shapes(4)
    models = ModelCache(parametric_catalogue, DEFAULT)
    results, _ = match_objects(shapes, parametric_catalogue, cache=models)
    results[-1] = ObjectMatch(shapes[-1], None, "refused for the test", [], reason_code="top_unseen")
    georef = georef_from_options(lat=53.35, lon=-6.26)
    offset = np.array([10.0, -4.0, 2.0])
    return place([f"c{k // 2}-{k + 1}" for k in range(4)], [s.n_points for s in shapes], results, [1, 1, 2, 2],
                 [offset] * 4, georef, models), georef, models


def test_a_scene_gets_every_format_of_both_tables(placed, tmp_path):
    objs, georef, models = placed
    entries = write_twin(TwinFiles(tmp_path, "toy", objs, georef, models, [("scene", [0, 1, 2, 3])], ply="twin"))
    for name in ("twin.kmz", "twin.ply", "twin.glb", "tiles/tileset.json", "twin.city.json",
                 "twin.geojson", "sections.json", "twin.gpkg"):
        assert (tmp_path / name).is_file(), name
    assert entries["tiles"]["n_tiles"] == 1 and entries["tiles"]["n_scan_points"] == 0
    assert not (tmp_path / "twin.prj").exists()  # a local frame (a --lat/--lon) has no CRS to state
    kml = zipfile.ZipFile(tmp_path / "twin.kmz").read("doc.kml").decode()
    assert kml.count("<Placemark>") == 4 and "<Region>" not in kml
    kinds = {p.doc["kind"] or "unknown" for p in objs}  # a Folder and a Style a kind, ExtendedData with the kind
    assert kml.count("<Folder>") == len(kinds) and kml.count("<Style id=") == len(kinds)
    assert kml.count('<Data name="kind">') == 4 and kml.count('<Data name="type">') == 4
    assert list(json.loads((tmp_path / "sections.json").read_text())) == [p.id for p in objs]
    assert not (tmp_path / "twin.city.jsonl").exists()


def test_a_city_gets_a_kmz_folder_and_a_ply_file_a_group(placed, tmp_path):
    objs, georef, models = placed
    bounds = {"north": 53.36, "south": 53.34, "east": -6.25, "west": -6.27}
    write_twin(TwinFiles(tmp_path, "toy city", objs, georef, models, [("c0", [0, 1]), ("c1", [2, 3])], ply="groups",
                         regions={"c0": bounds, "c1": bounds}, templates=True, seq=True, fork=True))
    kml = zipfile.ZipFile(tmp_path / "twin.kmz").read("doc.kml").decode()
    kinds = {p.doc["kind"] or "unknown" for p in objs}
    assert kml.count("<Region>") >= 2 and kml.count("<Placemark>") == 4
    assert kml.count("<Folder>") == len(kinds) + kml.count("<Region>")
    assert sorted(p.name for p in (tmp_path / "ply").iterdir()) == ["c0.ply", "c1.ply"]
    assert not (tmp_path / "twin.ply").exists()
    assert len((tmp_path / "twin.city.jsonl").read_text().splitlines()) == 1 + 4  # the header, then each object


def test_a_format_added_to_a_table_is_written_with_no_other_change(placed, tmp_path, monkeypatch):
    objs, georef, models = placed
    seen = {}

    def ids_file(f):  # a new format of the placed objects
        (f.stage / "ids.txt").write_text("\n".join(p.id for p in f.placed))
        return {"ids": len(f.placed)}

    def kinds_file(view):  # a new format of the records
        seen["kinds"] = [d["kind"] for d in view.docs]

    monkeypatch.setattr(formats, "TWIN_FORMATS", formats.TWIN_FORMATS + (ids_file,))
    monkeypatch.setattr(formats, "RECORD_FORMATS", formats.RECORD_FORMATS + (kinds_file,))
    entries = write_twin(TwinFiles(tmp_path, "toy", objs, georef, models, [("scene", [0, 1, 2, 3])]))
    assert entries["ids"] == 4 and (tmp_path / "ids.txt").read_text().split() == [p.id for p in objs]
    assert seen["kinds"] == ["car", "car", "car", "unknown"]
