"""build-twin end to end on a simulated car park of the shared cars, and the KMZ read back."""

import io
import xml.etree.ElementTree as ET
import zipfile
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from tests.conftest import catalogue_models
from tests.twinreg.helpers import DUBLIN
from twinreg.cli import app
from twinreg.io.ply import write_ply

KML = "{http://www.opengis.net/kml/2.2}"


def _truth(park, obj):
    c = np.array(obj["centroid"][:2]) - park["offset"][:2]
    d = [np.hypot(*(c - [car.x, car.y])) for car in park["scene"].cars]
    k = int(np.argmin(d))
    return park["scene"].cars[k], d[k]


def test_every_car_matched_to_its_own_model_in_place(park, twin):
    doc, _ = twin
    objs = doc["objects"]
    assert len(objs) == 12
    right = 0
    seen = set()
    for o in objs:
        car, dist = _truth(park, o)
        seen.add(id(car))
        assert o["match"] is not None
        right += o["match"]["name"] == park["names"][car.model]
        assert dist < 0.15, (o["id"], dist)
        err = np.degrees(np.angle(np.exp(1j * (o["heading_rad"] - car.heading))))
        assert abs(err) < 3.0, (o["id"], err)
    assert right >= 11
    assert len(seen) == 12  # every car once, no distractor in the list
    assert doc["matching"]["n_trials"] < doc["matching"]["n_pairs_without_prefilter"]
    for o in objs:  # every match was verified against all of the object's points
        v = o["match"]["verification"]
        assert v["accepted"] and v["outlier_share"] <= 0.10 and 0.05 < v["tolerance_m"] < 0.2


def test_matches_say_how_sure_they_are(park, twin):
    """The contract's confidence, ambiguous_with and outside_tolerance, in twin.json, the report and the KMZ."""
    doc, out = twin
    names = set(park["names"])
    for o in doc["objects"]:
        m = o["match"]
        assert 0.0 <= m["confidence"] <= 1.0 and m["margin_sigma"] >= 0.0
        assert set(m["ambiguous_with"]) <= names - {m["name"]}
        assert m["outside_tolerance"] is False  # every car of this park is inside the size window
        assert m["evidence"]["score_m"] <= m["runner_up"]["score_m"]
        assert o["measured_size"]["length"] > 0
    # a margin of many noise units is a confident match: most cars of this dense park are
    assert np.mean([o["match"]["confidence"] >= 0.9 for o in doc["objects"]]) >= 0.75
    report = (out / "report.html").read_text()
    assert "<th>confidence</th>" in report and "<th>ambiguous with</th>" in report
    kml = zipfile.ZipFile(out / "twin.kmz").read("doc.kml").decode()
    assert kml.count('<Data name="confidence">') == len(doc["objects"])


def test_kmz_reads_back(park, twin):
    import collada

    doc, out = twin
    z = zipfile.ZipFile(out / "twin.kmz")
    assert z.namelist()[0] == "doc.kml"
    root = ET.fromstring(z.read("doc.kml"))
    marks = root.findall(f".//{KML}Placemark")
    assert len(marks) == len(doc["objects"])
    names = set(z.namelist())
    for pm, obj in zip(marks, doc["objects"]):
        model = pm.find(f"{KML}Model")
        assert model.find(f"{KML}altitudeMode").text == "clampToGround"
        href = model.find(f"{KML}Link/{KML}href").text
        assert href in names
        dae = collada.Collada(io.BytesIO(z.read(href)))
        assert dae.assetInfo.upaxis == "Z_UP" and dae.assetInfo.unitmeter == 1.0
        n_tri = sum(len(p) for g in dae.geometries for p in g.primitives)
        assert 0 < n_tri <= 21845
        lat = float(model.find(f"{KML}Location/{KML}latitude").text)
        lon = float(model.find(f"{KML}Location/{KML}longitude").text)
        assert abs(lat - obj["lat"]) < 1e-7 and abs(lon - obj["lon"]) < 1e-7
        # the scene's +X is east at the anchor: heading (clockwise from north) = 90 - the scene angle
        car, _ = _truth(park, obj)
        heading = float(model.find(f"{KML}Orientation/{KML}heading").text)
        expect = (90.0 - np.degrees(car.heading)) % 360
        assert abs((heading - expect + 180) % 360 - 180) < 3.0
        data = {d.get("name"): d.find(f"{KML}value").text for d in pm.findall(f".//{KML}Data")}
        assert data["model"] == obj["match"]["name"]
    # the anchor is at the Dublin car park
    lats = [o["lat"] for o in doc["objects"]]
    assert 53.3509 < min(lats) and max(lats) < 53.3515


def test_car_facing_east_has_heading_90(catalogue16, tmp_path):
    """One car, front towards +X (east): KML heading 90; the same car facing north: heading 0."""
    from twinreg.sim.scan import _ground_mesh, pose_matrix, scan_meshes, transform

    v, f, g = catalogue_models(catalogue16, ["generic_sedan_chrono"])[0]
    for scene_heading, expect in ((0.0, 90.0), (np.pi / 2, 0.0)):
        scan = scan_meshes([(transform(v, pose_matrix(0, 0, scene_heading)), f, g), _ground_mesh(-8, 8, -8, 8)],
                           seed=1)
        path = tmp_path / f"one_{expect:.0f}.ply"
        write_ply(path, scan.points)
        out = tmp_path / f"twin_{expect:.0f}"
        res = CliRunner().invoke(app, ["build-twin", str(path), *DUBLIN, "--library", str(catalogue16.folder),
                                       "--out", str(out), "--json"])
        assert res.exit_code == 0, res.output
        root = ET.fromstring(zipfile.ZipFile(out / "twin.kmz").read("doc.kml"))
        heading = float(root.find(f".//{KML}Orientation/{KML}heading").text)
        assert abs((heading - expect + 180) % 360 - 180) < 2.0, heading


def test_twin_ply_carries_offset_and_georef(twin):
    from twinreg.io.points import read_points

    doc, out = twin
    header = (out / "twin.ply").read_bytes().split(b"end_header")[0].decode()
    assert "comment offset" in header and "anchor_latlon 53.35116 -6.261601" in header
    offset = np.array([float(x) for x in header.split("comment offset ")[1].split()[:3]])
    pts = read_points(out / "twin.ply").points + offset
    centre = np.array([o["centroid"] for o in doc["objects"]])
    assert np.abs(pts[:, :2].mean(0) - centre[:, :2].mean(0)).max() < 1.0
    assert (out / "report.html").exists() and (out / "sections.svg").stat().st_size > 10_000


def _state(folder):
    return sorted((str(p.relative_to(folder)), p.read_bytes()) for p in folder.rglob("*") if p.is_file())


def test_bad_inputs_leave_nothing_half_written(tmp_path, park, catalogue16):
    runner = CliRunner()
    out = tmp_path / "out"

    def run(*args):
        return runner.invoke(app, ["build-twin", *map(str, args)])

    res = run(park["path"], *DUBLIN, "--library", catalogue16.folder, "--out", out)
    assert res.exit_code == 0, res.output
    before = _state(out)
    empty = tmp_path / "emptylib"
    res = run(park["path"], *DUBLIN, "--library", empty, "--out", out)
    assert res.exit_code == 1 and "error:" in res.output
    res = run(park["path"], "--lat", "95", "--lon", "0", "--library", catalogue16.folder, "--out", out)
    assert res.exit_code == 1 and "--lat 95" in res.output
    flat = tmp_path / "flat.xyz"
    g = np.random.default_rng(0).uniform(-10, 10, (5000, 3)) * [1, 1, 0]
    np.savetxt(flat, g)
    res = run(flat, *DUBLIN, "--library", catalogue16.folder, "--out", out)
    assert res.exit_code == 1 and "no car-sized objects" in res.output
    blocker = tmp_path / "file"
    blocker.write_text("x")
    res = run(park["path"], *DUBLIN, "--library", catalogue16.folder, "--out", blocker / "sub")
    assert res.exit_code == 1 and "error:" in res.output
    for bad in (("--tol", "-1"), ("--threshold", "-1"), ("--tol", "0")):
        res = run(park["path"], *DUBLIN, *bad, "--library", catalogue16.folder, "--out", out)
        assert res.exit_code == 2 and f"error: {bad[0]} " in res.output and "positive" in res.output
    assert _state(out) == before
    assert not [p for p in tmp_path.iterdir() if ".tmp-" in p.name]
    # a good run replaces the earlier twin (a folder twinreg wrote) as a whole
    res = run(park["path"], *DUBLIN, "--library", catalogue16.folder, "--out", out)
    assert res.exit_code == 0, res.output
    assert (out / "twin.kmz").exists() and (out / ".twinreg-output.json").exists()
    assert not [p for p in tmp_path.iterdir() if ".tmp-" in p.name or ".old-" in p.name or ".swap" in p.name]
    assert not [p for p in out.rglob(".tmp-*")]


def test_pictures_drawn_in_process_without_the_helper(park, catalogue16, tmp_path, monkeypatch):
    """Without the helper process (TWINREG_NO_HELPER=1, or a helper that cannot start) this process draws the
    same pictures, byte for byte, and no child process is started for them."""
    import psutil

    from twinreg.geo.georef import georef_from_options
    from twinreg.pipeline import build_twin

    georef = georef_from_options(53.35116, -6.261601)
    build_twin(park["path"], catalogue16, georef, tmp_path / "helper")
    monkeypatch.setenv("TWINREG_NO_HELPER", "1")
    before = {p.pid for p in psutil.Process().children(recursive=True)}
    started = []
    monkeypatch.setattr("multiprocessing.context.ForkProcess.start",
                        lambda self: started.append(self.name) or (_ for _ in ()).throw(OSError("no fork")))
    twin = build_twin(park["path"], catalogue16, georef, tmp_path / "here")
    assert len(twin["objects"]) == 12 and not started
    assert {p.pid for p in psutil.Process().children(recursive=True)} <= before
    for name in ("topview.svg", "heatmap.svg", "dendrogram.svg", "sections.svg", "confidence.svg"):
        assert (tmp_path / "helper" / name).read_bytes() == (tmp_path / "here" / name).read_bytes(), name
    page = (tmp_path / "here" / "report.html").read_text()
    assert all(f"src='{name}'" in page for name in ("topview.svg", "sections.svg", "confidence.svg"))
    # the records' formats and the scan's files, written by forked children with the helpers, the same written here
    for name in ("twin.city.json", "twin.geojson", "sections.json"):
        assert (tmp_path / "helper" / name).read_bytes() == (tmp_path / "here" / name).read_bytes(), name
    import laspy

    a, b = (laspy.read(tmp_path / out / "scan.copc.laz") for out in ("helper", "here"))
    assert len(a.points) == len(b.points) == len(park["scene"].points)
    assert np.array_equal(a.classification, b.classification) and np.array_equal(a.x, b.x)
    with np.load(tmp_path / "helper" / "observed.npz") as x, np.load(tmp_path / "here" / "observed.npz") as y:
        assert sorted(x.files) == sorted(y.files)
        assert all(np.array_equal(x[k], y[k], equal_nan=x[k].dtype.kind == "f") for k in x.files)


MAIN_PID = __import__("os").getpid()


def hang_in_helper(*args):
    """Stands for a drawing call that hangs in the helper process (and draws normally in the main one)."""
    import os
    import time

    from twinreg.report import scene as report

    if os.getpid() != MAIN_PID:
        time.sleep(3600)
    return report.write_report(*args)


def _children(ignore=()):
    """Live child processes of this one, but for ``ignore`` (pids there before: e.g. the resource tracker a Dask
    cluster of an earlier test started, which lives as long as this process)."""
    import psutil

    return [c for c in psutil.Process().children(recursive=True)
            if c.is_running() and c.status() != "zombie" and c.pid not in ignore]


@pytest.mark.timeout(300)
def test_a_stuck_helper_does_not_hang_build_twin(park, catalogue16, tmp_path, monkeypatch):
    from twinreg import pipeline
    from twinreg.errors import ExportError
    from twinreg.geo.georef import georef_from_options

    monkeypatch.setattr(pipeline, "write_report", hang_in_helper)
    monkeypatch.setattr(pipeline, "HELPER_TIMEOUT_S", 3.0)
    earlier = {c.pid for c in _children()}
    georef = georef_from_options(53.35116, -6.261601)
    twin = pipeline.build_twin(park["path"], catalogue16, georef, tmp_path / "out")
    assert len(twin["objects"]) == 12
    for name in ("topview.svg", "sections.svg", "report.html"):  # drawn here when the helper was stuck
        assert (tmp_path / "out" / name).stat().st_size > 1000
    assert not list((tmp_path / "out").rglob(".tmp-*"))
    assert _children(earlier) == []  # the helper was stopped, not left behind

    # an export error while the helper is stuck: the error comes out at once, nothing is left behind
    def broken_tiles(*args, **kwargs):
        raise ExportError("disk full (simulated)")

    monkeypatch.setattr("twinreg.export.formats.write_tiles", broken_tiles)
    before = sorted(p.name for p in (tmp_path / "out").iterdir())
    with pytest.raises(ExportError, match="disk full"):
        pipeline.build_twin(park["path"], catalogue16, georef, tmp_path / "out")
    assert _children(earlier) == []
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]


def test_two_runs_on_one_out_one_succeeds_one_is_refused(park, catalogue16, tmp_path):
    import subprocess
    import sys
    import time

    out = tmp_path / "out"
    cmd = [str(Path(sys.executable).parent / "twinreg"), "--library", str(catalogue16.folder), "build-twin",
           str(park["path"]), *DUBLIN, "--anchor", str(park["offset"][0]), str(park["offset"][1]), "--out", str(out)]
    first = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    try:
        t = time.monotonic()
        while not (tmp_path / ".out.lock").exists() and time.monotonic() - t < 60:
            time.sleep(0.05)
        second = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
        assert second.returncode == 1
        line = second.stderr.strip()
        assert line.startswith("error:") and "\n" not in line, line
        assert f"another twinreg run is writing this folder (process {first.pid}, twinreg build-twin" in line, line
        assert first.wait(300) == 0, first.stderr.read()
    finally:
        first.kill()
    assert (out / "twin.json").is_file() and not (tmp_path / ".out.lock").exists()
