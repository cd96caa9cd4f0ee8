"""Issue 46 through the command line: a tiny file cannot take all memory, a stranger's twin or catalogue text
cannot blow up a reader or run escapes, classify keeps a batch, and a new user's first day: furniture and cars
catalogued from their manifests in one command each, names from folders, counts by kind, -v / -q / --log."""

from __future__ import annotations

import json
import resource
import shutil
import subprocess
import sys
import time
import tomllib
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from tests.conftest import SHARED_DATA as DATA, need
from tests.twinreg.helpers import DUBLIN, ROOT
from twinreg.cli import app

TWINREG = str(Path(sys.executable).with_name("twinreg"))
#: the address space a command of these tests may take: the findings reached 23.5 GB; a healthy run stays far below
LIMIT = 6 << 30


def _invoke(*args):
    return CliRunner().invoke(app, [str(a) for a in args])


def _bounded(*args, limit: int = LIMIT, timeout: float = 120) -> tuple[subprocess.CompletedProcess, float]:
    """The real command with its memory capped (a blow-up is a MemoryError or a kill, not a slow machine)."""
    def cap():
        resource.setrlimit(resource.RLIMIT_AS, (limit, limit))

    t = time.monotonic()
    proc = subprocess.run([TWINREG, *map(str, args)], capture_output=True, text=True, timeout=timeout,
                          preexec_fn=cap)
    return proc, time.monotonic() - t


def _box_obj(path: Path, length: float, width: float, height: float) -> Path:
    v = [(x, y, z) for z in (0, height) for x in (0, length) for y in (0, width)]
    f = [(1, 2, 4, 3), (5, 7, 8, 6), (1, 5, 6, 2), (3, 4, 8, 7), (1, 3, 7, 5), (2, 6, 8, 4)]
    path.write_text("".join(f"v {x} {y} {z}\n" for x, y, z in v) + "".join(f"f {a} {b} {c} {d}\n" for a, b, c, d in f))
    return path


def test_a_140_byte_box_is_sampled_within_bounds_or_refused(tmp_path):
    box = _box_obj(tmp_path / "box.obj", 120, 90, 15)
    assert box.stat().st_size < 200
    proc, took = _bounded("--library", tmp_path / "lib", "add-model", box, "--category", "building", "--unit", "m",
                          "--json")
    assert proc.returncode == 0, proc.stderr
    row = json.loads(proc.stdout)
    assert row["n_points"] < 400_000 and "sampled every" in row["notes"] and took < 60
    huge = _box_obj(tmp_path / "huge.obj", 400, 300, 15)
    proc, took = _bounded("--library", tmp_path / "lib", "add-model", huge, "--category", "building", "--unit", "m")
    assert proc.returncode == 1 and len(proc.stderr.strip().splitlines()) == 1 and took < 30
    assert "huge.obj" in proc.stderr and ("too large" in proc.stderr or "implausible" in proc.stderr)


def test_a_forged_twins_huge_fused_shape_is_bounded_too(tmp_path):
    import trimesh

    twin = tmp_path / "forged"
    (twin / "shapes").mkdir(parents=True)
    (twin / "twin.json").write_text(json.dumps({"objects": [], "shapes": [
        {"type": 1, "kind": "building", "members": ["a", "b"], "file": "shapes/type_1.ply"}]}))
    trimesh.creation.box(extents=(120, 90, 15)).export(twin / "shapes" / "type_1.ply")
    lib = tmp_path / "lib"
    proc, _ = _bounded("--library", lib, "add-model", "--from-twin", twin, "--type", 1, "--name", "block")
    assert proc.returncode == 0, proc.stderr
    # --name is checked before the twin is read: a taken name is refused even where the twin does not exist
    proc, took = _bounded("--library", lib, "add-model", "--from-twin", tmp_path / "nowhere", "--type", 1,
                          "--name", "block")
    assert proc.returncode == 1 and "the name 'block' is taken" in proc.stderr and took < 20


def test_scanned_references_are_checked_before_they_are_read(tmp_path):
    lib = tmp_path / "lib"
    many = tmp_path / "many.xyz"
    many.write_bytes(b"1.0 2.0 0.5\n" * 2_500_000)  # 30 MB, more points than one object's reference needs
    proc, took = _bounded("--library", lib, "add-model", many, "--category", "pole", limit=3 << 30)
    assert proc.returncode == 1 and "2,500,000 points" in proc.stderr and "crop it" in proc.stderr, proc.stderr
    assert took < 20 and len(proc.stderr.strip().splitlines()) == 1
    line = tmp_path / "line.xyz"
    line.write_bytes(b"1 " * 20_000_000)  # 40 MB, one line
    proc, took = _bounded("--library", lib, "add-model", line, "--category", "pole", limit=3 << 30)
    assert proc.returncode == 1 and "a line of more than" in proc.stderr and took < 20, proc.stderr
    # a dense but plausible one is thinned to the models' sampling, and --scale is honoured for a scan
    rng = np.random.default_rng(0)
    pole = np.c_[rng.normal(0, 0.06, (150_000, 2)), rng.uniform(0, 4.5, 150_000)]
    np.savetxt(tmp_path / "pole.xyz", pole, fmt="%.4f")
    res = _invoke("--library", lib, "add-model", tmp_path / "pole.xyz", "--category", "pole", "--scale", "2",
                  "--json")
    assert res.exit_code == 0, res.output
    row = json.loads(res.stdout)
    assert row["n_points"] < 60_000 and "thinned" in row["notes"] and "scale x2" in row["notes"]
    assert 8.5 < row["size"]["height"] < 9.5  # 4.5 m of points, scaled twice


def test_a_twin_json_of_empty_objects_is_refused_before_it_is_parsed(tmp_path):
    twin = tmp_path / "t"
    twin.mkdir()
    (twin / "twin.json").write_bytes(b'{"objects":[' + b"{}," * 10_000_000 + b"{}]}")  # 30 MB
    (twin / "shapes").mkdir()
    other = tmp_path / "u"
    shutil.copytree(twin, other)
    lib = tmp_path / "lib"
    for args in (("compare", twin, other, "--out", tmp_path / "c"), ("coverage", twin / "twin.json"),
                 ("add-model", "--from-twin", twin, "--type", 1, "--name", "x", "--category", "bin")):
        proc, took = _bounded("--library", lib, *args, limit=2 << 30)
        assert proc.returncode != 0 and took < 30, (args, proc.stderr)
        assert "objects and arrays" in proc.stderr and len(proc.stderr.strip().splitlines()) == 1, proc.stderr


def test_make_model_and_class_are_text_never_escapes_or_markup(tmp_path, parametric_objs):
    lib = tmp_path / "lib"
    assert _invoke("--library", lib, "add-model", parametric_objs["demo_sedan"], "--name", "s").exit_code == 0
    for option, value in (("--make", "Audi\x1b]52;c;ZXZpbA==\x07"), ("--model", "TT\x1b[2J"),
                          ("--body-class", "a\nb"), ("--tag", "x\x1b[31m")):
        res = _invoke("--library", lib, "update-model", "s", option, value)
        assert res.exit_code == 1 and "control character" in res.output, (option, res.output)
        res = _invoke("--library", lib, "add-model", parametric_objs["demo_coupe"], option, value)
        assert res.exit_code == 1 and "control character" in res.output, (option, res.output)
    # rich markup is text: shown as typed, no MarkupError, no hyperlink
    res = _invoke("--library", lib, "update-model", "s", "--make", "[/bold]", "--model", "[link=http://x]y[/link]")
    assert res.exit_code == 0, res.output
    shown = _invoke("--library", lib, "show-model", "s")
    assert shown.exit_code == 0 and "[/bold]" in shown.stdout and "[link=http://x]y[/link]" in shown.stdout
    csv = _invoke("--library", lib, "list-models", "--csv")
    assert "\x1b" not in csv.stdout and "[/bold]" in csv.stdout


def test_damaged_faces_are_one_line(tmp_path):
    head = ("ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n"
            "element face 2\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n4 0 0\n0 2 1.5\n4 2 1.5\n")
    for name, face in (("far.ply", "3 0 1 1000000000\n3 1 2 3\n"), ("negative.ply", "3 0 1 -5\n3 1 2 3\n")):
        (tmp_path / name).write_text(head + face)
        res = _invoke("--library", tmp_path / "lib", "add-model", tmp_path / name, "--category", "bin")
        assert res.exit_code == 1 and "a face names vertex" in res.output and "unexpected" not in res.output
        assert len(res.output.strip().splitlines()) == 1


def test_classify_checks_its_options_first_and_keeps_the_batch(tmp_path, parametric_catalogue):
    from tests.conftest import toy_car

    folder = tmp_path / "objects"
    folder.mkdir()
    car = toy_car(0)
    with_nan = np.vstack([car, np.full((40, 3), np.nan)])
    np.savetxt(folder / "a.xyz", with_nan, fmt="%.4f")
    (folder / "b.xyz").write_text("0 0 0\n1 1 1\n2 2 2\n")  # degenerate
    res = _invoke("--library", parametric_catalogue.folder, "classify", folder, "--min-confidence", "2")
    assert res.exit_code == 2 and "--min-confidence 2" in res.output and len(res.output.strip().splitlines()) == 1
    res = _invoke("--library", parametric_catalogue.folder, "classify", folder, "--json")
    assert res.exit_code == 0, res.output
    items = json.loads(res.stdout)
    assert [Path(i["file"]).name for i in items] == ["a.xyz", "b.xyz"]
    assert items[0]["n_points"] == len(car) and "error" not in items[0]
    assert items[1]["kind"] is None and "degenerate" in items[1]["error"]
    assert "40 of" in res.stderr and "dropped" in res.stderr and "skipped" in res.stderr
    res = _invoke("inspect", folder / "a.xyz")
    assert res.exit_code == 0 and "dropped" in res.stderr


@pytest.fixture(scope="module")
def furniture_lib(tmp_path_factory) -> Path:
    lib = tmp_path_factory.mktemp("furniture") / "lib"
    folder = need(DATA / "street_furniture")
    res = _invoke("--library", lib, "import-models", folder, "--manifest", folder / "catalogue.csv", "--json")
    assert res.exit_code == 0, res.output
    return lib


def test_a_manifest_catalogues_the_shared_furniture_in_one_command(furniture_lib):
    import csv

    folder = DATA / "street_furniture"
    rows = list(csv.DictReader((folder / "catalogue.csv").open()))
    got = {m["name"]: m for m in json.loads(_invoke("--library", furniture_lib, "list-models", "--json").stdout)}
    assert set(got) == {r["name"] for r in rows}  # the bus stop's parts beside its base_link are left out
    for r in rows:
        m = got[r["name"]]
        assert m["category"] == r["category"] and m["model"] == r["model"], r
    assert 8.5 < got["lamp_post"]["size"]["height"] < 10  # scale 3
    assert 0.8 < got["construction_cone"]["size"]["height"] < 1.3  # scale 10


def test_a_manifest_catalogues_the_shared_cars_with_names_makes_and_models(tmp_path):
    import csv

    folder = need(DATA / "cars")
    res = _invoke("--library", tmp_path / "lib", "import-models", folder, "--manifest", folder / "catalogue.csv",
                  "--json")
    assert res.exit_code == 0, res.output
    rows = {r["name"]: r for r in csv.DictReader((folder / "catalogue.csv").open())}
    got = {m["name"]: m for m in json.loads(res.stdout)["added"]}
    assert set(got) == set(rows)
    for name, r in rows.items():
        assert (got[name]["make"] or "") == r["make"] and (got[name]["model"] or "") == r["model"]


def test_without_a_manifest_names_come_from_folders_not_part_names(tmp_path):
    cars = need(DATA / "cars")
    src = tmp_path / "cad"
    for rel in ("ford_fusion_2013/body.dae", "toyota_prius/Hybrid.obj", "nissan_patrol/suv_chassis.obj"):
        shutil.copytree((cars / rel).parent, src / Path(rel).parent)
    res = _invoke("--library", tmp_path / "lib", "import-models", src, "--json")
    assert res.exit_code == 0, res.output
    assert sorted(m["name"] for m in json.loads(res.stdout)["added"]) == ["ford_fusion_2013", "nissan_patrol",
                                                                         "toyota_prius"]


def test_a_bad_manifest_changes_nothing(tmp_path, parametric_objs):
    src = tmp_path / "cad"
    src.mkdir()
    shutil.copy(parametric_objs["demo_sedan"], src / "sedan.obj")
    lib = tmp_path / "lib"
    for text, words in (("file,name,colour\nsedan.obj,s,red\n", "unknown column"),
                        ("file,name\n../../etc/passwd,x\n", "not a path inside"),
                        ("file,scale\nsedan.obj,huge\n", "is not a factor"),
                        ("file,make\nsedan.obj,\"a\x1b[2Jb\"\n", "control character")):
        (tmp_path / "m.csv").write_text(text)
        res = _invoke("--library", lib, "import-models", src, "--manifest", tmp_path / "m.csv")
        assert res.exit_code == 1 and words in res.output and len(res.output.strip().splitlines()) == 1, res.output
        assert not lib.exists()


@pytest.fixture(scope="module")
def street_twin(furniture_lib, catalogue16, park, tmp_path_factory):
    """The shared park built with the cars and the furniture catalogued, through the real command, with -v and
    --log."""
    out = tmp_path_factory.mktemp("kinds") / "out"
    lib = tmp_path_factory.mktemp("both") / "lib"
    shutil.copytree(catalogue16.folder, lib)
    res = _invoke("--library", lib, "import-models", DATA / "street_furniture", "--manifest",
                  DATA / "street_furniture" / "catalogue.csv", "-q")
    assert res.exit_code == 0, res.output
    log = out.parent / "run.log"
    args = ["--library", lib, "build-twin", park["path"], *DUBLIN, "--anchor", park["offset"][0],
            park["offset"][1], "--out", out]
    res = _invoke(*args, "-v", "--log", log)
    assert res.exit_code == 0, res.output
    return {"out": out, "stderr": res.stderr, "log": log.read_text(), "args": args}


def test_the_kmz_has_a_folder_and_a_style_a_kind(street_twin):
    import xml.etree.ElementTree as ET
    import zipfile
    from collections import Counter

    out = street_twin["out"]
    doc = json.loads((out / "twin.json").read_text())
    ns = {"k": "http://www.opengis.net/kml/2.2"}
    root = ET.fromstring(zipfile.ZipFile(out / "twin.kmz").read("doc.kml"))
    kinds = Counter(o["kind"] for o in doc["objects"])
    folders = {f.find("k:name", ns).text: f for f in root.findall("k:Document/k:Folder", ns)}
    assert set(folders) == {f"{k} ({n})" for k, n in kinds.items()}
    styles = {s.get("id") for s in root.findall("k:Document/k:Style", ns)}
    for kind, n in kinds.items():
        marks = folders[f"{kind} ({n})"].findall("k:Placemark", ns)
        assert len(marks) == n
        for pm in marks:
            assert pm.find("k:styleUrl", ns).text.lstrip("#") in styles
            data = {d.get("name"): d.find("k:value", ns).text for d in pm.findall(".//k:Data", ns)}
            assert data["kind"] == kind and data["type"] and "model" in data and "confidence" in data


def test_the_console_counts_by_kind_and_model_and_lists_objects_with_v(street_twin, park):
    doc = json.loads((street_twin["out"] / "twin.json").read_text())
    err, log = street_twin["stderr"], street_twin["log"]
    assert any(line.startswith("kinds: ") for line in err.splitlines())
    assert any(line.startswith("models: ") for line in err.splitlines())
    for o in doc["objects"]:  # -v: a line each, in the log too
        assert f"  {o['id']}: " in err and f"  {o['id']}: " in log
    assert "size of " in err and "times the scan" in err
    # again into the same folder, quietly: no progress, no summary, the replacement said in the log only
    res = _invoke(*street_twin["args"], "-q", "--log", street_twin["out"].parent / "again.log")
    assert res.exit_code == 0
    assert all(line.startswith("warning") for line in res.stderr.splitlines()), res.stderr
    again = (street_twin["out"].parent / "again.log").read_text()
    assert "held a twin before this run; it was replaced" in again and "kinds: " in again
    assert f"  {doc['objects'][0]['id']}: " in again  # the log has what -v would say


def test_pictures_stay_pictures(tmp_path):
    from xml.etree import ElementTree

    from twinreg.report.scene import MAX_SECTION_ROWS, plot_object_sections

    rng = np.random.default_rng(0)
    items = [{"title": f"obj{k}: no match (a long reason " + "x" * 200 + ")",
              "object": {"lon": rng.uniform([-2, 0], [2, 1.5], (40, 2)), "tra": rng.uniform([-0.9, 0], [0.9, 1.5],
                                                                                           (20, 2))}}
             for k in range(400)]
    path = plot_object_sections(items, tmp_path / "sections.svg")
    svg = ElementTree.parse(path).getroot()
    width, height = float(svg.get("width")), float(svg.get("height"))
    assert height < 120 * (MAX_SECTION_ROWS + 5) and width < 2000


def test_the_package_metadata_installs_without_a_licence_warning():
    meta = tomllib.loads((ROOT / "pyproject.toml").read_text())
    assert isinstance(meta["project"]["license"], str)  # an SPDX expression, not the deprecated table
