"""Every bad input of issue 19 is one line naming the file and the fix, exit 1 (2 for usage), nothing left behind;
names are written as UTF-8."""

from __future__ import annotations

import errno
import json
import os
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from tests.conftest import write_las
from twinreg.cli import app
from twinreg.io.ply import write_ply


def _invoke(*args):
    return CliRunner().invoke(app, [str(a) for a in args])


def _one_line_error(res, code: int, *words):
    assert res.exit_code == code, res.output
    text = res.output.strip()
    assert text.startswith("error:") and len(text.splitlines()) == 1, text
    assert "unexpected" not in text and "Traceback" not in text, text
    for w in words:
        assert w in text, (w, text)


@pytest.fixture(scope="module")
def park(tmp_path_factory) -> Path:
    from twinreg.sim.parametric import LIBRARY, car_mesh
    from twinreg.sim.scan import car_park

    folder = tmp_path_factory.mktemp("park")
    p = car_park([car_mesh(LIBRARY[2])], n_cars=2, seed=1, distractors=False)
    write_ply(folder / "park.ply", p.points)
    return folder / "park.ply"


def test_a_scene_with_a_non_ascii_name_builds_and_keeps_its_name(park, parametric_catalogue, tmp_path):
    scene = tmp_path / "scän ü.ply"
    scene.write_bytes(park.read_bytes())
    out = tmp_path / "twin"
    res = _invoke("build-twin", scene, "--lat", "53.35", "--lon", "-6.26", "--library", parametric_catalogue.folder,
                  "--out", out, "--json")
    assert res.exit_code == 0, res.output
    assert json.loads((out / "twin.json").read_text(encoding="utf-8"))["scene"] == "scän ü.ply"
    header = (out / "twin.ply").read_bytes().split(b"end_header")[0].decode("utf-8")
    assert "scän ü.ply" in header
    assert not [p for p in tmp_path.iterdir() if ".tmp" in p.name]


def test_a_failure_after_the_pictures_leaves_no_stage_behind(park, parametric_catalogue, tmp_path, monkeypatch):
    """The picture helper draws into the stage while the twin is written: a failure then stops it before the
    stage is deleted, so nothing is left beside OUT."""
    import twinreg.pipeline as pipeline

    def broken(*args, **kwargs):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(pipeline, "write_twin", broken)
    out = tmp_path / "twin"
    res = _invoke("build-twin", park, "--lat", "53.35", "--lon", "-6.26", "--library", parametric_catalogue.folder,
                  "--out", out)
    _one_line_error(res, 1, str(out), "free space")
    assert sorted(p.name for p in tmp_path.iterdir()) == []


@pytest.mark.parametrize("count", ["1000000000000", "-5", "1e12", "x"])
def test_a_ply_header_with_an_impossible_count(tmp_path, count):
    bad = tmp_path / "bad.ply"
    bad.write_bytes(f"ply\nformat binary_little_endian 1.0\nelement vertex {count}\nproperty double x\n"
                    "property double y\nproperty double z\nend_header\n".encode() + bytes(240))
    _one_line_error(_invoke("detect", bad, "--json"), 1, "bad.ply", "header")


def test_a_point_at_1e300(tmp_path, park):
    from twinreg.io.points import read_points

    pts = read_points(park).points
    pts[0] = [1e300, 0.0, 0.0]
    bad = tmp_path / "far.xyz"
    np.savetxt(bad, pts)
    _one_line_error(_invoke("detect", bad, "--json"), 1, "far.xyz", "beyond")


@pytest.mark.parametrize("what", ["zero", "negative", "offset"])
def test_las_headers_with_impossible_scales_or_offsets(tmp_path, what):
    import laspy

    pts = np.random.default_rng(0).uniform(0, 10, (500, 3)) + [500000.0, 5000000.0, 10.0]
    path = write_las(tmp_path / "s.las", pts, crs="EPSG:32629")
    las = laspy.read(path)
    if what == "zero":
        las.header.scales = np.array([0.0, 0.001, 0.001])
    elif what == "negative":
        las.header.scales = np.array([-0.001, 0.001, 0.001])
    else:
        las.header.offsets = np.array([1e30, 0.0, 0.0])
    las.write(tmp_path / "bad.las")
    _one_line_error(_invoke("detect", tmp_path / "bad.las", "--json"), 1, "bad.las", "pdal")


@pytest.mark.parametrize("opts", [["--anchor", "nan", "0"], ["--alt", "inf"], ["--anchor", "0", "1e300"]])
def test_georeference_options_that_are_not_numbers(park, parametric_catalogue, tmp_path, opts):
    out = tmp_path / "twin"
    res = _invoke("build-twin", park, "--lat", "53.35", "--lon", "-6.26", *opts, "--library",
                  parametric_catalogue.folder, "--out", out)
    _one_line_error(res, 1, "not a finite number")
    assert not out.exists()


def test_a_file_given_as_the_library(tmp_path):
    f = tmp_path / "lib.txt"
    f.write_text("not a folder")
    _one_line_error(_invoke("list-models", "--library", f), 1, "lib.txt", "not a catalogue folder")


def test_a_refused_command_leaves_no_new_catalogue(tmp_path):
    lib = tmp_path / "newlib"
    bad = tmp_path / "broken.obj"
    bad.write_text("this is not geometry\n")
    assert _invoke("add-model", bad, "--library", lib).exit_code == 1
    assert not lib.exists()
    assert _invoke("import-library", tmp_path / "missing.zip", "--library", lib).exit_code != 0
    assert not lib.exists()


def test_a_symlinked_out_keeps_its_link(park, parametric_catalogue, tmp_path):
    real = tmp_path / "real_out"
    link = tmp_path / "out"
    link.symlink_to(real, target_is_directory=True)
    for _ in range(2):  # the first run creates the folder the link names, the second replaces it
        res = _invoke("build-twin", park, "--lat", "53.35", "--lon", "-6.26", "--library",
                      parametric_catalogue.folder, "--out", link)
        assert res.exit_code == 0, res.output
    assert link.is_symlink() and (link / "twin.json").is_file() and (real / "twin.json").is_file()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out", "real_out"]


def test_a_full_disk_names_the_folder(tmp_path, monkeypatch):
    """ENOSPC while the output is written: one line with OUT and the fix, OUT as it was."""
    from twinreg.errors import ExportError
    from twinreg.io.outdir import staged_folder

    out = tmp_path / "out"
    with pytest.raises(ExportError, match="out: cannot write the output: No space left on device.*free space"):
        with staged_folder(out) as stage:
            (stage / "a.txt").write_text("x")
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
    assert not out.exists() and list(tmp_path.iterdir()) == []


def test_a_catalogue_on_a_full_disk_is_not_called_unusable(tmp_path, monkeypatch):
    import sqlite3

    from twinreg.catalogue import db
    from twinreg.errors import CatalogueError

    def full(*args, **kwargs):
        raise sqlite3.OperationalError("database or disk is full")

    monkeypatch.setattr(db, "_upgrade_to_head", full)
    with pytest.raises(CatalogueError, match="cannot be written.*free space"):
        db.open_engine(tmp_path / "lib")


def test_a_full_disk_while_adding_a_model(parametric_objs, tmp_path, monkeypatch):
    """ENOSPC while the model's file is copied in: one line naming the file and the fix, no row, no file."""
    import shutil

    from twinreg.catalogue.repository import Catalogue

    lib = tmp_path / "lib"
    Catalogue(lib).add(parametric_objs["demo_sedan"], name="first")
    before = sorted(p.name for p in lib.rglob("*") if p.is_file() and not p.name.endswith(("-shm", "-wal")))

    def full(src, dst, *args, **kwargs):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(dst))

    monkeypatch.setattr(shutil, "copyfile", full)
    res = _invoke("add-model", parametric_objs["demo_suv"], "--library", lib)
    _one_line_error(res, 1, "No space left on device", str(lib), "free space")
    assert [r.name for r in Catalogue(lib).list()] == ["first"]
    after = sorted(p.name for p in lib.rglob("*") if p.is_file() and not p.name.endswith(("-shm", "-wal")))
    assert after == before
