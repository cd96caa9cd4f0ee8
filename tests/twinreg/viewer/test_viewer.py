"""The offline viewer in a real browser: the system's headless Chromium (Debian package, driven by playwright-core)
opens `twinreg view` on the demo's twin with every non-loopback request refused, becomes ready with no console
error, and its screenshot shows each car in its model's colour where the car is; the server serves nothing
outside its folders."""

from __future__ import annotations

import json
import shutil
import subprocess
import urllib.error
import urllib.request
from pathlib import Path

import numpy as np
import pytest

from tests.conftest import keep_picture

from tests.twinreg.helpers import BIN, CHROMIUM, ROOT, chroma as _chroma, clean_env as _env


@pytest.fixture(scope="module")
def demo_twin(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("demo") / "demo"
    proc = subprocess.run([str(BIN / "twinreg"), "demo", "--out", str(out)], capture_output=True, text=True,
                          timeout=600, env=_env())
    assert proc.returncode == 0, proc.stderr
    assert f"twinreg view {out / 'twin'}" in proc.stdout  # the demo ends with the command that opens it
    return out / "twin"


@pytest.fixture()
def served(demo_twin):
    p = subprocess.Popen([str(BIN / "twinreg"), "view", str(demo_twin), "--port", "0", "--no-open"],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=_env())
    try:
        url = p.stdout.readline().strip()
        assert url.startswith("http://127.0.0.1:"), p.stderr.read()
        yield url
    finally:
        p.terminate()
        p.wait(timeout=30)


def test_the_viewer_shows_the_demo_cars_in_a_real_browser_offline(demo_twin, served):
    if not CHROMIUM.exists() or not (ROOT / "node_modules" / "playwright-core").is_dir():
        pytest.fail("chromium or the npm packages are missing: run `make install`")
    shot = demo_twin.parent / "viewer.png"
    proc = subprocess.run(["node", str(ROOT / "tests" / "js" / "shoot_viewer.mjs"), served, str(shot)],
                          capture_output=True, text=True, timeout=300, cwd=ROOT)
    assert proc.returncode == 0, proc.stderr
    got = json.loads(proc.stdout.strip().splitlines()[-1])
    assert got["ready"] and got["errors"] == [] and got["blocked"] == [], got
    twin = json.loads((demo_twin / "twin.json").read_text())
    assert got["stats"]["instances"] == len(twin["objects"]) and got["stats"]["scanPoints"] > 10_000
    # the kind filter lists the twin's kinds and draws exactly the objects of the kind chosen
    kinds = {o["kind"] for o in twin["objects"]}
    assert got["kinds"]["options"] == ["", *sorted(kinds, key=lambda k: -sum(o["kind"] == k for o in twin["objects"]))]
    for kind in kinds:
        assert sorted(got["kinds"]["shown"][kind]) == sorted(o["id"] for o in twin["objects"] if o["kind"] == kind)
    assert got["kinds"]["shown"]["no_such_kind"] == [] and len(got["kinds"]["shown"][""]) == len(twin["objects"])
    tiles = json.loads((demo_twin / "tiles" / "scan" / "tileset.json").read_text())
    assert tiles["root"]["refine"] == "ADD"
    assert got["ms"] < 30_000
    import matplotlib.image

    img = matplotlib.image.imread(str(shot))[..., :3] * 255.0
    h, w = img.shape[:2]
    shown = 0
    for car in got["cars"]:
        x, y = int(round(car["x"])), int(round(car["y"]))
        assert 0 <= x < w and 0 <= y < h, car  # every car is in the picture
        patch = img[max(y - 4, 0):y + 5, max(x - 4, 0):x + 5].reshape(-1, 3)
        want = _chroma([int(car["colour"][k:k + 2], 16) for k in (0, 2, 4)])
        near = np.linalg.norm(_chroma(patch) - want, axis=1) < 0.05
        shown += near.mean() >= 0.3
    assert shown >= 0.8 * len(got["cars"]), (shown, len(got["cars"]))
    # the click on the first car (nearest the camera among those drawn there) shows its record and sections
    first = got["cars"][0]["id"]
    assert got["clicked"]["text"].split("\n")[0].split()[-1] == first or first in got["clicked"]["text"]
    assert got["clicked"]["sections"] == 1
    model = got["found"]["model"]
    assert model and got["found"]["hits"] == sum(1 for o in twin["objects"] if o["match"]
                                                 and model.lower() in o["match"]["name"].lower())
    keep_picture(shot, "viewer_demo.png")


def test_the_scan_streams_by_level_of_detail(demo_twin, served):
    """On a small screen (where a screen-space error is small), the whole park needs only the coarse tiles;
    close to a car, denser tiles are requested and shown; back out, they are hidden."""
    proc = subprocess.run(["node", str(ROOT / "tests" / "js" / "shoot_viewer.mjs"), served,
                           str(demo_twin.parent / "small.png"), "480", "200", "zoom"],
                          capture_output=True, text=True, timeout=300, cwd=ROOT)
    assert proc.returncode == 0, proc.stderr
    got = json.loads(proc.stdout.strip().splitlines()[-1])
    assert got["ready"] and got["errors"] == [], got
    z = got["zoom"]
    assert z["near"]["scanRequests"] > z["start"]["scanRequests"], z
    assert z["near"]["scanPoints"] > 2 * z["start"]["scanPoints"] > 0, z
    assert z["far"]["scanPoints"] == z["start"]["scanPoints"], z
    twin = json.loads((demo_twin / "twin.json").read_text())
    assert twin["tiles"]["n_scan_points"] == twin["n_points"]  # every point of the scan is in the tiles


def test_the_server_serves_only_its_folders(demo_twin, served):
    with urllib.request.urlopen(served + "twin/twin.json") as r:
        assert json.loads(r.read())["objects"]
    with urllib.request.urlopen(served + "vendor/three/build/three.module.js") as r:
        assert r.status == 200
    for bad in ("twin/../../../../etc/passwd", "twin/%2e%2e/%2e%2e/etc/passwd", "nothing-here.js"):
        with pytest.raises(urllib.error.HTTPError) as e:
            urllib.request.urlopen(served + bad)
        assert e.value.code == 404


def test_view_refuses_a_folder_that_is_not_a_twin(tmp_path):
    proc = subprocess.run([str(BIN / "twinreg"), "view", str(tmp_path), "--no-open"], capture_output=True,
                          text=True, timeout=60, env=_env())
    assert proc.returncode == 1 and proc.stderr.startswith("error:") and str(tmp_path) in proc.stderr


XSS = '<img src=x onerror="window.__xss=1;document.title=\'pwned\'">'


@pytest.fixture()
def hostile_twin(demo_twin, tmp_path) -> Path:
    """The demo's twin as a stranger might share it: a model name, make and reason that are HTML."""
    folder = tmp_path / "hostile"
    shutil.copytree(demo_twin, folder)
    twin = json.loads((folder / "twin.json").read_text())
    matched = [o for o in twin["objects"] if o["match"]]
    for o in matched:
        o["match"]["name"] = XSS
        o["match"]["make"] = XSS
    for o in twin["objects"]:
        if not o["match"]:
            o["reason"] = XSS
    twin["scene"] = XSS
    (folder / "twin.json").write_text(json.dumps(twin))
    return folder


def test_names_from_a_twin_are_text_in_the_page_never_script(hostile_twin):
    """Stored XSS (issue 19): the names are shown as text, no script of theirs runs, the page sends a CSP."""
    if not CHROMIUM.exists() or not (ROOT / "node_modules" / "playwright-core").is_dir():
        pytest.fail("chromium or the npm packages are missing: run `make install`")
    from twinreg.viewer import serve

    server, url = serve(hostile_twin, 0)
    try:
        with urllib.request.urlopen(url) as r:
            csp = r.headers["Content-Security-Policy"]
        assert "script-src 'self'" in csp and "unsafe-inline" not in csp
        proc = subprocess.run(["node", str(ROOT / "tests" / "js" / "probe_xss.mjs"), url], capture_output=True,
                              text=True, timeout=300, cwd=ROOT)
    finally:
        server.shutdown()
    assert proc.returncode == 0, proc.stderr
    got = json.loads(proc.stdout.strip().splitlines()[-1])
    assert got["ready"] and not got["ran"], got
    assert "<img" in got["details"]  # shown, as text
    assert got["hits"] and all("<img" in h for h in got["hits"])
    assert got["errors"] == [] and got["blocked"] == [], got


def _get(url: str, host: str | None = None) -> int:
    req = urllib.request.Request(url, headers={"Host": host} if host else {})
    try:
        with urllib.request.urlopen(req, timeout=10) as r:
            return r.status
    except urllib.error.HTTPError as e:
        return e.code


def test_the_server_answers_only_local_hosts_lists_no_folder_and_drops_idle_sockets(demo_twin, monkeypatch):
    import socket
    import time

    from twinreg.viewer import server as srv

    monkeypatch.setattr(srv._Handler, "timeout", 1.0)
    server, url = srv.serve(demo_twin, 0)
    try:
        port = server.server_address[1]
        assert _get(url + "twin/twin.json") == 200
        assert _get(url + "twin/twin.json", host=f"localhost:{port}") == 200
        for host in ("evil.example", f"attacker.example:{port}", "127.0.0.1.evil.example"):
            assert _get(url + "twin/twin.json", host=host) == 421, host  # DNS rebinding reads nothing
        for folder in ("twin/", "twin/tiles/", "vendor/three/", "vendor/three/build/"):
            assert _get(url + folder) == 404, folder
        for bad in ("twin/%00", "twin/a%00b.json", "%2e%2e%2f%2e%2e%2fetc/passwd", "twin/..%5c..%5cetc"):
            assert _get(url + bad) in (400, 404), bad
        # an idle connection is closed by the server, not kept forever
        s = socket.create_connection(("127.0.0.1", port))
        s.settimeout(10)
        t0 = time.perf_counter()
        assert s.recv(10) == b""
        assert time.perf_counter() - t0 < 8
        s.close()
    finally:
        server.shutdown()


def test_a_bad_port_is_a_usage_error(demo_twin):
    for port in ("99999", "-1", "http"):
        proc = subprocess.run([str(BIN / "twinreg"), "view", str(demo_twin), "--port", port, "--no-open"],
                              capture_output=True, text=True, timeout=60, env=_env())
        assert proc.returncode == 2, (port, proc.stderr)
        assert "Traceback" not in proc.stderr and "OverflowError" not in proc.stderr


def test_planted_pages_and_scripts_in_a_twin_are_never_served(demo_twin, tmp_path):
    """A stranger's twin folder holding evil.html and evil.js: neither is served (the folder's files are data of
    the types the viewer reads), and its data comes with a policy under which nothing runs."""
    from twinreg.viewer import serve

    folder = tmp_path / "planted"
    shutil.copytree(demo_twin, folder)
    (folder / "evil.html").write_text('<script src="/twin/evil.js"></script>')
    (folder / "evil.js").write_text("window.__pwned = 1")
    (folder / "evil.svg").write_text('<svg xmlns="http://www.w3.org/2000/svg" onload="alert(1)"/>')
    (folder / "tiles" / "x.json.html").write_text("<script>alert(1)</script>")
    server, url = serve(folder, 0)
    try:
        for bad in ("twin/evil.html", "twin/evil.js", "twin/evil.svg", "twin/tiles/x.json.html", "twin/report.html"):
            assert _get(url + bad) == 404, bad
        for good, kind in (("twin/twin.json", "application/json"), ("twin/tiles/tileset.json", "application/json")):
            with urllib.request.urlopen(url + good) as r:
                assert r.headers["Content-Type"] == kind
                assert r.headers["Content-Security-Policy"] == "default-src 'none'; sandbox"
                assert r.headers["X-Content-Type-Options"] == "nosniff"
        with urllib.request.urlopen(url) as r:  # the viewer's own page keeps its own policy
            assert "script-src 'self'" in r.headers["Content-Security-Policy"]
    finally:
        server.shutdown()


def test_a_tileset_that_points_at_itself_is_read_once(demo_twin, tmp_path):
    """A stranger's tileset whose tile's content is the tileset itself (and a scan tileset that does the same): the
    viewer reads each once, becomes ready, and stops asking."""
    if not CHROMIUM.exists() or not (ROOT / "node_modules" / "playwright-core").is_dir():
        pytest.fail("chromium or the npm packages are missing: run `make install`")
    folder = tmp_path / "looped"
    shutil.copytree(demo_twin, folder)
    tileset = json.loads((folder / "tiles" / "tileset.json").read_text())
    box = tileset["root"]["boundingVolume"]
    loop = {"boundingVolume": box, "geometricError": 0, "content": {"uri": "tileset.json"}}
    tileset["root"].setdefault("children", []).append(loop)
    (folder / "tiles" / "tileset.json").write_text(json.dumps(tileset))
    scans = sorted((folder / "tiles").rglob("scan/*.json"))
    if scans:  # the scan's streamed tileset pointing at itself too
        scan = json.loads(scans[0].read_text())
        scan["root"].setdefault("children", []).append(loop | {"content": {"uri": scans[0].name}})
        scans[0].write_text(json.dumps(scan))
    from twinreg.viewer import serve

    server, url = serve(folder, 0)
    try:
        proc = subprocess.run(["node", str(ROOT / "tests" / "js" / "count_tilesets.mjs"), url], capture_output=True,
                              text=True, timeout=180, cwd=ROOT)
    finally:
        server.shutdown()
    assert proc.returncode == 0, proc.stderr
    got = json.loads(proc.stdout.strip().splitlines()[-1])
    assert got["ready"] and got["blocked"] == [], got
    assert got["tilesets"] and max(got["tilesets"].values()) <= 2, got  # once (a cached re-read at most)


def test_the_viewer_takes_three_js_only_from_its_own_checkout(monkeypatch):
    from twinreg.viewer.server import vendor_folder

    monkeypatch.delenv("TWINREG_NODE_MODULES", raising=False)
    assert vendor_folder() == ROOT / "node_modules"  # not the nearest node_modules further up
