"""The observation record (observed.npz): written and read back the same, looked up pixel by pixel, and refused
from its members' headers when it is not what build-twin writes (before anything is decompressed)."""

from __future__ import annotations

import io
import zipfile

import numpy as np
import pytest

from cosco.sections import Sections
from twinreg.errors import RecordError
from twinreg.io import observed


def _record(tmp_path):
    rng = np.random.default_rng(0)
    pts = np.column_stack([rng.uniform(0, 20, 5000), rng.uniform(0, 10, 5000), rng.uniform(0, 2, 5000)])
    ground = pts[:, 2] < 0.3
    hag = np.where(ground, 0.0, pts[:, 2])
    r = observed.raster(pts, hag, ground, pts.min(0), pts.max(0) + 1e-6)
    secs = [Sections(rng.normal(size=(40, 2)), rng.normal(size=(12, 2)), 0.05) for _ in range(3)]
    doc = observed.write(tmp_path / observed.FILE, [r], secs)
    return r, secs, doc


def test_written_and_read_back_the_same(tmp_path):
    r, secs, doc = _record(tmp_path)
    assert doc["format"] == observed.FORMAT and doc["rasters"] == 1 and doc["area_seen_m2"] > 150
    back = observed.read(tmp_path / observed.FILE, 3)
    assert np.array_equal(back.rasters[0].code, r.code) and np.allclose(back.rasters[0].lo, r.lo)
    assert all(np.allclose(a.longitudinal, b.longitudinal, atol=1e-6) for a, b in zip(back.sections, secs))
    code, ground = back.lookup(np.array([[5.0, 5.0], [500.0, 5.0]]))
    assert code[0] != observed.NONE and code[1] == observed.NONE and np.isnan(ground[1])
    with pytest.raises(RecordError, match="do not match the twin's 4 objects"):
        observed.read(tmp_path / observed.FILE, 4)


def _rewrite(path, change):
    """The record with its members' headers changed by ``change(name, dtype, shape)`` -> (dtype, shape) or None
    (dropped), each member only a header (what a bomb's directory says)."""
    with np.load(path) as z:
        members = {k: (z[k].dtype, z[k].shape) for k in z.files}
    out = {}
    for name, (dt, shape) in members.items():
        got = change(name, dt, shape)
        if got is not None:
            out[name] = got
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as zf:
        for name, (dt, shape) in out.items():
            buf = io.BytesIO()
            np.lib.format.write_array_header_2_0(buf, {"descr": np.dtype(dt).str, "fortran_order": False,
                                                       "shape": shape})
            zf.writestr(f"{name}.npy", buf.getvalue())


@pytest.mark.parametrize("change,words", [
    (lambda n, d, s: ("u1", (30000, 10)) if n == "code0" else (d, s), "at most 20000 a side"),
    (lambda n, d, s: ("f8", s) if n == "code0" else (d, s), "is not a u1 array"),
    (lambda n, d, s: None if n == "sec_res" else (d, s), "has no sec_res"),
    (lambda n, d, s: ("f4", (3 * 4096 + 1, 2)) if n == "sec_lon" else (d, s), "more points than 3 objects"),
    (lambda n, d, s: (d, (20000, 20000)) if n in ("code0", "ground0") else (d, s), "would take 1,907 MB"),
])
def test_refused_from_the_headers(tmp_path, change, words):
    _record(tmp_path)
    _rewrite(tmp_path / observed.FILE, change)
    with pytest.raises(RecordError, match=words):
        observed.read(tmp_path / observed.FILE, 3)
