"""report.html leads with the picture: on the real AHN tile (many objects without a model, long reasons) in the
system's headless Chromium at 1280 px, the map is above the fold, every image is loaded, no table cell runs over
two lines; the full reasons are on demand."""

from __future__ import annotations

import html
import json
import subprocess

import pytest
from typer.testing import CliRunner

from tests.conftest import SHARED_DATA, keep_picture, need
from tests.twinreg.helpers import CHROMIUM, ROOT
from twinreg.cli import app


def _layout(page) -> dict:
    """tests/js/report_layout.mjs on a report at 1280 x 900 in headless Chromium: no console error, nothing
    blocked; what it measured."""
    proc = subprocess.run(["node", str(ROOT / "tests" / "js" / "report_layout.mjs"), page.as_uri(), "1280", "900"],
                          capture_output=True, text=True, timeout=300, cwd=ROOT)
    assert proc.returncode == 0, proc.stderr
    got = json.loads(proc.stdout.strip().splitlines()[-1])
    assert got["errors"] == [] and got["blocked"] == [], got
    return got


def test_report_leads_with_the_map_and_keeps_cells_short(catalogue16, tmp_path):
    if not CHROMIUM.exists():
        pytest.fail("chromium is missing: run `make install`")
    tile = need(SHARED_DATA / "ahn_amsterdam") / "ahn_2397_9705.laz"
    r = CliRunner().invoke(app, ["--library", str(catalogue16.folder), "build-twin", str(tile), "--crs",
                                 "EPSG:28992", "--vertical-crs", "EPSG:5709", "--out", str(tmp_path / "ahn")])
    assert r.exit_code == 0, r.output
    twin = json.loads((tmp_path / "ahn" / "twin.json").read_text())
    unmatched = [o for o in twin["objects"] if not o["match"]]
    assert len(unmatched) >= 3 and max(len(o["reason"]) for o in unmatched) > 80  # long reasons to keep short
    got = _layout(tmp_path / "ahn" / "report.html")
    assert len(got["images"]) >= 3 and all(i["loaded"] for i in got["images"]), got["images"]
    assert got["images"][0]["src"] == "topview.svg" and got["lead"]["top"] < 200 and got["lead"]["bottom"] <= 900
    assert got["cells"] > 10 * len(twin["objects"]) and got["tall"] == [], got["tall"]
    shot = subprocess.run(["node", str(ROOT / "tests" / "js" / "shoot_page.mjs"),
                           (tmp_path / "ahn" / "report.html").as_uri(), str(tmp_path / "report_ahn.png"), "1280",
                           "900"], capture_output=True, text=True, timeout=300, cwd=ROOT)
    assert shot.returncode == 0, shot.stderr
    keep_picture(tmp_path / "report_ahn.png", "report_ahn.png")  # the README's picture
    page = (tmp_path / "ahn" / "report.html").read_text()
    assert page.count("<details>") == len(unmatched)
    for o in unmatched:  # the full reason is there, behind its gist
        assert f"<span>{html.escape(o['reason'], quote=True)}</span>" in page
    # the objects by kind, each kind's count as twin.json has it
    from collections import Counter

    for kind, n in Counter(o["kind"] for o in twin["objects"]).items():
        assert f"<tr><td>{kind}</td><td>{n}</td>" in page


def test_city_report_leads_with_the_map(city_twin, small_city):
    if not CHROMIUM.exists():
        pytest.fail("chromium is missing: run `make install`")
    root, _ = small_city
    got = _layout(root / "out" / "report.html")
    assert all(i["loaded"] for i in got["images"]) and got["images"][0]["src"] == "map.png"
    assert got["lead"]["top"] < 200 and got["lead"]["bottom"] <= 900 and got["tall"] == [], got


def test_svg_pictures_are_well_formed_and_show_strangers_text_as_text(tmp_path):
    """The report's pictures are XML a browser reads; a model name or reason from someone else's catalogue is
    escaped (shown, never run); the embedded raster is the PNG of the pixels given."""
    import base64
    import io
    from xml.etree import ElementTree

    import numpy as np
    from PIL import Image

    from twinreg.report.scene import draw_dendrogram, draw_heatmap, plot_object_sections, plot_twin_top
    from twinreg.report.svg import png

    hostile = "<script>x</script> & ]]> 'q' \"t\""  # under the rows' 44 characters
    rng = np.random.default_rng(1)
    pts = np.c_[rng.uniform(0, 30, (5000, 2)), rng.uniform(0, 2, 5000)]
    footprints = [{"corners": np.array([[5, 5], [9, 5], [9, 7], [5, 7.0]]), "color": (0.1, 0.5, 0.7),
                   "centre": np.array([7, 6.0]), "front": np.array([8.5, 6.0]), "label": hostile}]
    top = plot_twin_top(pts, pts[:, 2] < 0.1, footprints, tmp_path / "topview.svg", hostile, hag=pts[:, 2])
    items = [{"title": hostile, "object": {"lon": rng.uniform([-2, 0], [2, 1.5], (40, 2)),
                                            "tra": rng.uniform([-0.9, 0], [0.9, 1.5], (20, 2))},
              "model": {"lon": rng.uniform([-2, 0], [2, 1.5], (40, 2)), "tra": np.zeros((0, 2))}}]
    sections = plot_object_sections(items * 3, tmp_path / "sections.svg")
    m = np.array([[0.0, 0.05, 0.08], [0.05, 0.0, 0.07], [0.08, 0.07, 0.0]])
    heat = draw_heatmap(m, [hostile, "b", "c"], tmp_path / "heatmap.svg")
    tree = draw_dendrogram(np.array([[0, 1, 0.05, 2], [2, 3, 0.075, 3]]), [hostile, "b", "c"], 0.065,
                           tmp_path / "dendrogram.svg")
    for path in (top, sections, heat, tree):
        root = ElementTree.parse(path).getroot()  # well-formed, or this raises
        assert root.tag.endswith("svg") and float(root.get("width")) > 100
        assert "<script" not in path.read_text() and not root.findall(".//{http://www.w3.org/2000/svg}script")
        assert any(hostile in (t.text or "") for t in root.iter("{http://www.w3.org/2000/svg}text")), path.name
    # the raster embedded is the one given, read back by an independent decoder
    pixels = rng.integers(0, 256, (7, 5, 4), dtype=np.uint8)
    assert np.array_equal(np.asarray(Image.open(io.BytesIO(png(pixels)))), pixels)
    image = ElementTree.parse(top).getroot().find(".//{http://www.w3.org/2000/svg}image")
    shown = np.asarray(Image.open(io.BytesIO(base64.b64decode(image.get("href").split(",", 1)[1]))))
    assert shown.shape[2] == 2 and (shown[:, :, 1] == 255).sum() > 1000  # grey and alpha, the scan's cells opaque


def test_a_twin_without_models_says_so_and_claims_no_background_confidence():
    """A sweep whose objects no catalogue model fits: no empty model table or confidence chart but a sentence, and
    no median confidence for unknown, vegetation or structure (they claim no catalogued kind); a named kind keeps
    its median."""
    from twinreg.report.scene import _summary_tables, kinds_table

    objs = [{"kind": k, "kind_confidence": c, "match": None, "reason": "no catalogue model within the size tolerance"}
            for k, c in (("vegetation", 0.0), ("vegetation", 0.0), ("unknown", 0.0), ("car", 0.6), ("car", 0.8))]
    page = _summary_tables({"objects": objs})
    assert "No catalogue model was placed" in page and "confidence.svg" not in page and "<th>make</th>" not in page
    rows = {r.split("</td>")[0]: r for r in kinds_table(objs).split("<tr><td>")[1:]}
    assert all("<td></td></tr>" in rows[k] for k in ("vegetation", "unknown"))
    assert "<td>0.70</td>" in rows["car"]
    placed = objs + [{"kind": "car", "kind_confidence": 0.9, "reason": "", "match": {"name": "Prius", "confidence": 0.9}}]
    assert "confidence.svg" in _summary_tables({"objects": placed})
