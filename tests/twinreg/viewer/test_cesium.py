"""CesiumJS itself (the npm package's bundle, served from 127.0.0.1, no ion, no imagery) opens a city twin's
tiles/tileset.json at its default detail in headless Chromium: framing the whole city it draws every cell's coarse
scan tile and the cars; at street level over a car it requests denser scan tiles and draws fewer points; back out,
it draws the coarse tiles again without requesting anything."""

from __future__ import annotations

import json
import subprocess

import pytest

from tests.conftest import keep_picture
from tests.twinreg.helpers import CHROMIUM, ROOT


def test_cesium_shows_the_scan_from_the_whole_city_to_street_level(small_city, city_twin):
    from tests.twinreg.helpers import tileset_heights as _heights

    if not CHROMIUM.exists() or not (ROOT / "node_modules" / "cesium").is_dir():
        pytest.fail("chromium or the npm packages are missing: run `make install`")
    root, _ = small_city
    out = root / "out"
    heights = _heights(out)
    car = sorted(heights)[len(heights) // 2]
    lon, lat, h = heights[car]
    shot = root / "cesium.png"
    proc = subprocess.run(["node", str(ROOT / "tests" / "js" / "cesium_scan.mjs"), str(out), str(shot), str(lon),
                           str(lat), str(h + 6.0)], capture_output=True, text=True, timeout=300, cwd=ROOT)
    assert proc.returncode == 0, proc.stderr
    got = json.loads(proc.stdout.strip().splitlines()[-1])
    assert got["failed"] is None and got["errors"] == [] and got["blocked"] == [], got
    city, street, again = (got["views"][k] for k in ("city", "street", "city_again"))
    cells = [p for p in (out / "tiles" / "scan").iterdir() if p.is_dir() and any(p.iterdir())]
    assert city["scan"] == len(cells) and city["levels"] == [0], city  # every cell's coarse tile, from afar
    assert city["cars"] == city_twin["tiles"]["n_tiles"]
    assert city["points"] > 0.15 * city_twin["n_points"], city
    assert street["scan"] > 0 and min(street["levels"]) >= 1, street  # denser tiles near the ground
    assert 0 < street["points"] < city["points"] and street["height"] < 60, street
    assert again["scan"] == 0 and again["points"] == city["points"], again
    keep_picture(shot, "cesium_city.png")
