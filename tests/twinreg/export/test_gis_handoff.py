"""The twin where GIS users open it, on real scans: Autzen (international feet, Oregon Lambert stated in the LAS
header as a WKT without a code) and an AHN tile of Amsterdam given as RD New with NAP heights. twin.ply is read by
open3d and by CloudCompare (Debian's package, headless) with its vertices where scan.copc.laz's points are, in
the same units; twin.city.json loads in cjio and passes the CityJSON 2.0 schema with the right referenceSystem and
the extent of its geometry; twin.gpkg is read back (pyogrio) in the scan's CRS with srs_id 2994 or 7415; every
GeoJSON feature has the same properties."""

from __future__ import annotations

import json
import os
import shutil
import sqlite3
import subprocess

import numpy as np
import pytest
from typer.testing import CliRunner

from tests.conftest import SHARED_DATA, need
from twinreg.cli import app

CLOUDCOMPARE = shutil.which("CloudCompare")
SCANS = {"autzen": (SHARED_DATA / "autzen_parking" / "autzen_parking_north.las", [], "EPSG:2994", 2994),
         "ahn": (SHARED_DATA / "ahn_amsterdam" / "ahn_2397_9705.laz",
                 ["--crs", "EPSG:28992", "--vertical-crs", "EPSG:5709"], "EPSG:7415", 7415)}


@pytest.fixture(scope="module", params=sorted(SCANS))
def real_twin(request, catalogue16, tmp_path_factory):
    scan, args, code, srs = SCANS[request.param]
    out = tmp_path_factory.mktemp(request.param) / "twin"
    r = CliRunner().invoke(app, ["build-twin", str(need(scan)), *args, "--library", str(catalogue16.folder),
                                 "--out", str(out), "--json"])
    assert r.exit_code == 0, r.output
    return request.param, out, json.loads((out / "twin.json").read_text()), code, srs


def _scan_bounds(out):
    import laspy

    with laspy.open(out / "scan.copc.laz") as f:
        return np.asarray(f.header.mins), np.asarray(f.header.maxs)


def _inside(v, lo, hi, margin=10.0):
    """Every vertex within the scan's bounds, allowing an object cut by the scan's edge ``margin`` units past it
    (a twin in metres over a scan in feet would be off by a factor of 3.28: hundreds of metres here). An object cut
    by the edge is drawn whole (its model, or its type's fused shape, seen from its members): on Autzen a car whose
    points reach the scan's edge has its box corner 2 ft past it and its fused shape 3.2 ft."""
    return bool(((v >= lo - margin) & (v <= hi + margin)).all())


def test_twin_ply_overlays_the_scan_in_open3d(real_twin):
    from twinreg.o3d import load

    name, out, doc, code, _ = real_twin
    header = (out / "twin.ply").read_bytes().split(b"end_header")[0].decode()
    assert max(len(line) for line in header.splitlines()) <= 120
    assert f"comment crs {code.split('+')[0] if name == 'autzen' else 'EPSG:28992'}" in header
    mesh = load().io.read_triangle_mesh(str(out / "twin.ply"))
    v = np.asarray(mesh.vertices)
    assert len(v) > 1000 and len(mesh.triangles) > 1000
    lo, hi = _scan_bounds(out)
    assert _inside(v, lo, hi), (v.min(0), v.max(0), lo, hi)
    # each object's stated position (CRS units) is under its placed mesh
    unit = doc["georef"]["crs_unit_m"]
    for o in doc["objects"]:
        assert np.allclose(np.array(o["position_crs"][:2]) * unit, o["centroid"][:2], atol=1e-6)
    assert (out / "twin.prj").read_text().startswith(("PROJCS", "COMPD_CS", "PROJCRS"))


@pytest.mark.skipif(CLOUDCOMPARE is None and os.environ.get("TWINREG_REQUIRE_SHARED_DATA") != "1",
                    reason="CloudCompare is not installed (make test installs it)")
def test_twin_ply_opens_in_cloudcompare_where_the_scan_is(real_twin, tmp_path):
    """CloudCompare reads twin.ply (shifting its large coordinates itself) and saves the mesh back at the same
    place, inside the scan's bounds."""
    from twinreg.io.points import read_points

    assert CLOUDCOMPARE, "CloudCompare is missing: run `make test` (it installs Debian's cloudcompare)"
    _, out, _, _, _ = real_twin
    shutil.copy(out / "twin.ply", tmp_path / "twin.ply")
    proc = subprocess.run([CLOUDCOMPARE, "-SILENT", "-O", "-GLOBAL_SHIFT", "AUTO", "twin.ply", "-M_EXPORT_FMT",
                           "PLY", "-SAVE_MESHES"], cwd=tmp_path, capture_output=True, text=True, timeout=300,
                          env={**os.environ, "QT_QPA_PLATFORM": "offscreen"})
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    assert "loaded successfully" in proc.stdout
    saved = [p for p in tmp_path.glob("twin_*.ply")]
    assert len(saved) == 1, proc.stdout[-2000:]
    ours, theirs = read_points(tmp_path / "twin.ply").points, read_points(saved[0]).points
    assert theirs.shape == ours.shape and np.abs(theirs - ours).max() < 0.001
    lo, hi = _scan_bounds(out)
    assert _inside(theirs, lo, hi)


def test_cityjson_states_its_crs_and_the_extent_of_its_geometry(real_twin):
    import jsonschema

    from tests.conftest import REPO

    name, out, doc, code, srs = real_twin
    cj = json.loads((out / "twin.city.json").read_text())
    jsonschema.validate(cj, json.loads((REPO / "docs" / "schemas" / "cityjson-2.0-twin.schema.json").read_text()))
    assert cj["metadata"]["referenceSystem"] == f"https://www.opengis.net/def/crs/EPSG/0/{srs}"
    v = np.array(cj["vertices"], dtype=np.float64) * cj["transform"]["scale"] + cj["transform"]["translate"]
    ext = np.array(cj["metadata"]["geographicalExtent"])
    assert np.allclose(ext, [*v.min(0), *v.max(0)], atol=0.001), (ext, v.min(0), v.max(0))
    assert ext[5] - ext[2] > 1.0  # the cars' heights, not their centroids'
    lo, hi = _scan_bounds(out)
    assert _inside(v, lo, hi)
    code_py = ("import sys, json; from cjio import cityjson; c = cityjson.reader(file=open(sys.argv[1])); "
               "print(json.dumps([c.get_version(), len(c.j['CityObjects']), c.get_epsg()]))")
    proc = subprocess.run([os.sys.executable, "-c", code_py, str(out / "twin.city.json")], capture_output=True,
                          text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert json.loads(proc.stdout) == ["2.0", len(doc["objects"]), srs]


def test_geopackage_reads_back_in_the_scans_crs(real_twin):
    import pyogrio

    name, out, doc, code, srs = real_twin
    info = pyogrio.read_info(out / "twin.gpkg")
    assert info["crs"] == f"EPSG:{srs}" and info["features"] == len(doc["objects"])
    assert info["geometry_type"] == "Polygon"
    with sqlite3.connect(out / "twin.gpkg") as con:
        assert con.execute("select srs_id from gpkg_geometry_columns").fetchall() == [(srs,)]
    meta, _, geometry, fields = pyogrio.raw.read(out / "twin.gpkg")
    props = dict(zip(meta["fields"], fields))
    geo = json.loads((out / "twin.geojson").read_text())
    from twinreg.export.gpkg import METRE_FIELDS, unit_name

    # the GeoJSON's properties, sizes named in metres, and the unit of x, y, z (Autzen's feet) said in a column
    assert list(meta["fields"]) == [f"{n}_m" if n in METRE_FIELDS else n
                                    for n in geo["features"][0]["properties"]] + ["xyz_unit"]
    assert set(props["xyz_unit"]) == {unit_name(doc["georef"]["crs_unit_m"])}
    assert list(props["id"]) == [o["id"] for o in doc["objects"]]
    assert list(props["matched"]) == [o["match"] is not None for o in doc["objects"]]
    lo, hi = _scan_bounds(out)
    for k, o in enumerate(doc["objects"]):  # each footprint (CRS units) around the object's stated position
        ring = np.frombuffer(geometry[k][13:], dtype="<f8").reshape(-1, 2)
        assert _inside(np.c_[ring, np.full(len(ring), lo[2])], lo, hi)
        assert np.abs(ring[:-1].mean(0) - o["position_crs"][:2]).max() < 2.0 / doc["georef"]["crs_unit_m"]


def test_geojson_features_share_their_keys(real_twin):
    from twinreg.matching.match import REASON_CODES

    _, out, doc, _, _ = real_twin
    feats = json.loads((out / "twin.geojson").read_text())["features"]
    keys = {tuple(f["properties"]) for f in feats}
    assert len(keys) == 1 and {"kind", "matched", "reason_code", "model", "x", "y", "z"} <= set(next(iter(keys)))
    for f, o in zip(feats, doc["objects"]):
        p = f["properties"]
        assert p["matched"] is (o["match"] is not None)
        # a model's category when matched; else the kind recognised from the nearest references (the catalogue
        # holds cars only: a car, or unknown when none fits, or what every scan holds, vegetation and structure),
        # with its confidence and the object's type
        assert p["kind"] == o["kind"] and p["kind"] in (("car",) if o["match"] else
                                                         ("car", "unknown", "vegetation", "structure"))
        assert p["type"] == o["type"] and p["symmetry_level"] == o["symmetry"]["level"]
        assert p["shape_source"] == o["shape"]["source"] and (p["shape_source"] == "model") == bool(o["match"])
        assert (p["reason_code"] in REASON_CODES) if not p["matched"] else p["reason_code"] is None
        assert "match_name" not in p and "match_model" not in p
