"""Output folders: a user's files are never deleted, inputs and the catalogue are never inside OUT, and a run killed
between the two renames of the swap loses nothing (the next run finishes it)."""

import json
import subprocess
import sys

import pytest
from typer.testing import CliRunner

from twinreg.cli import app
from twinreg.errors import ExportError
from twinreg.io.outdir import MARKER, recover, staged_folder
from twinreg.io.ply import write_ply

runner = CliRunner()


def listing(folder):
    return sorted((str(p.relative_to(folder)), p.read_bytes()) for p in folder.rglob("*") if p.is_file())


@pytest.fixture
def scans(tmp_path):
    """A folder of a user's scans: a small scene and other files."""
    from twinreg.sim.parametric import LIBRARY, car_mesh
    from twinreg.sim.scan import car_park

    folder = tmp_path / "scans"
    folder.mkdir()
    park = car_park([car_mesh(LIBRARY[2])], n_cars=2, seed=1, distractors=False)
    write_ply(folder / "park.ply", park.points)
    (folder / "notes.txt").write_text("field notes")
    return folder


def test_detect_into_the_scans_own_folder_is_refused(scans):
    before = listing(scans)
    res = runner.invoke(app, ["detect", str(scans / "park.ply"), "--out", str(scans)])
    assert res.exit_code == 1 and res.output.startswith("error:") and "park.ply" in res.output
    assert "\n" not in res.output.strip()
    assert listing(scans) == before


def test_build_twin_into_the_current_folder_is_refused(scans, monkeypatch, tmp_path):
    lib = scans / "lib"
    lib.mkdir()
    monkeypatch.chdir(scans)
    before = listing(scans)
    res = runner.invoke(app, ["build-twin", "park.ply", "--lat", "53.35", "--lon", "-6.26", "--library", "lib",
                              "--out", "."])
    assert res.exit_code == 1 and "error:" in res.output and "choose another --out" in res.output
    assert listing(scans) == before
    # an output folder inside which the catalogue lies is refused even when it is twinreg's own
    out = tmp_path / "twin"
    with staged_folder(out) as stage:
        (stage / "twin.json").write_text("{}")
    with pytest.raises(ExportError, match="which this run reads"):
        with staged_folder(out, protect=[out / "twin.json"]):
            pass


def test_only_a_folder_twinreg_wrote_is_replaced(tmp_path):
    out = tmp_path / "out"
    with staged_folder(out) as stage:
        (stage / "a.txt").write_text("first")
        (stage / "sub").mkdir()
        (stage / "sub" / "b.txt").write_text("first")
    assert json.loads((out / MARKER).read_text())["files"] == ["a.txt", "sub/b.txt"]
    with staged_folder(out) as stage:
        (stage / "a.txt").write_text("second")
    assert (out / "a.txt").read_text() == "second" and not (out / "sub").exists()
    (out / "a.txt-wal").write_text("SQLite's file beside a.txt, were it a database: twinreg's")
    with staged_folder(out) as stage:
        (stage / "a.txt").write_text("third")
    assert sorted(p.name for p in out.iterdir()) == sorted([MARKER, "a.txt"])
    (out / "mine.txt-wal").write_text("beside no file twinreg wrote: the user's")
    with pytest.raises(ExportError, match="mine.txt-wal"):
        with staged_folder(out):
            pass
    (out / "mine.txt-wal").unlink()
    (out / "mine.txt").write_text("the user's")
    with pytest.raises(ExportError, match="mine.txt"):
        with staged_folder(out):
            pass
    assert (out / "mine.txt").read_text() == "the user's"
    foreign = tmp_path / "foreign"
    foreign.mkdir()
    (foreign / "thesis.pdf").write_text("years of work")
    with pytest.raises(ExportError, match="did not write"):
        with staged_folder(foreign):
            pass
    assert listing(foreign) == [("thesis.pdf", b"years of work")]
    empty = tmp_path / "empty"
    empty.mkdir()
    with staged_folder(empty) as stage:
        (stage / "x.txt").write_text("x")
        (stage / ".tmp-abc.png").write_text("a killed helper's half picture")
    assert sorted(p.name for p in empty.iterdir()) == sorted([MARKER, "x.txt"])  # no temporary file published


CRASH = """
import os, sys
from pathlib import Path
from twinreg.io import outdir
real = os.replace
calls = []
def replace(a, b):
    real(a, b)
    calls.append(b)
    if Path(b).name.startswith(".out.old-"):
        os._exit(9)  # killed between the two renames of the swap
outdir.os.replace = replace
with outdir.staged_folder(Path(sys.argv[1])) as stage:
    (stage / "twin.json").write_text("new")
"""


def test_a_run_killed_between_the_renames_is_finished_by_the_next(tmp_path):
    out = tmp_path / "out"
    with staged_folder(out) as stage:
        (stage / "twin.json").write_text("old")
    proc = subprocess.run([sys.executable, "-c", CRASH, str(out)], capture_output=True, text=True)
    assert proc.returncode == 9, proc.stderr
    assert not out.exists()  # the crash left OUT missing, with the journal beside it
    assert (tmp_path / ".out.swap").exists()
    assert recover(out) == "finished"
    assert (out / "twin.json").read_text() == "new"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]
    # and the next run through staged_folder does the same by itself
    proc = subprocess.run([sys.executable, "-c", CRASH, str(out)], capture_output=True, text=True)
    assert proc.returncode == 9 and not out.exists()
    with staged_folder(out) as stage:
        (stage / "twin.json").write_text("third")
    assert (out / "twin.json").read_text() == "third"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]


def test_a_failed_run_leaves_the_old_folder(tmp_path):
    out = tmp_path / "out"
    with staged_folder(out) as stage:
        (stage / "twin.json").write_text("old")
    with pytest.raises(RuntimeError):
        with staged_folder(out) as stage:
            (stage / "twin.json").write_text("half")
            raise RuntimeError("export failed")
    assert (out / "twin.json").read_text() == "old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]


def test_the_listing_is_every_file_as_rglob_lists_it(tmp_path):
    """The marker's listing (os.walk) names what ``Path.rglob`` names: files, hidden ones, links to files and
    broken links; a link to a folder is not followed."""
    import os

    from twinreg.io.outdir import _listing

    (tmp_path / "a" / "b").mkdir(parents=True)
    (tmp_path / "a" / "b" / "f.txt").write_text("x")
    (tmp_path / ".hidden").write_text("y")
    (tmp_path / "c").mkdir()
    os.symlink(tmp_path / "a", tmp_path / "c" / "to_folder")
    os.symlink(tmp_path / "a" / "b" / "f.txt", tmp_path / "c" / "to_file")
    os.symlink(tmp_path / "missing", tmp_path / "broken")
    want = sorted(str(p.relative_to(tmp_path)) for p in tmp_path.rglob("*") if not p.is_dir())
    assert _listing(tmp_path) == want == [".hidden", "a/b/f.txt", "broken", "c/to_file"]


def _staged(target, kind, protect=()):
    with staged_folder(target, protect=protect, kind=kind) as stage:
        (stage / f"{kind.replace(' ', '_')}.json").write_text("{}")


def test_a_folder_of_another_kind_is_not_replaced(tmp_path):
    """A twin (a city twin can be half an hour of work) is not replaced by a comparison, nor the reverse; an older
    marker without a kind is judged by its files."""
    twin, changes = tmp_path / "twin", tmp_path / "changes"
    _staged(twin, "twin")
    _staged(changes, "comparison")
    assert json.loads((twin / MARKER).read_text())["kind"] == "twin"
    before = listing(twin)
    with pytest.raises(ExportError, match=r"holds a twin \(written by twinreg build-twin\).*with a comparison"):
        _staged(twin, "comparison")
    with pytest.raises(ExportError, match=r"holds a comparison \(written by twinreg compare\)"):
        _staged(changes, "twin")
    assert listing(twin) == before
    old = tmp_path / "old"
    _staged(old, "twin")
    (old / "twin.json").write_text("{}")
    marker = json.loads((old / MARKER).read_text())
    (old / MARKER).write_text(json.dumps({"tool": "twinreg", "files": marker["files"] + ["twin.json"]}))
    with pytest.raises(ExportError, match="holds a twin"):
        _staged(old, "comparison")
    _staged(twin, "twin")  # the same kind is replaced as before


def test_out_inside_an_input_or_the_catalogue_is_refused(tmp_path):
    twin, lib = tmp_path / "twin", tmp_path / "library"
    _staged(twin, "twin")
    lib.mkdir()
    for inside in (twin / "changes", lib / "changes"):
        with pytest.raises(ExportError, match="lies inside"):
            _staged(inside, "comparison", protect=[twin, lib])
        assert not inside.exists()


def test_a_second_run_on_the_same_out_is_refused(tmp_path):
    """While one run holds OUT, another is refused at once, naming it; the lock goes with the run (killed or
    not) and leaves no file."""
    from twinreg.io.outdir import locked

    out = tmp_path / "out"
    holder = subprocess.Popen([sys.executable, "-c", "import sys, time\nfrom twinreg.io.outdir import locked\n"
                               f"with locked({str(out)!r}, 'build-twin'):\n    print('held', flush=True)\n"
                               "    time.sleep(60)\n"], stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "held"
        with pytest.raises(ExportError, match=rf"another twinreg run is writing this folder \(process {holder.pid}, "
                                              r"twinreg build-twin, started 20"):
            with locked(out, "compare"):
                pass
    finally:
        holder.kill()
        holder.wait()
    with locked(out, "compare"):  # a killed holder's lock is gone with it
        pass
    assert not any(p.name.endswith(".lock") for p in tmp_path.iterdir())


def test_a_killed_runs_staging_is_cleared_by_the_next_write_beside_it(tmp_path):
    """kill -9 during the staging of one OUT: the hidden staging folder is removed by the next command writing
    anything beside it (not only to that OUT)."""
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True,
                          text=True).stdout.strip()
    left = tmp_path / f".changes.tmp-{dead}-abcd1234"
    left.mkdir()
    (left / "changes.json").write_text("{}")
    alive = tmp_path / f".other.tmp-{__import__('os').getpid()}-abcd1234"
    alive.mkdir()
    _staged(tmp_path / "twin", "twin")
    assert not left.exists() and alive.exists()
