"""A bundle from a stranger is data (issue 19): its rows decide no path, its sizes and arrays are checked before
anything is written, a bomb is refused unread, and remove-model deletes only the catalogue's own unshared files.
Every hostile bundle is refused in one line, exit 1, with the catalogue unchanged."""

import hashlib
import json
import shutil
import sqlite3
import zipfile
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from twinreg.cli import app


def _invoke(*args):
    return CliRunner().invoke(app, [str(a) for a in args])


def _state(folder: Path) -> dict:
    """Every file under ``folder`` with its hash (the catalogue unchanged = the same dict)."""
    if not folder.exists():
        return {}
    out = {p.relative_to(folder).as_posix(): hashlib.sha256(p.read_bytes()).hexdigest()
           for p in folder.rglob("*") if p.is_file() and p.name != ".lock" and not p.name.endswith(("-shm", "-wal"))}
    if (folder / "catalogue.sqlite").exists():  # its content, not its bytes (SQLite's WAL files come and go)
        con = sqlite3.connect(folder / "catalogue.sqlite")
        out["catalogue.sqlite"] = hashlib.sha256("\n".join(con.iterdump()).encode()).hexdigest()
        con.close()
    return out


@pytest.fixture(scope="module")
def good_bundle(parametric_catalogue, tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("bundle") / "lib.zip"
    res = _invoke("export-library", path, "--library", parametric_catalogue.folder)
    assert res.exit_code == 0, res.output
    return path


def rebuild(src: Path, dst: Path, sql=(), members=None, manifest_edit=None, drop_db=False) -> Path:
    """A copy of bundle ``src`` whose database had ``sql`` run on it, with ``members`` (name -> bytes) added or
    replaced, every checksum and byte count made right again (an attacker can do that) unless ``manifest_edit``
    changes the manifest afterwards."""
    work = dst.parent / (dst.stem + "_work")
    shutil.rmtree(work, ignore_errors=True)
    with zipfile.ZipFile(src) as z:
        z.extractall(work)
    db = work / "catalogue.sqlite"
    con = sqlite3.connect(db)
    for q in sql:
        con.execute(q)
    con.commit()
    con.close()
    if drop_db:
        db.unlink()
    for name, data in (members or {}).items():
        (work / name).parent.mkdir(parents=True, exist_ok=True)
        (work / name).write_bytes(data)
    files = [p for p in work.rglob("*") if p.is_file() and p.name != "bundle.json"]
    manifest = json.loads((work / "bundle.json").read_text())
    manifest["members"] = {p.relative_to(work).as_posix(): {"bytes": p.stat().st_size,
                                                              "sha256": hashlib.sha256(p.read_bytes()).hexdigest()}
                           for p in files}
    if manifest_edit:
        manifest_edit(manifest)
    with zipfile.ZipFile(dst, "w") as z:
        z.writestr("bundle.json", json.dumps(manifest))
        for p in files:
            z.write(p, p.relative_to(work).as_posix())
    return dst


def _first(bundle: Path, column: str):
    with zipfile.ZipFile(bundle) as z:
        data = z.read("catalogue.sqlite")
    tmp = bundle.parent / "peek.sqlite"
    tmp.write_bytes(data)
    con = sqlite3.connect(tmp)
    value = con.execute(f"SELECT {column} FROM ref_models ORDER BY id LIMIT 1").fetchone()[0]
    con.close()
    return value


def _refused(bundle: Path, lib: Path, *extra):
    before = _state(lib)
    res = _invoke("import-library", bundle, "--library", lib, *extra)
    assert res.exit_code == 1, res.output
    assert "not a valid bundle" in res.output and "Traceback" not in res.output
    assert len(res.output.strip().splitlines()) == 1, res.output
    assert _state(lib) == before  # nothing written, not even a new empty catalogue
    return res.output


@pytest.fixture()
def lib(tmp_path, parametric_objs) -> Path:
    """A user's catalogue with one model, and a file of the user's beside it that no import may touch."""
    from twinreg.catalogue.repository import Catalogue

    folder = tmp_path / "mylib"
    Catalogue(folder).add(parametric_objs["demo_coupe"], name="mine")
    (tmp_path / "thesis.tex").write_text("years of work")
    return folder


@pytest.mark.parametrize("column,value", [
    ("stored_file", "/tmp/twinreg-hostile-absolute.obj"),
    ("stored_file", "../thesis.tex"),
    ("stored_file", "files/../../../etc/hostname"),
    ("mesh_file", "catalogue.sqlite"),
    ("mesh_file", "../thesis.tex"),
])
def test_rows_naming_paths_are_refused(good_bundle, lib, tmp_path, column, value):
    bad = rebuild(good_bundle, tmp_path / "bad.zip", [f"UPDATE ref_models SET {column} = '{value}'"])
    out = _refused(bad, lib)
    assert "model 1" in out and ("not where a catalogue keeps them" in out or "format suffix" in out)
    assert (tmp_path / "thesis.tex").read_text() == "years of work"
    assert not Path("/tmp/twinreg-hostile-absolute.obj").exists()


def test_a_row_pointing_at_another_models_files_is_refused(good_bundle, lib, tmp_path):
    other = _first(good_bundle, "mesh_file")
    bad = rebuild(good_bundle, tmp_path / "bad.zip", [f"UPDATE ref_models SET mesh_file = '{other}' WHERE id = 2"])
    _refused(bad, lib)


@pytest.mark.parametrize("sha", ["../../../../tmp/x", "*", "AB" * 32, "ab" * 31])
def test_content_addresses_that_are_not_sha256_are_refused(good_bundle, lib, tmp_path, sha):
    bad = rebuild(good_bundle, tmp_path / "bad.zip", [f"UPDATE ref_models SET sha256 = '{sha}' WHERE id = 1"])
    assert "content address" in _refused(bad, lib)


def test_a_file_that_does_not_hash_to_its_address_is_refused(good_bundle, lib, tmp_path):
    stored = _first(good_bundle, "stored_file")
    bad = rebuild(good_bundle, tmp_path / "bad.zip", members={stored: b"v 0 0 0\n"})
    assert "does not hash to its content address" in _refused(bad, lib)


def test_lying_blobs_and_sizes_are_refused(good_bundle, lib, tmp_path):
    huge = np.array([100_000_000, 3], dtype="<i4").tobytes() + np.zeros(30, dtype="<f4").tobytes()
    cases = [
        ("points", f"UPDATE ref_models SET points = X'{huge.hex()}' WHERE id = 1"),
        ("length", "UPDATE ref_models SET length = 1e308 WHERE id = 1"),
        ("width", "UPDATE ref_models SET width = -5 WHERE id = 1"),
        ("section", "UPDATE ref_models SET section_transverse = X'0102' WHERE id = 1"),
        ("tags", "UPDATE ref_models SET tags_json = '{\"a\": 1}' WHERE id = 1"),
        ("name", "UPDATE ref_models SET name = 'evil' || char(10) || 'line' WHERE id = 1"),
        ("category", "UPDATE ref_models SET category = '<script>alert(1)</script>' WHERE id = 1"),
        ("source", "UPDATE ref_models SET source = '../../etc' WHERE id = 1"),
        ("level", "UPDATE ref_models SET sym_level = 'spherical' WHERE id = 1"),
    ]
    for what, sql in cases:
        out = _refused(rebuild(good_bundle, tmp_path / f"bad_{what}.zip", [sql]), lib)
        assert "model 1" in out, (what, out)


def test_a_mesh_that_is_not_a_mesh_is_refused(good_bundle, lib, tmp_path):
    mesh = _first(good_bundle, "mesh_file")
    pickled = tmp_path / "p.npz"
    np.savez(pickled, vertices=np.array([object()], dtype=object), faces=np.zeros((1, 3), int))
    out = _refused(rebuild(good_bundle, tmp_path / "bad.zip", members={mesh: pickled.read_bytes()}), lib)
    assert "not a usable mesh" in out


def test_a_zip_bomb_is_refused_before_it_is_inflated(good_bundle, lib, tmp_path):
    """A member of 300 MB of zeros (the right checksum) squeezed into a few hundred kB: refused from the zip's
    directory alone, nothing extracted."""
    bomb = tmp_path / "bomb.zip"
    size = 300 * 1024 ** 2
    h = hashlib.sha256()
    block = bytes(1 << 20)
    for _ in range(size >> 20):
        h.update(block)
    with zipfile.ZipFile(good_bundle) as src, zipfile.ZipFile(bomb, "w", zipfile.ZIP_DEFLATED) as z:
        manifest = json.loads(src.read("bundle.json"))
        manifest["members"]["files/zz/zeros.bin"] = {"bytes": size, "sha256": h.hexdigest()}
        z.writestr("bundle.json", json.dumps(manifest))
        for name in src.namelist():
            if name != "bundle.json":
                z.writestr(name, src.read(name))
        with z.open("files/zz/zeros.bin", "w", force_zip64=True) as fh:
            for _ in range(size >> 20):
                fh.write(block)
    assert bomb.stat().st_size < 5 * 1024 ** 2
    assert "zip bomb" in _refused(bomb, lib)


def test_byte_counts_must_match_the_manifest(good_bundle, lib, tmp_path):
    def lie(manifest):
        manifest["members"]["catalogue.sqlite"]["bytes"] += 1

    assert "bundle.json says" in _refused(rebuild(good_bundle, tmp_path / "bad.zip", manifest_edit=lie), lib)


def test_a_zip_with_no_database_is_refused(good_bundle, lib, tmp_path):
    assert "catalogue.sqlite" in _refused(rebuild(good_bundle, tmp_path / "bad.zip", drop_db=True), lib)
    with zipfile.ZipFile(tmp_path / "empty.zip", "w") as z:
        z.writestr("readme.txt", "hello")
    assert "no bundle.json" in _refused(tmp_path / "empty.zip", lib)
    (tmp_path / "text.zip").write_text("not a zip")
    assert "not a zip file" in _refused(tmp_path / "text.zip", lib)


def test_a_database_with_triggers_runs_none_of_them(good_bundle, lib, tmp_path):
    """A trigger planted in the bundle's database would run during the schema upgrade: it is dropped unread."""
    sql = ["CREATE TABLE loot (x TEXT)",
           "CREATE TRIGGER t AFTER UPDATE ON ref_models BEGIN INSERT INTO loot VALUES ('ran'); END"]
    res = _invoke("import-library", rebuild(good_bundle, tmp_path / "trig.zip", sql), "--library",
                  tmp_path / "fresh")
    assert res.exit_code == 0, res.output
    con = sqlite3.connect(tmp_path / "fresh" / "catalogue.sqlite")
    assert con.execute("SELECT count(*) FROM sqlite_master WHERE type = 'trigger'").fetchone()[0] == 0
    con.close()


def test_only_the_imported_models_members_are_extracted(good_bundle, tmp_path, monkeypatch):
    """With --skip, the models left out have none of their files read out of the zip."""
    from twinreg.catalogue import bundle as B

    extracted = []
    real = B._Bundle.extract

    def spy(self, name, into):
        extracted.append(name)
        return real(self, name, into)

    monkeypatch.setattr(B._Bundle, "extract", spy)
    lib = tmp_path / "lib"
    assert _invoke("import-library", good_bundle, "--library", lib).exit_code == 0
    extracted.clear()
    res = _invoke("import-library", good_bundle, "--library", lib, "--skip", "--json")
    assert res.exit_code == 0, res.output
    assert extracted == ["catalogue.sqlite"]


def test_remove_model_deletes_only_its_own_unshared_files(parametric_objs, tmp_path):
    """A catalogue whose rows were edited to point at the user's files, the database or another model's files
    (an older twinreg's import, or a hand edit): remove-model deletes none of them."""
    from twinreg.catalogue.repository import Catalogue

    lib = tmp_path / "lib"
    cat = Catalogue(lib)
    cat.add(parametric_objs["demo_sedan"], name="a")
    b = cat.add(parametric_objs["demo_suv"], name="b")
    cat.add(parametric_objs["demo_coupe"], name="c")
    cat.close()
    (tmp_path / "thesis.tex").write_text("years of work")
    con = sqlite3.connect(lib / "catalogue.sqlite")
    con.execute("UPDATE ref_models SET stored_file = ?, mesh_file = 'catalogue.sqlite', sha256 = '*' "
                "WHERE name = 'a'", (str(tmp_path / "thesis.tex"),))
    con.execute("UPDATE ref_models SET stored_file = ?, mesh_file = ?, sha256 = '../../../../tmp/x' "
                "WHERE name = 'c'", (b.stored_file, b.mesh_file))
    con.commit()
    con.close()
    cached = sorted((lib / "meshes").glob("*.npz"))
    for ref in ("name:a", "name:c"):
        res = _invoke("remove-model", ref, "--yes", "--library", lib)
        assert res.exit_code == 0, res.output
    assert (tmp_path / "thesis.tex").read_text() == "years of work"
    assert (lib / "catalogue.sqlite").is_file()
    assert (lib / b.stored_file).is_file() and (lib / b.mesh_file).is_file()
    assert [r.name for r in Catalogue(lib).list()] == ["b"]
    assert all(p.exists() for p in cached if p.name.startswith(b.sha256))


def test_export_library_refuses_the_catalogue_and_a_users_file(parametric_catalogue, tmp_path):
    lib = parametric_catalogue.folder
    before = _state(lib)
    for dst in (lib / "catalogue.sqlite", lib / "x.zip", lib / "files" / "y.zip"):
        res = _invoke("export-library", dst, "--library", lib)
        assert res.exit_code == 1 and "inside the catalogue folder" in res.output, res.output
    assert _state(lib) == before
    mine = tmp_path / "notes.zip"
    mine.write_text("my notes")
    res = _invoke("export-library", mine, "--library", lib)
    assert res.exit_code == 1 and "not a twinreg bundle" in res.output and "--force" in res.output
    assert mine.read_text() == "my notes"
    assert _invoke("export-library", mine, "--library", lib, "--force").exit_code == 0
    assert zipfile.is_zipfile(mine)
    assert _invoke("export-library", mine, "--library", lib).exit_code == 0  # a bundle may be overwritten


def test_export_needs_no_writer_lock(parametric_catalogue, tmp_path):
    """The export only reads: it succeeds while another process holds the catalogue's writer lock."""
    import subprocess
    import sys

    lib = parametric_catalogue.folder
    holder = subprocess.Popen([sys.executable, "-c", (
        "import fcntl, sys, time; fh = open(sys.argv[1], 'a+'); fcntl.flock(fh, fcntl.LOCK_EX); "
        "print('locked', flush=True); time.sleep(60)"), str(lib / ".lock")], stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "locked"
        res = _invoke("export-library", tmp_path / "while_locked.zip", "--library", lib)
        assert res.exit_code == 0, res.output
    finally:
        holder.kill()
        holder.wait()


@pytest.mark.parametrize("column,value", [
    ("make", "Audi\x1b]52;c;ZXZpbA==\x07"),  # a clipboard write on the terminal that lists it
    ("model", "TT\x1b[2J"),
    ("body_class", "sedan\x07"),
    ("notes", "fine\x1b[31m red"),
])
def test_escapes_in_a_rows_text_are_refused(good_bundle, lib, tmp_path, column, value):
    """Issue 46: a make, model, body class or note holding a terminal escape or a control character is refused,
    as a name is."""
    bad = rebuild(good_bundle, tmp_path / "bad.zip", [f"UPDATE ref_models SET {column} = '{value}'"])
    assert "not plain text" in _refused(bad, lib)
