"""twinreg library-report (issue 10): the catalogue's near-duplicates, its confusion at a survey's density, the
JSON against its schema, the same report for the same seed, and the page in a real browser."""

import json
import subprocess
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from tests.conftest import keep_picture
from twinreg.cli import app

ROOT = Path(__file__).resolve().parents[3]
CHROMIUM = Path("/usr/bin/chromium")


@pytest.fixture(scope="module")
def report16(catalogue16, tmp_path_factory):
    """The 16 shared cars at 300 pts/m2, 4 scans each."""
    out = tmp_path_factory.mktemp("libreport") / "report"
    res = CliRunner().invoke(app, ["library-report", "--density", "300", "--scans", "4", "--out", str(out),
                                   "--library", str(catalogue16.folder), "--json"])
    assert res.exit_code == 0, res.output
    return json.loads(res.stdout), out


def test_near_duplicates_are_fusion_and_mondeo_not_prius_and_patrol(report16):
    doc, _ = report16
    pairs = {frozenset((d["a"], d["b"])) for d in doc["taxonomy"]["near_duplicates"]}
    assert frozenset(("ford_fusion_2013", "ford_mondeo_2015")) in pairs
    assert frozenset(("toyota_prius", "nissan_patrol")) not in pairs
    by_name = {m["name"]: m for m in doc["models"]}
    assert by_name["ford_mondeo_2015"]["near_duplicates"] == ["ford_fusion_2013"]


def test_dense_scans_are_told_apart(report16):
    """At 300 pts/m2 the confusion matrix's diagonal is at least 90 % for the models with no near-duplicate."""
    doc, _ = report16
    m = np.array(doc["confusion"]["matrix"])
    names = doc["confusion"]["names"]
    alone = [k for k, n in enumerate(names) if not doc["models"][k]["near_duplicates"]]
    assert len(alone) == 14 and m.sum() == 16 * 4
    assert m[alone, alone].sum() / m[alone].sum() >= 0.9


def test_the_json_follows_its_schema_and_the_pictures_exist(report16):
    import jsonschema

    doc, out = report16
    schema = json.loads((ROOT / "docs" / "schemas" / "library-report.schema.json").read_text())
    jsonschema.validate(json.loads((out / "library.json").read_text()), schema)
    for m in doc["models"]:
        assert (out / m["picture"]).stat().st_size > 5_000
    assert (out / "confusion.png").exists() and (out / "taxonomy.png").exists()


def test_same_seed_same_report_whatever_the_workers(parametric_catalogue, tmp_path):
    docs = []
    for workers in ("1", "2"):
        res = CliRunner().invoke(app, ["library-report", "--density", "50", "--scans", "2", "--workers", workers,
                                       "--out", str(tmp_path / workers), "--library",
                                       str(parametric_catalogue.folder), "--json"])
        assert res.exit_code == 0, res.output
        docs.append(json.loads(res.stdout))
    assert docs[0]["confusion"] == docs[1]["confusion"]


def test_the_report_in_a_real_browser(report16):
    if not CHROMIUM.exists() or not (ROOT / "node_modules" / "playwright-core").is_dir():
        pytest.fail("the browser test needs /usr/bin/chromium and node_modules; run `make test`")
    _, out = report16
    shot = out / "shot.png"
    proc = subprocess.run(["node", str(ROOT / "tests" / "js" / "shoot_page.mjs"), (out / "library.html").as_uri(),
                           str(shot)], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    page = json.loads(proc.stdout.strip().splitlines()[-1])
    assert not page["errors"] and not page["blocked"]
    assert len(page["images"]) == 18 and all(i["loaded"] for i in page["images"])
    assert "near-duplicate of ford_fusion_2013" in page["text"]
    keep_picture(shot, "library_report.png")
