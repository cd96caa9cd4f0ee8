"""Portable catalogues (issue 10): export-library / import-library round trip, clashes, an older schema, and a
damaged zip refused with one line and no change."""

import hashlib
import json
import shutil
import sqlite3
import zipfile

import pytest
from typer.testing import CliRunner

from twinreg.cli import app


def _rows(folder):
    con = sqlite3.connect(folder / "catalogue.sqlite")
    cols = [c[1] for c in con.execute("PRAGMA table_info(ref_models)")]
    rows = {r[cols.index("name")]: dict(zip(cols, r)) for r in con.execute("SELECT * FROM ref_models")}
    con.close()
    for r in rows.values():
        r.pop("id")
    return rows


def _files(folder):
    return {p.relative_to(folder).as_posix(): hashlib.sha256(p.read_bytes()).hexdigest()
            for sub in ("files", "meshes") for p in (folder / sub).rglob("*") if p.is_file()}


@pytest.fixture(scope="module")
def bundle(catalogue16, tmp_path_factory):
    path = tmp_path_factory.mktemp("bundle") / "lib.zip"
    res = CliRunner().invoke(app, ["export-library", str(path), "--library", str(catalogue16.folder), "--json"])
    assert res.exit_code == 0, res.output
    doc = json.loads(res.stdout)
    assert doc["n_models"] == 16 and doc["schema_revision"] == "0005_category"
    return path


def test_round_trip_gives_identical_rows_files_and_checksums(bundle, catalogue16, tmp_path):
    res = CliRunner().invoke(app, ["import-library", str(bundle), "--library", str(tmp_path / "lib"), "--json"])
    assert res.exit_code == 0, res.output
    assert len(json.loads(res.stdout)["added"]) == 16
    assert _rows(tmp_path / "lib") == _rows(catalogue16.folder)
    copied, source = _files(tmp_path / "lib"), _files(catalogue16.folder)
    assert copied and all(source[k] == v for k, v in copied.items())
    # every original file and normalised mesh (meshes/<sha>.npz) came along; decimated ones as they were cached
    assert {k for k in source if k.startswith("files/") or k.count(".") == 1} <= set(copied)


def test_clashing_names_change_nothing_unless_asked(bundle, parametric_objs, tmp_path):
    from twinreg.catalogue.repository import Catalogue

    lib = tmp_path / "lib"
    Catalogue(lib).add(parametric_objs["demo_sedan"], name="ford_fusion_2013")  # another car under a bundle name
    before_rows, before_files = _rows(lib), _files(lib)
    res = CliRunner().invoke(app, ["import-library", str(bundle), "--library", str(lib)])
    assert res.exit_code == 1
    assert "ford_fusion_2013" in res.output and "--rename or --skip" in res.output
    assert _rows(lib) == before_rows and _files(lib) == before_files
    res = CliRunner().invoke(app, ["import-library", str(bundle), "--library", str(lib), "--skip", "--json"])
    assert res.exit_code == 0 and len(json.loads(res.stdout)["added"]) == 15
    lib2 = tmp_path / "lib2"
    Catalogue(lib2).add(parametric_objs["demo_sedan"], name="ford_fusion_2013")
    res = CliRunner().invoke(app, ["import-library", str(bundle), "--library", str(lib2), "--rename", "--json"])
    assert json.loads(res.stdout)["added"]["ford_fusion_2013"] == "ford_fusion_2013-2"
    assert len(_rows(lib2)) == 17


def test_a_damaged_zip_is_refused_with_one_line(bundle, tmp_path):
    lib = tmp_path / "lib"
    bad = tmp_path / "bad.zip"
    data = bytearray(bundle.read_bytes())
    z = zipfile.ZipFile(bundle)
    info = z.getinfo("catalogue.sqlite")
    data[info.header_offset + 200] ^= 0xFF  # one byte of the database, inside the zip
    bad.write_bytes(bytes(data))
    res = CliRunner().invoke(app, ["import-library", str(bad), "--library", str(lib)])
    assert res.exit_code == 1
    lines = [ln for ln in res.output.splitlines() if ln.strip()]
    assert len(lines) == 1 and "bad.zip" in lines[0] and "export it again" in lines[0]
    assert not (lib / "files").exists() and not (lib / "meshes").exists()
    res = CliRunner().invoke(app, ["import-library", str(tmp_path), "--library", str(lib)])  # not a zip at all
    assert res.exit_code == 1 and "no such bundle file" in res.output


def test_an_older_schema_is_upgraded_on_import(bundle, tmp_path):
    """A bundle written before migration 0004 (no section descriptor) imports with its descriptors filled."""
    from tests.twinreg.helpers import downgrade_catalogue

    work = tmp_path / "old"
    zipfile.ZipFile(bundle).extractall(work)
    downgrade_catalogue(work / "catalogue.sqlite", "0003_frame")
    con = sqlite3.connect(work / "catalogue.sqlite")
    con.execute("PRAGMA journal_mode=DELETE")
    con.close()
    manifest = json.loads((work / "bundle.json").read_text())
    manifest["schema_revision"] = "0003_frame"
    old = tmp_path / "old.zip"
    with zipfile.ZipFile(old, "w") as z:
        for name in manifest["members"]:
            p = work / name
            manifest["members"][name] = {"bytes": p.stat().st_size, "sha256": hashlib.sha256(p.read_bytes()).hexdigest()}
            z.write(p, name)
        z.writestr("bundle.json", json.dumps(manifest))
    assert "profile_mid" not in {c[1] for c in sqlite3.connect(work / "catalogue.sqlite").execute(
        "PRAGMA table_info(ref_models)")}
    lib = tmp_path / "lib"
    res = CliRunner().invoke(app, ["import-library", str(old), "--library", str(lib), "--json"])
    assert res.exit_code == 0, res.output
    rows = _rows(lib)
    assert len(rows) == 16 and all(r["profile_mid"] > 0.5 for r in rows.values())
    shutil.rmtree(work)
