"""build-twin on tiles: the same twin as the merged scene, every car once, resumable after Ctrl-C or a kill, the
same on an external Dask cluster, and COPC tiles read by bounds give the same twin as plain LAZ."""

from __future__ import annotations

from collections import Counter

import json
import os
import signal
import subprocess
import sys
import time
import zipfile
from pathlib import Path

import numpy as np
import pytest

from tests.conftest import CELL

BIN = Path(sys.executable).parent


def _merged(folder: Path, dst: Path) -> Path:
    import laspy

    from twinreg.sim.city import write_laz

    pts = []
    for f in sorted(folder.glob("*.laz")):
        las = laspy.read(f)
        pts.append(np.column_stack([las.x, las.y, las.z]))
    write_laz(dst, np.vstack(pts), "EPSG:28992")
    return dst


def _strip(twin: dict) -> dict:
    """twin.json without what may change from run to run (timings, the reused-cell count, worker sums)."""
    t = json.loads(json.dumps(twin))
    t.pop("timing_s"), t.pop("classified_scan", None)
    t["grid"].pop("n_cells_reused")
    t["matching"].pop("worker_s"), t["matching"].pop("registration_ms_per_trial")
    for c in t["cells"]:
        c.pop("timing_s")
    return t


def test_tiles_give_the_merged_scenes_twin_with_every_car_once(small_city, city_twin, parametric_catalogue,
                                                               tmp_path):
    from scipy.spatial import cKDTree

    from twinreg.pipeline import build_twin

    root, truth = small_city
    assert len(truth["tiles"]) == 4 and city_twin["grid"]["n_cells"] > 4
    merged = build_twin(_merged(root / "laz", tmp_path / "merged.laz"), parametric_catalogue, None, tmp_path / "m")
    a = sorted(merged["objects"], key=lambda o: o["centroid"][:2])
    b = sorted(city_twin["objects"], key=lambda o: o["centroid"][:2])
    assert len(a) == len(b) == len(truth["cars"])
    for x, y in zip(a, b):  # the same objects, points, matches and poses (ids aside)
        assert x["n_points"] == y["n_points"]
        assert np.allclose(x["centroid"], y["centroid"], atol=1e-6, rtol=0)
        assert abs(x["heading_rad"] - y["heading_rad"]) < 1e-6  # the pose refinement sums in point order
        assert (x["match"] or {}).get("name") == (y["match"] or {}).get("name")
        assert x["match"]["rmse_m"] == y["match"]["rmse_m"] and x["size"] == y["size"]
        assert np.allclose([x["lat"], x["lon"], x["bearing_deg"]], [y["lat"], y["lon"], y["bearing_deg"]],
                           rtol=0, atol=1e-9)
    # every car exactly once, those across seams too
    cars = np.array([[c["x"], c["y"]] for c in truth["cars"]])
    d, idx = cKDTree(cars).query(np.array([o["centroid"][:2] for o in b]))
    assert d.max() < 0.1 and len(set(idx)) == len(cars)
    names = [c["model"] for c in truth["cars"]]
    assert sum(o["match"]["name"] == names[i] for o, i in zip(b, idx)) >= 0.95 * len(cars)

    def straddles(step):  # cars across a seam of a grid of ``step`` metres (along x by length, along y by width)
        r = cars % step
        gap = np.minimum(r, step - r)
        return (gap[:, 0] < 1.8) | (gap[:, 1] < 0.8)

    assert straddles(40.0).sum() >= 10 and straddles(CELL).sum() >= 3  # across tile seams and cell seams
    # ids: cell and index, the same from run to run
    assert all(o["id"].startswith("c") and "-" in o["id"] for o in b)


def test_city_output_is_complete_and_clean(small_city, city_twin):
    root, _ = small_city
    out = root / "out"
    names = {p.name for p in out.iterdir()}
    assert {"twin.json", "twin.kmz", "report.html", "map.png", "histograms.png", "taxonomy.png"} <= names
    assert not [p for p in out.rglob("*") if p.name.startswith(".tmp-") or ".tmp-" in p.name]
    stored = sorted(p.name for p in (out / ".cells").iterdir() if p.is_file())
    assert len(stored) == city_twin["grid"]["n_cells"] and not (out / ".cells" / "split").exists()
    # each cell's scan tiles are kept beside its result (a rerun reuses both), and linked into tiles/scan
    kept = sorted(p.name for p in (out / ".cells" / "scan").iterdir())
    assert kept == sorted(n[:-4] for n in stored)
    assert city_twin["tiles"]["n_scan_points"] == city_twin["n_points"]  # every point of every cell
    with zipfile.ZipFile(out / "twin.kmz") as z:
        kml = z.read("doc.kml").decode()
    import xml.etree.ElementTree as ET

    ns = {"k": "http://www.opengis.net/kml/2.2"}
    root = ET.fromstring(kml)
    kinds = root.findall("k:Document/k:Folder", ns)  # a Folder a kind, each holding its cells' Regions
    assert sorted(f.find("k:name", ns).text for f in kinds) == sorted(
        f"{k} ({n})" for k, n in Counter(o["kind"] for o in city_twin["objects"]).items())
    folders = [f for f in root.findall(".//k:Folder", ns) if f.find("k:Region", ns) is not None]
    assert {f.find("k:name", ns).text for f in folders} == {c["name"] for c in city_twin["cells"] if c["n_objects"]}
    n_marks = 0
    for f in folders:
        box = {t: float(f.find(f"k:Region/k:LatLonAltBox/k:{t}", ns).text) for t in ("north", "south", "east",
                                                                                     "west")}
        for pm in f.findall("k:Placemark", ns):
            lat = float(pm.find(".//k:latitude", ns).text)
            lon = float(pm.find(".//k:longitude", ns).text)
            assert box["south"] <= lat <= box["north"] and box["west"] <= lon <= box["east"]
            n_marks += 1
    assert n_marks == len(city_twin["objects"])
    html = (out / "report.html").read_text()
    assert "map.png" in html and "taxonomy.png" in html and f"{len(city_twin['objects'])} objects" in html


def test_copc_tiles_read_by_bounds_give_the_same_twin(small_city, city_twin, parametric_catalogue):
    from twinreg.city.build import build_city_twin
    from twinreg.city.sources import open_sources

    root, _ = small_city
    assert all(s.copc for s in open_sources([root / "copc"]))
    twin = build_city_twin([root / "copc"], parametric_catalogue, None, root / "out_copc", cell=CELL, workers=2)
    assert "classified_scan" not in twin and not (root / "out_copc" / "classified").exists()  # not asked for
    a, b = _strip(city_twin), _strip(twin)
    for t in (a, b):
        t.pop("sources"), t.pop("scene"), t["georef"].pop("scan_centre")  # from the headers' bounds
        t.pop("survey_date"), t.pop("survey_date_source")  # the headers' dates: the COPC writer leaves it unset
    ga, gb = a.pop("georef"), b.pop("georef")
    assert (ga["crs"], gb["crs"]) == ("EPSG:7415", "EPSG:28992")
    assert ga["vertical_crs"] == "EPSG:5709" and ga["vertical_source"] == "file header"  # the LAZ tiles: RD New + NAP
    assert "RDNAPTRANS2018" in ga["height_transformation"] and gb["vertical_source"] is None
    ha, hb = a["tiles"]["origin"].pop("h"), b["tiles"]["origin"].pop("h")
    assert 40 < ha - hb < 46  # the tileset's origin: NAP to ellipsoidal in Amsterdam
    assert a == b
    # the same cars, higher on the ellipsoid where the heights are NAP: by the geoid's undulation at each car
    from tests.twinreg.helpers import tileset_heights as _heights, undulation as _undulation

    stated, flat = _heights(root / "out"), _heights(root / "out_copc")
    assert set(stated) == set(flat) == {o["id"] for o in twin["objects"]}
    for oid, (lon, lat, h) in stated.items():
        n = _undulation("nap", lon, lat)
        assert abs(n) > 20 and abs(h - flat[oid][2] - n) < 0.02, (oid, h, flat[oid][2], n)


def _cli(*args, **kw):
    return subprocess.Popen([str(BIN / "twinreg"), *map(str, args)], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, **kw)


def _finished(out: Path) -> list[Path]:
    """The cells a run has stored (not a result being written under a temporary name)."""
    return [p for p in (out / ".cells").glob("*.npz") if not p.name.startswith(".tmp")]


@pytest.mark.parametrize("stop", ["ctrl-c", "kill"])
def test_an_interrupted_run_resumes_with_the_same_twin(small_city, city_twin, parametric_catalogue, tmp_path, stop):
    root, _ = small_city
    out = tmp_path / "out"
    args = ["--library", parametric_catalogue.folder, "build-twin", root / "laz", "--cell", CELL, "--out", out,
            "--classified-scan", "--workers", "1", "--json"]
    # Ctrl-C as in a terminal (a shell's background job would inherit SIGINT ignored), or the whole process group
    # (the command, its Dask scheduler and workers) killed at once
    p = _cli(*args, start_new_session=True, preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and p.poll() is None:
        if len(_finished(out)) >= 2:
            break
        time.sleep(0.05)
    assert p.poll() is None, p.communicate()
    if stop == "ctrl-c":
        p.send_signal(signal.SIGINT)
    else:
        os.killpg(p.pid, signal.SIGKILL)
    p.communicate(timeout=60)
    assert p.returncode == (130 if stop == "ctrl-c" else -signal.SIGKILL)
    done = len(_finished(out))
    assert 2 <= done < city_twin["grid"]["n_cells"]
    assert not (out / "twin.json").exists()
    q = _cli(*args[:-3], "--workers", "2", "--json")  # the rerun on two workers: the same twin
    stdout, stderr = q.communicate(timeout=300)
    assert q.returncode == 0, stderr
    twin = json.loads(stdout)
    assert twin["grid"]["n_cells_reused"] == done
    assert _strip(twin) == _strip(city_twin)
    # the command's --classified-scan: the same classified files as the library's run, every one written
    assert twin["classified_scan"]["files"] == city_twin["classified_scan"]["files"]
    assert twin["classified_scan"]["n_points"] == city_twin["classified_scan"]["n_points"]
    assert all((out / f).is_file() for f in twin["classified_scan"]["files"])
    assert not [p for p in out.rglob("*") if ".tmp-" in p.name]


@pytest.fixture()
def dask_cluster(tmp_path):
    """A Dask scheduler and two workers as separate processes on 127.0.0.1."""
    sched_file = tmp_path / "scheduler.json"
    env = dict(os.environ)
    procs = [subprocess.Popen([sys.executable, "-m", "dask", "scheduler", "--host", "127.0.0.1", "--port", "0",
                               "--no-dashboard", "--scheduler-file", str(sched_file)], env=env,
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)]
    try:
        deadline = time.monotonic() + 60
        while not sched_file.exists() and time.monotonic() < deadline:
            time.sleep(0.1)
        address = json.loads(sched_file.read_text())["address"]
        for _ in range(2):
            procs.append(subprocess.Popen([sys.executable, "-m", "dask", "worker", address, "--nthreads", "1",
                                           "--no-dashboard", "--host", "127.0.0.1", "--memory-limit", "3GiB"],
                                          env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        from distributed import Client

        with Client(address, timeout=30) as c:
            c.wait_for_workers(2, timeout=60)
            assert len(c.scheduler_info()["workers"]) == 2
        yield address
    finally:
        for p in procs[::-1]:
            p.terminate()
        for p in procs:
            try:
                p.wait(timeout=20)
            except subprocess.TimeoutExpired:
                p.kill()


def test_an_existing_dask_cluster_gives_the_same_twin(small_city, city_twin, parametric_catalogue, tmp_path,
                                                      dask_cluster):
    root, _ = small_city
    p = _cli("--library", parametric_catalogue.folder, "build-twin", root / "laz", "--cell", CELL, "--out",
             tmp_path / "out", "--scheduler", dask_cluster, "--json")
    stdout, stderr = p.communicate(timeout=300)
    assert p.returncode == 0, stderr
    assert _strip(json.loads(stdout)) == _strip(city_twin)


def test_the_citys_formats_have_a_tile_per_cell_and_its_crs(small_city, city_twin):
    """The tiles of a city run: one model tile per cell holding objects and the scan's tileset beside them, every
    object once; CityJSON in the tiles' CRS (EPSG:28992) valid against the schema; GLBs valid."""
    import jsonschema

    from tests.twinreg.helpers import ROOT, node_script as _node, tileset_instances as _instances

    root, _ = small_city
    out = root / "out"
    ts = json.loads((out / "tiles" / "tileset.json").read_text())
    uris = [c["content"]["uri"] for c in ts["root"]["children"]]
    cells_with_objects = {c["name"] for c in city_twin["cells"] if c["n_objects"]}
    assert sorted(u for u in uris if u.endswith(".glb")) == sorted(f"cells/{n}.glb" for n in cells_with_objects)
    assert "scan/tileset.json" in uris and city_twin["tiles"]["n_scan_points"] > 100_000
    assert set(_instances(out)) == {o["id"] for o in city_twin["objects"]}
    cj = json.loads((out / "twin.city.json").read_text())
    jsonschema.validate(cj, json.loads((ROOT / "docs" / "schemas" / "cityjson-2.0-twin.schema.json").read_text()))
    assert cj["metadata"]["referenceSystem"].endswith("/EPSG/0/7415")  # RD New + NAP, as the tiles state
    for r in _node("validate_gltf.mjs", *map(str, sorted((out / "tiles").rglob("*.glb")))):
        assert r["errors"] == 0, r
