"""`twinreg view` on a comparison, in the system's headless Chromium (offline: every request that is not local
refused): each epoch is drawn with its cars where they are, each in its status colour, and a click on a changed
car shows its history; the report opens with every image loaded."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from tests.conftest import keep_picture
from tests.twinreg.helpers import CHROMIUM, ROOT, chroma as _chroma, clean_env as _env
from twinreg.change.compare import compare
from twinreg.change.report import COLOURS

BIN = Path(sys.executable).parent


@pytest.fixture(scope="module")
def comparison(surveys, tmp_path_factory):
    out = tmp_path_factory.mktemp("epochs") / "changes"
    compare([surveys.twins["before"], surveys.twins["after150"]], out)
    return out


def _serve(folder):
    p = subprocess.Popen([str(BIN / "twinreg"), "view", str(folder), "--port", "0", "--no-open"],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=_env())
    url = p.stdout.readline().strip()
    assert url.startswith("http://127.0.0.1:"), p.stderr.read()
    return p, url


def test_epoch_switch_draws_changed_cars_in_their_colour(comparison):
    if not CHROMIUM.exists() or not (ROOT / "node_modules" / "playwright-core").is_dir():
        pytest.fail("chromium or the npm packages are missing: run `make install`")
    p, url = _serve(comparison)
    try:
        proc = subprocess.run(["node", str(ROOT / "tests" / "js" / "shoot_epochs.mjs"), url,
                               str(comparison / "shot")], capture_output=True, text=True, timeout=300, cwd=ROOT)
    finally:
        p.terminate()
        p.wait(timeout=30)
    assert proc.returncode == 0, proc.stderr
    got = json.loads(proc.stdout.strip().splitlines()[-1])
    assert got["ready"] and got["errors"] == [] and got["blocked"] == [], got
    doc = json.loads((comparison / "changes.json").read_text())
    assert len(got["epochs"]) == 2
    later = {c["after"]["id"]: c["status"] for c in doc["changes"] if c["after"] is not None}
    assert {c["id"]: c["status"] for c in got["epochs"][1]["cars"]} == later
    import matplotlib.image

    for k, epoch in enumerate(got["epochs"]):
        img = matplotlib.image.imread(str(comparison / f"shot_{k}.png"))[..., :3] * 255.0
        h, w = img.shape[:2]
        right = changed = 0
        for car in epoch["cars"]:
            x, y = int(round(car["x"])), int(round(car["y"]))
            assert 0 <= x < w and 0 <= y < h, car
            if car["status"] == "same":
                continue
            changed += 1
            patch = _chroma(img[max(y - 2, 0):y + 3, max(x - 2, 0):x + 3].reshape(-1, 3))
            want = _chroma([int(car["colour"][i:i + 2], 16) for i in (0, 2, 4)])
            right += np.median(np.linalg.norm(patch - want, axis=1)) < 0.06
        assert changed >= 3 and right == changed, (k, right, changed)
    for status in ("moved", "replaced", "arrived"):
        assert status in got["epochs"][1]["legend"]
    hist = got["history"]
    assert hist and hist["status"] in hist["text"] and "epoch 0 -> 1" in hist["text"], hist
    keep_picture(comparison / "shot_1.png", "compare_epochs.png")  # the README's picture


def test_report_opens_with_every_image(comparison):
    if not CHROMIUM.exists():
        pytest.fail("chromium is missing: run `make install`")
    shot = comparison / "report.png"
    page = (comparison / "changes.html").as_uri()
    proc = subprocess.run(["node", str(ROOT / "tests" / "js" / "shoot_page.mjs"), page, str(shot)],
                          capture_output=True, text=True, timeout=300, cwd=ROOT)
    assert proc.returncode == 0, proc.stderr
    got = json.loads(proc.stdout.strip().splitlines()[-1])
    assert got["errors"] == [] and got["blocked"] == [], got
    assert len(got["images"]) >= 2 and all(i["loaded"] for i in got["images"]), got
    assert "What changed" in got["text"] and "Occupancy" in got["text"]
    keep_picture(comparison / "changes_0.png", "compare_map.png")
    assert set(COLOURS) == {"same", "moved", "replaced", "left", "arrived", "unobserved"}
