"""twin.gpkg written by pyogrio and read back: polygons in the stated CRS, every attribute of twin.geojson with
its type, nulls as nulls, a twin without a projected CRS in WGS84."""

from __future__ import annotations

import sqlite3

import numpy as np

from twinreg.export.geojson import PROPERTIES
from twinreg.export.gpkg import polygon_wkb, write_gpkg


def _docs():
    return [{"id": "obj1", "kind": "car", "n_points": 812, "position_crs": [121000.5, 487000.25, 1.1],
             "size": {"length": 4.4, "width": 1.8, "height": 1.5}, "match": {"name": "demo_sedan", "model_id": 3,
                                                                               "confidence": 0.93, "rmse_m": 0.03}},
            {"id": "obj2", "kind": "unknown", "n_points": 90, "position_crs": [121010.0, 487003.0, 0.9],
             "match": None, "reason_code": "no_model_of_this_size", "reason": "no catalogue model of its size"}]


def _rings():
    box = np.array([[-2.2, -0.9], [2.2, -0.9], [2.2, 0.9], [-2.2, 0.9]])
    return np.vstack([box + [121000.5, 487000.25], box + [121010.0, 487003.0]])


def test_read_back_in_its_crs_with_every_attribute(tmp_path):
    import pyogrio

    path = write_gpkg(tmp_path / "t.gpkg", _docs(), _rings(), "EPSG:7415", "m")
    info = pyogrio.read_info(path)
    assert info["crs"] == "EPSG:7415" and info["features"] == 2 and info["geometry_type"] == "Polygon"
    with sqlite3.connect(path) as con:
        assert con.execute("select srs_id from gpkg_geometry_columns").fetchall() == [(7415,)]
    meta, _, geometry, fields = pyogrio.raw.read(path)
    sizes = {"length", "width", "height", "measured_length", "measured_width", "measured_height"}
    assert list(meta["fields"]) == [f"{n}_m" if n in sizes else n for n, _ in PROPERTIES] + ["xyz_unit"]
    row = {name: list(col) for name, col in zip(meta["fields"], fields)}
    assert row["id"] == ["obj1", "obj2"] and list(row["matched"]) == [True, False]
    assert row["model"][0] == "demo_sedan" and row["model"][1] is None  # a null, not an empty text
    assert row["reason_code"] == [None, "no_model_of_this_size"] and row["xyz_unit"] == ["m", "m"]
    assert row["length_m"][0] == 4.4
    with sqlite3.connect(path) as con:  # the layer says its units
        (description,) = con.execute("select description from gpkg_contents").fetchone()
    assert "x, y, z in the CRS's unit (m)" in description and "sizes in metres" in description
    assert np.isnan(row["confidence"][1]) and row["confidence"][0] == 0.93
    ring = np.frombuffer(geometry[0][13:], dtype="<f8").reshape(-1, 2)
    assert len(ring) == 5 and np.array_equal(ring[0], ring[-1]) and np.allclose(ring[:4], _rings()[:4])


def test_a_local_twin_is_in_wgs84(tmp_path):
    import pyogrio

    ll = np.array([[-6.2610, 53.3510], [-6.2609, 53.3510], [-6.2609, 53.3511], [-6.2610, 53.3511]] * 2)
    path = write_gpkg(tmp_path / "local.gpkg", _docs(), ll, None)
    assert pyogrio.read_info(path)["crs"] == "EPSG:4326"


def test_polygon_wkb_is_a_closed_ring():
    wkb = polygon_wkb(np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0]]))
    assert wkb[:1] == b"\x01" and int.from_bytes(wkb[1:5], "little") == 3 and int.from_bytes(wkb[9:13], "little") == 4
    pts = np.frombuffer(wkb[13:], dtype="<f8").reshape(-1, 2)
    assert pts.tolist() == [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 0.0]]
