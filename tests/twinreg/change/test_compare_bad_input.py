"""Twins compare refuses, one line each, exit 1, nothing written: twins that do not overlap, twins in different
CRSs (naming both), a folder that is not a twin, a twin written before the observation record, the same twin twice
(by path or as a copy), an observation record that is not data this program wrote; and markup in a stranger's
twin shown as text in the report."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest
from typer.testing import CliRunner

from twinreg.cli import app

runner = CliRunner()


def _copy(src, dst, edit=None):
    shutil.copytree(src, dst)
    if edit:
        doc = json.loads((dst / "twin.json").read_text())
        edit(doc)
        (dst / "twin.json").write_text(json.dumps(doc))
    return dst


def _refused(args, out, *words, exists: bool = False):
    """compare refuses in one line holding ``words``, exit 1; ``out`` does not exist after (or, ``exists``, was
    there before and is left)."""
    r = runner.invoke(app, ["compare", *map(str, args), "--out", str(out)])
    assert r.exit_code == 1, r.output
    line = r.output.strip()
    assert line.startswith("error:") and "\n" not in line, line
    for w in words:
        assert w in line, line
    assert out.exists() == exists
    return line


def test_not_a_twin(surveys, tmp_path):
    (tmp_path / "empty").mkdir()
    _refused([surveys.twins["before"], tmp_path / "empty"], tmp_path / "out", "not a twin folder", "build-twin")


def test_written_before_the_record(surveys, tmp_path):
    old = _copy(surveys.twins["after150"], tmp_path / "old", lambda d: d.pop("observation"))
    (old / "observed.npz").unlink()
    _refused([surveys.twins["before"], old], tmp_path / "out", "no observation record", "rerun `twinreg build-twin`")


def test_the_same_twin_twice(surveys, tmp_path):
    t = surveys.twins["before"]
    _refused([t, t], tmp_path / "out", "given twice")
    copy = _copy(t, tmp_path / "copy")
    _refused([t, copy], tmp_path / "out", "the same twin")


def test_other_crs(surveys, tmp_path):
    def to_itm(doc):
        doc["georef"].update(crs="EPSG:2157", crs_name="IRENET95 / Irish Transverse Mercator", lat=None, lon=None)

    other = _copy(surveys.twins["after150"], tmp_path / "itm", to_itm)
    line = _refused([surveys.twins["before"], other], tmp_path / "out", "Irish Transverse Mercator", "53.35")
    assert "--crs" in line
    moved = _copy(surveys.twins["after150"], tmp_path / "moved", lambda d: d["georef"].update(lat=48.85))
    _refused([surveys.twins["before"], moved], tmp_path / "out", "local frame")


def test_another_vertical_datum_is_converted(surveys, tmp_path):
    """The earlier twin's heights ellipsoidal (EPSG:4979), the later's in EGM96 heights (EPSG:5773: the same
    survey, each height lowered by the undulation at Dublin): compare puts them in one datum and finds what the
    plain pair gives."""
    from twinreg.change.compare import changes_document
    from twinreg.geo.vertical import vertical_of

    n = float(vertical_of("EPSG:5773", "test", "test").undulation(-6.26, 53.35)[0])
    assert 50 < n < 60  # EGM96 at Dublin

    def stated(vertical, dz=0.0):
        def edit(doc):
            doc["georef"].update(vertical_crs=vertical, vertical_source="--vertical-crs")
            for o in doc["objects"]:
                o["centroid"][2] += dz
        return edit

    ell = _copy(surveys.twins["before"], tmp_path / "ell", stated("EPSG:4979"))
    egm = _copy(surveys.twins["after150"], tmp_path / "egm", stated("EPSG:5773", -n))
    with np.load(egm / "observed.npz") as z:
        arrays = {k: z[k] for k in z.files}
    arrays["z0"] = arrays["z0"] - n
    np.savez(egm / "observed.npz", **arrays)
    plain, _ = changes_document([surveys.twins["before"], surveys.twins["after150"]])
    said = []
    got, _ = changes_document([ell, egm], say=said.append)
    h = got["epochs"][1]["heights"]
    assert h["datum"] == "EPSG:5773" and h["to"] == "EPSG:4979" and abs(h["shift_m"] - n) < 0.05, h
    assert h["accuracy_m"] == 1.0 and got["epochs"][0]["heights"]["shift_m"] == 0.0
    assert any("converted to EPSG:4979" in s for s in said), said
    assert abs(got["alignment"][0]["shift"][2] - plain["alignment"][0]["shift"][2]) < 0.02
    def gist(doc):
        return [(c["status"], *((c[k] or {}).get("id") for k in ("before", "after"))) for c in doc["changes"]]

    assert gist(got) == gist(plain)
    for c, p in zip(got["changes"], plain["changes"]):  # the later heights given in the earlier's datum
        if c.get("after"):
            assert abs(c["after"]["centroid"][2] - p["after"]["centroid"][2]) < 0.05


def test_a_vertical_crs_that_is_not_one(surveys, tmp_path):
    def stated(vertical):
        return lambda doc: doc["georef"].update(vertical_crs=vertical, vertical_source="--vertical-crs")

    good = _copy(surveys.twins["before"], tmp_path / "good", stated("EPSG:5773"))
    for k, bad in enumerate(("EPSG:28992", "<script>x</script>")):
        other = _copy(surveys.twins["after150"], tmp_path / f"bad{k}", stated(bad))
        _refused([good, other], tmp_path / "out", str(other), "rerun build-twin")


def test_no_overlap(surveys, tmp_path):
    far = _copy(surveys.twins["after150"], tmp_path / "far")
    with np.load(far / "observed.npz") as z:
        arrays = {k: z[k] for k in z.files}
    arrays["lo"] = arrays["lo"] + 5000.0
    np.savez_compressed(far / "observed.npz", **arrays)
    _refused([surveys.twins["before"], far], tmp_path / "out", "does not overlap", "same place")


def test_record_that_is_not_data(surveys, tmp_path):
    bad = _copy(surveys.twins["after150"], tmp_path / "bad")
    with np.load(bad / "observed.npz") as z:
        arrays = {k: z[k] for k in z.files}
    arrays["code0"] = np.array([{"run": "code"}], dtype=object)
    np.savez(bad / "observed.npz", **arrays)
    _refused([surveys.twins["before"], bad], tmp_path / "out", "observed.npz", "rerun build-twin")
    (bad / "observed.npz").write_bytes(b"PK\x03\x04 not a zip")
    _refused([surveys.twins["before"], bad], tmp_path / "out", "observed.npz")


def test_undated_twins_keep_the_order_given(surveys, tmp_path):
    undated = _copy(surveys.twins["before"], tmp_path / "undated", lambda d: d.update(survey_date=None))
    r = runner.invoke(app, ["--json", "compare", str(surveys.twins["after150"]), str(undated), "--out",
                            str(tmp_path / "out")])
    assert r.exit_code == 0, r.output
    assert "no survey date" in r.output
    doc = json.loads(r.stdout[r.stdout.index("{"):])
    assert [e["date"] for e in doc["epochs"]] == ["2026-06-02", None]


def test_markup_in_a_strangers_twin_is_text(surveys, tmp_path):
    evil = "<img src=x onerror=alert(1)>"

    def inject(doc):
        doc["objects"][0]["id"] = evil
        for o in doc["objects"]:
            o["kind"] = evil
            if o["match"]:
                o["match"]["name"] = evil
        doc["survey_date"] = "2026-06-03"

    t = _copy(surveys.twins["after150"], tmp_path / "evil", inject)
    r = runner.invoke(app, ["compare", str(surveys.twins["before"]), str(t), "--out", str(tmp_path / "out")])
    assert r.exit_code == 0, r.output
    page = (tmp_path / "out" / "changes.html").read_text()
    assert evil not in page and "&lt;img src=x onerror=alert(1)&gt;" in page
    # a kind that is not a kind's word reads unknown
    changes = json.loads((tmp_path / "out" / "changes.json").read_text())["changes"]
    assert {c["after"]["kind"] for c in changes if c["after"] is not None} == {"unknown"}


@pytest.mark.parametrize("date", ["2026-13-01", "yesterday", 20260301])
def test_bad_date_in_twin(surveys, tmp_path, date):
    t = _copy(surveys.twins["after150"], tmp_path / "d", lambda d: d.update(survey_date=date))
    _refused([surveys.twins["before"], t], tmp_path / "out", "survey_date")


def _planted_npz(path, members: dict) -> None:
    """An npz whose members are .npy headers claiming ``shape`` with only a few bytes of data behind them (what a
    bomb's headers say, without the gigabytes): {name: (dtype, shape)}."""
    import io
    import zipfile

    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as zf:
        for name, (dtype, shape) in members.items():
            buf = io.BytesIO()
            np.lib.format.write_array_header_2_0(buf, {"descr": np.dtype(dtype).str, "fortran_order": False,
                                                       "shape": shape})
            zf.writestr(f"{name}.npy", buf.getvalue() + b"\0" * 64)


def _record_members(twin):
    with np.load(twin / "observed.npz") as z:
        return {k: (z[k].dtype, z[k].shape) for k in z.files}


@pytest.mark.parametrize("what", ["rasters", "sections", "extra"])
def test_record_bomb_refused_from_its_headers(surveys, tmp_path, what):
    """A record whose headers claim 8 rasters of 20000 x 20000 (16 GB once read), a (4e8, 2) section array or an
    array it should not hold is refused from its members' headers, before anything is decompressed."""
    import resource
    import time

    bad = _copy(surveys.twins["after150"], tmp_path / "bomb")
    members = _record_members(bad)
    for k in [k for k in members if k.startswith(("code", "ground"))]:
        del members[k]
    if what == "rasters":
        members["lo"] = (np.float64, (8, 2))
        members["z0"] = (np.float64, (8,))
        for k in range(8):
            members[f"code{k}"] = (np.uint8, (20000, 20000))
            members[f"ground{k}"] = (np.float32, (20000, 20000))
    else:
        members["lo"], members["z0"] = (np.float64, (1, 2)), (np.float64, (1,))
        members["code0"], members["ground0"] = (np.uint8, (10, 10)), (np.float32, (10, 10))
        if what == "sections":
            members["sec_lon"] = (np.float32, (400_000_000, 2))
        else:
            members["payload"] = (np.float64, (10,))
    _planted_npz(bad / "observed.npz", members)
    before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    t = time.perf_counter()
    line = _refused([surveys.twins["before"], bad], tmp_path / "out", "observed.npz", "rerun build-twin")
    assert time.perf_counter() - t < 10
    assert resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - before < 200 * 1024  # KiB: nothing was allocated
    assert {"rasters": "would take", "sections": "sections hold more points", "extra": "should not"}[what] in line


def test_twin_json_too_large_or_too_deep(surveys, tmp_path):
    from twinreg.change.epochs import MAX_TWIN_BYTES

    big = _copy(surveys.twins["after150"], tmp_path / "big")
    with open(big / "twin.json", "r+b") as fh:  # a sparse file: no disk, no time
        fh.truncate(MAX_TWIN_BYTES + 1)
    _refused([surveys.twins["before"], big], tmp_path / "out", "twin.json", "larger than")
    deep = _copy(surveys.twins["after150"], tmp_path / "deep")
    (deep / "twin.json").write_text("[" * 200_000 + "]" * 200_000)
    _refused([surveys.twins["before"], deep], tmp_path / "out", "nested deeper")


def _first_object(edit):
    def apply(doc):
        edit(doc["objects"][0], doc)
    return apply


@pytest.mark.parametrize("edit,words", [
    (lambda o, d: d.update(noise_m=-5), "noise_m"),
    (lambda o, d: o["size"].update(length=-4.2), "size"),
    (lambda o, d: o["measured_size"].update(height=1e4), "measured_size"),
    (lambda o, d: o["match"] and o["match"].update(confidence=7.0) or o.update(n_points=2.5), "confidence"),
    (lambda o, d: d["objects"][1].update(id=o["id"]), "two objects with the id"),
])
def test_values_out_of_range(surveys, tmp_path, edit, words):
    t = _copy(surveys.twins["after150"], tmp_path / "t", _first_object(edit))
    _refused([surveys.twins["before"], t], tmp_path / "out", words, "rerun build-twin")


def test_record_height_not_finite(surveys, tmp_path):
    bad = _copy(surveys.twins["after150"], tmp_path / "nan")
    with np.load(bad / "observed.npz") as z:
        arrays = {k: z[k] for k in z.files}
    arrays["z0"] = arrays["z0"] * np.nan
    np.savez(bad / "observed.npz", **arrays)
    _refused([surveys.twins["before"], bad], tmp_path / "out", "observed.npz", "not described consistently")


def test_twins_far_apart_are_said_to_be_other_places(surveys, tmp_path):
    """Twins 8,000 km apart are not of one place: said so, not "rebuild one in the other's CRS"."""
    def to_oregon(doc):
        doc["georef"].update(crs="EPSG:2994", crs_name="NAD83(HARN) / Oregon GIC Lambert (ft)", lat=None, lon=None)
        for o in doc["objects"]:
            o["lat"], o["lon"] = 44.06, -123.07

    far = _copy(surveys.twins["after150"], tmp_path / "oregon", to_oregon)
    line = _refused([surveys.twins["before"], far], tmp_path / "out", "km from", "different places")
    assert "--crs" not in line


def test_out_may_not_be_a_twin_or_inside_one_or_the_catalogue(surveys, tmp_path, parametric_catalogue):
    """compare --out T where T is a twin (a city twin can be half an hour of work), a folder inside an input twin
    or inside the catalogue: refused, nothing changed."""
    before, after = surveys.twins["before"], surveys.twins["after150"]
    other = _copy(after, tmp_path / "other")
    state = sorted((p.name, p.stat().st_mtime_ns) for p in other.iterdir())
    line = _refused([before, after], other, "holds a twin (written by twinreg build-twin)", exists=True)
    assert sorted((p.name, p.stat().st_mtime_ns) for p in other.iterdir()) == state and "--out" in line
    _refused([before, after], after / "changes", "lies inside")
    lib = parametric_catalogue.folder
    r = runner.invoke(app, ["compare", str(before), str(after), "--out", str(lib / "changes"), "--library",
                            str(lib)])
    assert r.exit_code == 1 and "lies inside" in r.output and not (lib / "changes").exists(), r.output
