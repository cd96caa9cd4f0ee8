"""A scene's objects described and matched in two processes (twinreg/detect.py ``described``, twinreg/matching/
match.py ``match_objects(split=True)``): about half of them in a child forked for it, on the other core. The answers
are those of one process, to the bit (every value compared); a child that dies leaves its half to this process, with the same answers.

The matching's split runs only where open3d has started no thread yet (a fresh process: a forked child cannot use
the pools of its parent's), so it is tested in a process of its own, on a real KITTI sweep (99 objects, the shared cars and furniture catalogued)."""

from __future__ import annotations

import os
import pickle
import subprocess
import sys

import pytest

from tests.conftest import KITTI, need

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))))

#: run in a fresh interpreter: argv = library, scan, mode ("split", "serial" or "child dies"), output pickle
SCRIPT = r"""
import os, pickle, sys
from pathlib import Path
from twinreg.catalogue.repository import Catalogue
from twinreg.detect import described, detect_file
from twinreg.matching.acceptance import scene_noise
from twinreg.matching.match import Evidence, ModelCache, match_objects
from twinreg.stages import taxonomy, with_targets
from twinreg.settings import DEFAULT
from cosco.arrays import point_spacing

lib, scan, mode, out = sys.argv[1:5]
if mode == "child dies":  # a real child, killed before it answers: its half is matched here
    import twinreg.process.helpers as helpers

    class Dying(helpers.Forked):
        def __init__(self, fn, *args):
            def die(*a):
                os._exit(3)
            super().__init__(die, *args)
            self.fn = fn

    helpers.Forked = Dying
cat = Catalogue(lib, create=False)
params = with_targets(cat, DEFAULT)
det = detect_file(Path(scan), params=params)
shapes, clouds, levels = described(det, params)
spacing = [point_spacing(c) for c in clouds]
clusters = taxonomy(shapes, params, {}, None, spacing=spacing)
results, stats = match_objects(shapes, cat, labels=clusters.labels, params=params,
                               evidence=Evidence(clouds, scene_noise(det.hag, det.is_ground)),
                               cache=ModelCache(cat, params), split=mode != "serial")
Path(out).write_bytes(pickle.dumps({"results": [pickle.dumps(r) for r in results], "n": len(shapes),
                                    "forked": stats.n_forked, "trials": stats.n_trials,
                                    "decided_by_type": stats.n_type_decided}))
"""


def differences(a, b, path: str = "") -> list[str]:
    """Where two answers differ in value, to the bit (floats by their repr, arrays by dtype, shape and bytes); which
    objects they share is not compared (a model's frame cached before or after an object's decision)."""
    import dataclasses

    import numpy as np

    if type(a) is not type(b):
        return [f"{path}: {type(a).__name__} / {type(b).__name__}"]
    if dataclasses.is_dataclass(a):
        return [d for f in dataclasses.fields(a) for d in differences(getattr(a, f.name), getattr(b, f.name),
                                                                       f"{path}.{f.name}")]
    if isinstance(a, dict):
        if list(a) != list(b):
            return [f"{path}: keys"]
        return [d for k in a for d in differences(a[k], b[k], f"{path}[{k!r}]")]
    if isinstance(a, (list, tuple)):
        if len(a) != len(b):
            return [f"{path}: length"]
        return [d for k, (x, y) in enumerate(zip(a, b)) for d in differences(x, y, f"{path}[{k}]")]
    if isinstance(a, np.ndarray):
        same = a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes()
        return [] if same else [f"{path}: array"]
    if isinstance(a, (float, np.floating)):
        return [] if repr(a) == repr(b) else [f"{path}: {a!r} / {b!r}"]
    if isinstance(a, (str, bytes, int, bool, type(None), np.integer, np.bool_, frozenset, set)):
        return [] if a == b else [f"{path}: {a!r} / {b!r}"]
    if hasattr(a, "__dict__"):
        return differences(vars(a), vars(b), path)
    return [] if a == b else [f"{path}: {a!r} / {b!r}"]


def _run(library, scan, mode: str, out) -> dict:
    env = {k: v for k, v in os.environ.items() if k not in ("TWINREG_NO_HELPER", "TWINREG_JIT")}
    res = subprocess.run([sys.executable, "-c", SCRIPT, str(library), str(scan), mode, str(out)], cwd=REPO, env=env,
                         capture_output=True, text=True, timeout=600)
    assert res.returncode == 0, res.stderr[-2000:]
    return pickle.loads(out.read_bytes())


@pytest.fixture(scope="module")
def sweep():
    return need(KITTI / "velodyne" / "000000.bin")


def test_a_sweeps_matching_split_with_a_forked_child_gives_the_answers_of_one_process(city_catalogue, sweep, tmp_path):
    serial = _run(city_catalogue, sweep, "serial", tmp_path / "serial.pkl")
    split = _run(city_catalogue, sweep, "split", tmp_path / "split.pkl")
    dies = _run(city_catalogue, sweep, "child dies", tmp_path / "dies.pkl")
    assert serial["n"] >= 30 and serial["forked"] == 0
    # a real share of the objects went to the child (their clusters whole), and came back
    assert 0.2 * serial["n"] <= split["forked"] <= 0.8 * serial["n"], split["forked"]
    assert dies["forked"] == 0
    for run in (split, dies):
        assert run["trials"] == serial["trials"] and run["decided_by_type"] == serial["decided_by_type"]
        differ = [d for a, b in zip(serial["results"], run["results"])
                  for d in differences(pickle.loads(a), pickle.loads(b))]
        assert not differ, differ[:10]


def test_a_sweeps_objects_described_in_two_processes_are_described_as_in_one(city_catalogue, sweep, monkeypatch):
    """The objects' shapes, points and levels, to the bit, whichever process described them; the child's half is
    about half of them by their points."""
    import twinreg.process.helpers as helpers
    from twinreg.detect import described, detect_file
    from twinreg.settings import DEFAULT
    from twinreg.stages import with_targets

    children = []

    class Counted(helpers.Forked):
        def wait(self, timeout=helpers.HELPER_TIMEOUT_S):
            value = super().wait(timeout)
            children.append((self.ran_apart, len(value)))
            return value

    monkeypatch.delenv("TWINREG_NO_HELPER", raising=False)
    monkeypatch.setattr(helpers, "Forked", Counted)
    from twinreg.catalogue.repository import Catalogue

    params = with_targets(Catalogue(city_catalogue, create=False), DEFAULT)
    det = detect_file(sweep, params=params)
    one = described(det, params)
    two = described(det, params, split=True)
    n = len(det.objects)
    assert n >= 30 and children and children[0][0] and 0.2 * n <= children[0][1] <= 0.8 * n, (children, n)
    assert all(len(a) == n for a in one + two)
    assert not differences(one, two)
