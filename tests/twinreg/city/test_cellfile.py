"""Resumable cells are data (issue 19): a cell's result goes to an npz of arrays and JSON and comes back equal; a
pickle, an npz holding Python objects, or JSON naming another class, planted in OUT/.cells under a cell's name, is
refused unread (never executed) and the cell is computed again."""

from __future__ import annotations

import json
import pickle

import numpy as np
import pytest

from cosco import describe_object
from tests.conftest import toy_car
from twinreg.io.observed import raster
from twinreg.city.cellfile import FORMAT, load, load_clouds, save
from twinreg.city.cells import CellObject, CellResult
from twinreg.city.resume import CellStore
from twinreg.errors import CellFileError


def _result() -> CellResult:
    pts = toy_car(3)
    shape = describe_object(pts)
    obj = CellObject(id="c0_0-1", cell="c0_0", offset=np.array([100.0, 200.0, 0.0]), n_points=len(pts),
                     shape=shape, cloud=pts[:50], spacing=0.05, ground_z=0.0)
    return CellResult("c0_0", "k123", (0.0, 0.0), (50.0, 50.0), n_read=10, n_points=9, objects=[obj],
                      timing_s={"read": 0.1},
                      observed=raster(pts + [10.0, 10.0, 0.0], pts[:, 2], pts[:, 2] < 0.1, (0.0, 0.0), (50.0, 50.0)),
                      scan_tiles={"folder": "x", "centre": [1.0, 2.0, 3.0], "lo": [0.0] * 3, "hi": [1.0] * 3, "n": 3,
                                  "error": 0.5, "uri": "c0_0.json"})


def test_a_cell_result_comes_back_equal(tmp_path):
    r = _result()
    back = load(save(r, tmp_path / "c0_0-k123.npz"))
    assert back.name == r.name and back.key == r.key and back.lo == r.lo and back.timing_s == r.timing_s
    a, b = r.objects[0], back.objects[0]
    assert a.id == b.id and np.array_equal(a.cloud, b.cloud) and np.array_equal(a.offset, b.offset)
    assert a.shape.size == b.shape.size and a.shape.symmetry == b.shape.symmetry
    assert np.array_equal(a.shape.sections.longitudinal, b.shape.sections.longitudinal)
    assert a.shape.frame.heading == b.shape.frame.heading
    assert back.scan_tiles == r.scan_tiles
    assert np.array_equal(back.observed.code, r.observed.code) and back.observed.z0 == r.observed.z0
    assert (back.observed.code != 255).sum() > 10


def test_point_samples_stay_in_the_file_until_asked_for(tmp_path):
    """The run's main process loads the cells without their objects' point samples; a worker reads the samples
    it matches, and they are the ones saved. An index the file does not hold is refused."""
    from dataclasses import replace

    r = _result()
    second = replace(r.objects[0], id="c0_0-2", cloud=r.objects[0].cloud[:20] + 1.0)
    r.objects.append(second)
    path = save(r, tmp_path / "c0_0-k123.npz")
    light = load(path, clouds=False)
    assert [o.cloud for o in light.objects] == [None, None]
    assert np.array_equal(light.objects[1].shape.sections.longitudinal, r.objects[1].shape.sections.longitudinal)
    got = load_clouds(path, [1, 0, 1])
    assert np.array_equal(got[0], second.cloud) and np.array_equal(got[1], r.objects[0].cloud)
    assert np.array_equal(got[2], second.cloud)
    for bad in ([2], [-1]):
        with pytest.raises(CellFileError):
            load_clouds(path, bad)
    (tmp_path / "other.npz").write_bytes(pickle.dumps({"x": 1}))
    with pytest.raises(CellFileError):
        load_clouds(tmp_path / "other.npz", [0])
    # a file whose document names a sample it does not hold is refused when loaded, as a full load refuses it
    z = np.load(path, allow_pickle=False)
    doc = json.loads(z["__doc__"].tobytes().decode("utf-8"))
    key = doc["result"]["fields"]["objects"][1]["fields"]["cloud"]["$array"]
    kept = {k: z[k] for k in z.files if k != key}
    z.close()
    broken = tmp_path / "broken.npz"
    with open(broken, "wb") as fh:
        np.savez(fh, **kept)
    for clouds in (True, False):
        with pytest.raises(CellFileError):
            load(broken, clouds=clouds)


def test_planted_files_are_refused_and_never_run(tmp_path):
    store = CellStore(tmp_path)
    store.folder.mkdir()
    marker = tmp_path / "ran"

    class Payload:
        def __reduce__(self):
            return (open, (str(marker), "w"))

    target = store.path("c0_0", "k123")
    for what in ("pickle", "object npz", "foreign class", "broken zip"):
        if what == "broken zip":
            target.write_bytes(b"PK\x03\x04 a zip's magic and nothing else")
        elif what == "pickle":
            target.write_bytes(pickle.dumps(Payload()))
        elif what == "object npz":
            np.savez(target, __doc__=np.array([Payload()], dtype=object))
        else:
            doc = {"format": FORMAT, "result": {"$class": "Popen", "fields": {"args": "touch x"}}}
            np.savez(target, __doc__=np.frombuffer(json.dumps(doc).encode(), dtype=np.uint8))
        assert not store.has("c0_0", "k123"), what
        assert not target.exists(), what  # forgotten: the cell is computed again
    assert not marker.exists()
    # a well-formed file with another class inside is refused when loaded too
    doc = {"format": FORMAT, "result": {"$class": "CellResult", "fields": {
        "name": "c0_0", "key": "k123", "lo": [0, 0], "hi": [1, 1], "objects": [{"$class": "Popen", "fields": {}}]}}}
    np.savez(target, __doc__=np.frombuffer(json.dumps(doc).encode(), dtype=np.uint8))
    try:
        load(target)
        raise AssertionError("a foreign class was loaded")
    except CellFileError:
        pass
    save(_result(), target)
    assert not store.has("c0_0", "k123")  # a result without its scan tiles is computed again
    (store.scan_folder() / "c0_0-k123").mkdir(parents=True)
    assert store.has("c0_0", "k123") and not store.has("c0_0", "other")
