"""The twin's open formats on a simulated car park of the shared cars: every GLB passes the Khronos glTF validator
and the instancing checks, the tileset's instances land within 1 cm of twin.json's lat/lon facing their bearing,
the CityJSON is valid against the 2.0 schema of what twinreg writes and loads in cjio, the GeoJSON footprints
surround each car's position."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from typer.testing import CliRunner

from tests.twinreg.helpers import (
    DUBLIN,
    cityjson_schema_valid,
    cjio_read,
    node_script as _node,
    string_column,
    tileset_instances as _instances,
)
from twinreg.cli import app
from twinreg.export.gltf import accessor_array, read_glb



def _glbs(out: Path) -> list[Path]:
    return sorted((out / "tiles").rglob("*.glb")) + [out / "twin.glb"]


def test_every_glb_passes_the_khronos_validator_and_the_instancing_checks(twin):  # noqa: F811
    doc, out = twin
    files = _glbs(out)
    assert len(files) >= 3  # a model tile, a scan tile, twin.glb
    reports = _node("validate_gltf.mjs", *map(str, files))
    assert len(reports) == len(files)
    for r in reports:
        assert r["errors"] == 0 and r["warnings"] == 0, r
    n_instances = 0
    for f in files:
        gltf, binary = read_glb(f.read_bytes())
        tables = gltf.get("extensions", {}).get("EXT_structural_metadata", {}).get("propertyTables", [])
        for node in gltf.get("nodes", []):
            inst = node.get("extensions", {}).get("EXT_mesh_gpu_instancing")
            if not inst:
                continue
            arrays = {k: accessor_array(gltf, binary, a) for k, a in inst["attributes"].items()}
            counts = {len(a) for a in arrays.values()}
            assert len(counts) == 1, f"{f.name}: instancing accessors of unequal counts {counts}"
            for a in arrays.values():
                assert np.isfinite(a).all()
            q = arrays["ROTATION"]
            assert np.allclose(np.linalg.norm(q, axis=1), 1.0, atol=1e-6)
            ids = arrays["_FEATURE_ID_0"]
            assert ids.max() < tables[0]["count"] and len(node["extras"]["ids"]) == len(ids)
            assert len(gltf["meshes"][node["mesh"]]["primitives"]) == 1  # each model flattened to one mesh
            if f.parent.name == "cells":
                n_instances += len(ids)
                # each instance's feature row names the object and its kind as twin.json does
                names = string_column(gltf, binary, tables[0], "id")
                kinds = string_column(gltf, binary, tables[0], "kind")
                by_id = {o["id"]: o["kind"] for o in doc["objects"]}
                assert all(by_id[names[int(i)]] == kinds[int(i)] for i in ids)
    assert n_instances == len(doc["objects"])  # every object once in the tiles


def test_instances_land_within_a_centimetre_of_twin_json_facing_their_bearing(twin):  # noqa: F811
    from pyproj import Transformer

    doc, out = twin
    found = _instances(out)
    assert set(found) == {o["id"] for o in doc["objects"]}
    to_geo = Transformer.from_crs("EPSG:4978", "EPSG:4979", always_xy=True)
    geod_err, bearing_err = [], []
    for o in doc["objects"]:
        p, d = found[o["id"]]
        lon, lat, _ = to_geo.transform(*p)
        dn = (lat - o["lat"]) * 111_320.0
        de = (lon - o["lon"]) * 111_320.0 * np.cos(np.radians(lat))
        geod_err.append(np.hypot(dn, de))
        la, lo = np.radians(lat), np.radians(lon)
        east = np.array([-np.sin(lo), np.cos(lo), 0.0])
        north = np.array([-np.sin(la) * np.cos(lo), -np.sin(la) * np.sin(lo), np.cos(la)])
        b = np.degrees(np.arctan2(d @ east, d @ north)) % 360
        bearing_err.append(abs((b - o["bearing_deg"] + 180) % 360 - 180))
    assert max(geod_err) < 0.01, max(geod_err)
    assert max(bearing_err) < 0.05, max(bearing_err)


def test_a_car_facing_east_is_drawn_facing_east(catalogue16, tmp_path):
    from tests.conftest import catalogue_models
    from twinreg.io.ply import write_ply
    from twinreg.sim.scan import _ground_mesh, pose_matrix, scan_meshes, transform

    v, f, g = catalogue_models(catalogue16, ["generic_sedan_chrono"])[0]
    scan = scan_meshes([(transform(v, pose_matrix(0, 0, 0.0)), f, g), _ground_mesh(-8, 8, -8, 8)], seed=1)
    write_ply(tmp_path / "east.ply", scan.points)
    res = CliRunner().invoke(app, ["build-twin", str(tmp_path / "east.ply"), *DUBLIN, "--library",
                                   str(catalogue16.folder), "--out", str(tmp_path / "out")])
    assert res.exit_code == 0, res.output
    (p, d), = _instances(tmp_path / "out").values()
    lon = np.radians(-6.261601)
    east = np.array([-np.sin(lon), np.cos(lon), 0.0])
    assert d @ east > np.cos(np.radians(2.0))
    # twin.glb (the local frame, Y-up): the same car's front is +X (east), its roof up (+Y)
    gltf, binary = read_glb((tmp_path / "out" / "twin.glb").read_bytes())
    node = gltf["nodes"][0]
    q = accessor_array(gltf, binary, node["extensions"]["EXT_mesh_gpu_instancing"]["attributes"]["ROTATION"])[0]
    assert abs(q[1]) < np.sin(np.radians(1.0)) and q[3] > 0.99
    assert "origin" in gltf["asset"]["extras"]


def _explicit_vertices(cj: dict, oid: str) -> np.ndarray:
    scale, translate = np.array(cj["transform"]["scale"]), np.array(cj["transform"]["translate"])
    geometry = cj["CityObjects"][oid]["geometry"][0]
    assert geometry["type"] == "MultiSurface"
    idx = np.unique(np.array([i for surface in geometry["boundaries"] for ring in surface for i in ring]))
    return np.array(cj["vertices"])[idx] * scale + translate


def _template_vertices(cj: dict, oid: str) -> np.ndarray:
    scale, translate = np.array(cj["transform"]["scale"]), np.array(cj["transform"]["translate"])
    gi = cj["CityObjects"][oid]["geometry"][0]
    assert gi["type"] == "GeometryInstance"
    m = np.array(gi["transformationMatrix"]).reshape(4, 4)  # row-major
    assert np.allclose(m[3], [0, 0, 0, 1]) and np.allclose(m[:3, 3], 0)
    ref = np.array(cj["vertices"][gi["boundaries"][0]]) * scale + translate
    t = cj["geometry-templates"]["templates"][gi["template"]]
    idx = np.unique(np.array([i for surface in t["boundaries"] for ring in surface for i in ring]))
    return np.array(cj["geometry-templates"]["vertices-templates"])[idx] @ m[:3, :3].T + ref


def test_cityjson_is_valid_and_places_each_car_at_its_centroid(twin):  # noqa: F811
    doc, out = twin
    cj = json.loads((out / "twin.city.json").read_text())
    cityjson_schema_valid(cj)
    version, n, epsg = cjio_read(out / "twin.city.json")
    assert version == "2.0" and n == len(doc["objects"]) and (epsg is None or epsg > 0)
    assert "geometry-templates" not in cj  # explicit geometry by default: every viewer draws it
    for o in doc["objects"]:
        co = cj["CityObjects"][o["id"]]
        assert co["type"] == "CityFurniture" and co["attributes"]["function"] == "vehicle"
        world = _explicit_vertices(cj, o["id"])
        centre = (world[:, :2].min(0) + world[:, :2].max(0)) / 2
        # the model's footprint centre lands on the object's centroid (the placed footprint's centre)
        assert np.hypot(*(centre - o["centroid"][:2])) < 0.15


def test_cityjson_templates_on_request_place_the_same_geometry(twin, park, catalogue16, tmp_path):  # noqa: F811
    doc, out = twin
    res = CliRunner().invoke(app, ["build-twin", str(park["path"]), *DUBLIN, "--anchor", str(park["offset"][0]),
                                   str(park["offset"][1]), "--library", str(catalogue16.folder), "--out",
                                   str(tmp_path / "t"), "--cityjson-templates"])
    assert res.exit_code == 0, res.output
    cj_t = json.loads((tmp_path / "t" / "twin.city.json").read_text())
    cj_e = json.loads((out / "twin.city.json").read_text())
    cityjson_schema_valid(cj_t)
    assert cjio_read(tmp_path / "t" / "twin.city.json")[1] == len(doc["objects"])
    assert len(cj_t["geometry-templates"]["templates"]) <= len(doc["objects"])
    for o in doc["objects"]:
        explicit, placed = _explicit_vertices(cj_e, o["id"]), _template_vertices(cj_t, o["id"])
        # the same mesh: each explicit vertex is a template vertex placed by its matrix, within 1 mm
        assert explicit.shape == placed.shape
        from scipy.spatial import cKDTree

        d, _ = cKDTree(placed).query(explicit)
        assert d.max() < 0.001, (o["id"], d.max())
        assert cj_t["CityObjects"][o["id"]]["attributes"] == cj_e["CityObjects"][o["id"]]["attributes"]


def test_city_cityjson_seq_reads_a_feature_a_line(city_twin, small_city):
    root, _ = small_city
    lines = (root / "out" / "twin.city.jsonl").read_text().splitlines()
    head, features = json.loads(lines[0]), [json.loads(x) for x in lines[1:]]
    assert head["type"] == "CityJSON" and head["CityObjects"] == {} and head["vertices"] == []
    assert [f["id"] for f in features] == [o["id"] for o in city_twin["objects"]]
    whole = json.loads((root / "out" / "twin.city.json").read_text())
    assert "geometry-templates" in whole  # a city's file: templates; its sequence: the explicit geometry
    from scipy.spatial import cKDTree

    for f in features:
        assert f["type"] == "CityJSONFeature" and list(f["CityObjects"]) == [f["id"]]
        mine = np.array(f["vertices"]) * head["transform"]["scale"] + head["transform"]["translate"]
        d, _ = cKDTree(_template_vertices(whole, f["id"])).query(mine)
        assert d.max() < 0.001
        # its faces are its model's (the template's, indices from the feature's own first vertex)
        gi = whole["CityObjects"][f["id"]]["geometry"][0]
        faces = np.array(whole["geometry-templates"]["templates"][gi["template"]]["boundaries"])
        mine_faces = np.array(f["CityObjects"][f["id"]]["geometry"][0]["boundaries"])
        assert mine_faces.shape == faces.shape and len(np.unique(faces - mine_faces)) == 1
        assert mine_faces.min() >= 0 and mine_faces.max() < len(f["vertices"])
    version, n, _ = cjio_read(root / "out" / "twin.city.jsonl", stdin=True)
    assert version == "2.0" and n == len(features)


def test_geojson_footprints_surround_each_car(twin):  # noqa: F811
    doc, out = twin
    gj = json.loads((out / "twin.geojson").read_text())
    assert gj["type"] == "FeatureCollection" and len(gj["features"]) == len(doc["objects"])
    by_id = {o["id"]: o for o in doc["objects"]}
    for feat in gj["features"]:
        ring = np.array(feat["geometry"]["coordinates"][0])
        assert feat["geometry"]["type"] == "Polygon" and (ring[0] == ring[-1]).all() and len(ring) == 5
        x, y = ring[:-1, 0], ring[:-1, 1]
        assert np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y) > 0  # counter-clockwise (RFC 7946)
        o = by_id[feat["id"]]
        c = ring[:-1].mean(0)
        assert abs(c[0] - o["lon"]) * 111_320 * np.cos(np.radians(o["lat"])) < 0.2
        assert abs(c[1] - o["lat"]) * 111_320 < 0.2
        assert feat["properties"]["model"] == (o["match"]["name"] if o["match"] else None)


def test_a_placed_models_footprint_is_that_of_its_placed_mesh(catalogue16):
    """The footprint rectangle comes from the model's plan hull placed (a city's objects keep no placed vertices):
    the same rectangle as from every vertex of the placed mesh, for each shared car in several poses."""
    from cosco.footprint import min_area_rectangle
    from twinreg.matching.cache import ModelCache

    models = ModelCache(catalogue16)
    rows = catalogue16.list()
    models.add_rows(rows)
    rng = np.random.default_rng(3)
    for r in rows:
        v = np.asarray(models.mesh(r.id)[0], dtype=np.float64)
        outline = models.outline(r.id)
        assert 3 <= len(outline) < len(v)
        for a in rng.uniform(0, 2 * np.pi, 3):
            m = np.eye(4)
            m[:2, :2] = [[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]]
            m[:3, 3] = rng.uniform(-500, 500, 3)
            whole = min_area_rectangle((v @ m[:3, :3].T + m[:3, 3])[:, :2])
            hull = min_area_rectangle((outline @ m[:3, :3].T + m[:3, 3])[:, :2])
            assert np.allclose(hull.corners(), whole.corners(), atol=1e-9)
