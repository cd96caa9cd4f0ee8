"""A scene's cosco stages in this process by both paths (the ``kernel_path`` fixture): the ground, the far
outliers, the segmentation, every object's description and level of symmetry are the same with the numpy
references and with the compiled kernels."""

from __future__ import annotations

import numpy as np
import pytest

import cosco
from cosco.ground import remove_ground
from cosco.levels import symmetry_level
from cosco.params import DEFAULT
from cosco.segment import far_outliers, segment_objects
from tests.conftest import toy_car

_RESULTS: dict = {}


def _scene() -> np.ndarray:
    rng = np.random.default_rng(7)
    ground = np.c_[rng.uniform(-15, 15, (30000, 2)), rng.normal(0, 0.02, 30000)]
    cars = [toy_car(seed) + [x, y, 0.0] for seed, (x, y) in enumerate([(-6, -3), (0, 4), (7, -2)])]
    pole = np.c_[rng.normal(9, 0.05, (400, 2)), rng.uniform(0, 6, 400)]
    stray = np.array([[2000.0, 0.0, 5.0]])
    return np.vstack([ground, *cars, pole, stray])


def _run() -> dict:
    pts = _scene()
    far = far_outliers(pts)
    kept = pts[~far]
    is_ground, hag, _ = remove_ground(kept)
    seg = segment_objects(kept, hag, DEFAULT.with_(segment={"targets": "all"}), is_ground=is_ground)
    shapes = [cosco.describe_object(kept[o.indices], DEFAULT) for o in seg.objects if o.target]
    levels = [symmetry_level(kept[o.indices], DEFAULT).level for o in seg.objects if o.target]
    return {"far": far, "ground": is_ground, "hag": hag, "labels": seg.labels,
            "shapes": [(s.size.as_array(), s.heading, s.symmetry.pcr, s.sections.longitudinal) for s in shapes],
            "levels": levels}


def test_a_scene_is_the_same_by_both_paths(kernel_path):
    _RESULTS[kernel_path] = got = _run()
    assert got["far"].sum() == 1 and len(got["shapes"]) >= 3
    if len(_RESULTS) < 2:  # compared once both paths have run (numpy first)
        return
    a, b = _RESULTS["numpy"], _RESULTS["compiled"]
    for key in ("far", "ground", "labels"):
        assert np.array_equal(a[key], b[key]), key
    assert np.allclose(a["hag"], b["hag"], rtol=0, atol=1e-12)
    assert a["levels"] == b["levels"]
    for (sa, ha, pa, la), (sb, hb, pb, lb) in zip(a["shapes"], b["shapes"]):
        assert np.allclose(sa, sb, atol=1e-9) and abs(ha - hb) < 1e-9 and abs(pa - pb) < 1e-9
        assert np.allclose(la, lb, atol=1e-9)


def test_the_kernels_switched_on_between_the_components_and_their_passes(monkeypatch):
    """What build-twin does on a street sweep (``Settings.jit_min_components``): the segmentation tells its caller
    how many components it found before it joins and cuts them, and the kernels turned on there give the
    references' objects."""
    from cosco import kernels

    monkeypatch.setattr(kernels, "_STATE", {})
    monkeypatch.delenv("TWINREG_JIT", raising=False)
    monkeypatch.delenv("TWINREG_NO_NUMBA", raising=False)
    pts = _scene()
    kept = pts[~far_outliers(pts)]
    is_ground, hag, _ = remove_ground(kept)
    params = DEFAULT.with_(segment={"targets": "all"})
    assert not kernels.in_use()
    reference = segment_objects(kept, hag, params, is_ground=is_ground)
    counts = []

    def switch(n: int) -> None:
        counts.append((n, kernels.in_use()))
        kernels.enable()

    switched = segment_objects(kept, hag, params, is_ground=is_ground, on_components=switch)
    if not kernels.in_use():
        pytest.skip("numba is not installed")
    assert counts == [(reference.n_components, False)]
    assert np.array_equal(switched.labels, reference.labels)
    assert [o.indices.tolist() for o in switched.objects] == [o.indices.tolist() for o in reference.objects]
    assert np.allclose([(o.length, o.width, o.height) for o in switched.objects],
                       [(o.length, o.width, o.height) for o in reference.objects], rtol=0, atol=1e-9)


def test_kernels_left_for_later_load_on_their_first_call(monkeypatch):
    """``enable(later=...)`` (a scene past its ground and components, twinreg.pipeline.DETECTED) loads no such
    kernel; a later call of one loads it then, as ``enable`` would have, and its answers are the references'."""
    from cosco import kernels
    from twinreg import KERNEL_MODULES
    from twinreg.pipeline import DETECTED

    monkeypatch.setattr(kernels, "_STATE", {})
    monkeypatch.delenv("TWINREG_JIT", raising=False)
    monkeypatch.delenv("TWINREG_NO_NUMBA", raising=False)
    kernels.enable(*KERNEL_MODULES, later=DETECTED)
    if not kernels.in_use():
        pytest.skip("numba is not installed")
    names = [k.name for k in kernels.kernels()]
    assert all(any(n.startswith(p) for n in names) for p in DETECTED), DETECTED  # every prefix names a kernel
    later = {n for n in names if n.startswith(DETECTED)}
    assert later and later == kernels._STATE["later"] and not later & kernels._STATE["warmed"]
    assert set(names) - later <= kernels._STATE["warmed"]
    pts = _scene()
    kept = pts[~far_outliers(pts)]
    compiled = remove_ground(kept)
    used = {"cosco.ground.blocks._block_counts_fast", "cosco.ground.window._cell_lowest_fast"}
    assert used <= kernels._STATE["warmed"]
    with kernels.reference_only():
        reference = remove_ground(kept)
    assert np.array_equal(compiled[0], reference[0]) and np.array_equal(compiled[1], reference[1])


def test_a_preload_loads_on_its_thread_and_enable_takes_them_from_there(monkeypatch):
    """``preload`` (build-twin on a sweep, as soon as it is read) loads the kernels on a thread while this one goes
    on with the references; ``enable`` at the components waits for it and warms nothing twice, and the objects are
    the references'."""
    from cosco import kernels
    from twinreg import KERNEL_MODULES
    from twinreg.pipeline import DETECTED

    monkeypatch.setattr(kernels, "_STATE", {})
    monkeypatch.delenv("TWINREG_JIT", raising=False)
    monkeypatch.delenv("TWINREG_NO_NUMBA", raising=False)
    if kernels._numba() is None:
        pytest.skip("numba is not installed")
    pts = _scene()
    kept = pts[~far_outliers(pts)]
    is_ground, hag, _ = remove_ground(kept)
    params = DEFAULT.with_(segment={"targets": "all"})
    reference = segment_objects(kept, hag, params, is_ground=is_ground)
    assert kernels.preload(*KERNEL_MODULES, later=DETECTED)
    assert not kernels.preload(*KERNEL_MODULES, later=DETECTED)  # one thread
    assert not kernels.in_use()  # this thread keeps the references until enable
    seen = []

    def switch(n: int) -> None:
        seen.append(kernels.in_use())
        kernels.enable(*KERNEL_MODULES, later=DETECTED)

    switched = segment_objects(kept, hag, params, is_ground=is_ground, on_components=switch)
    assert seen == [False] and kernels.in_use() and "preload" not in kernels._STATE
    assert "preload_error" not in kernels._STATE
    names = {k.name for k in kernels.kernels()}
    later = {n for n in names if n.startswith(DETECTED)}
    assert names - later <= kernels._STATE["warmed"]
    assert [o.indices.tolist() for o in switched.objects] == [o.indices.tolist() for o in reference.objects]
    assert not kernels.preload(*KERNEL_MODULES)  # enabled: nothing to start
    assert kernels.settle() == 0.0


@pytest.mark.parametrize("value", [None, "", "0", "1", " Yes ", "off", "FALSE", "no", "2"])
def test_the_switches_are_read_as_flag_reads_them_and_followed_at_once(value, monkeypatch):
    """``in_use`` reads TWINREG_NO_NUMBA and TWINREG_JIT from the environment's own store (cosco.kernels._said, at
    every kernel call): what it makes of each value is :func:`cosco.kernels.flag`'s, and a change of the variable
    counts from the next call."""
    from cosco import kernels

    for name in ("TWINREG_JIT", "TWINREG_NO_NUMBA"):
        if value is None:
            monkeypatch.delenv(name, raising=False)
        else:
            monkeypatch.setenv(name, value)
        assert kernels._said(name) == kernels.flag(name)
        monkeypatch.setenv(name, "1")
        assert kernels._said(name)
        monkeypatch.delenv(name)
        assert not kernels._said(name)
