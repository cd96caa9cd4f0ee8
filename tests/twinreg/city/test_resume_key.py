"""A cell's key hashes only the parameters a cell reads: cells run with a recording copy of the parameters read
nothing else (a street city, whose segmentation reads the most), and a rerun with another model floor or size
tolerance computes no cell again, while a segmentation parameter changes every key."""

from __future__ import annotations

import dataclasses

import pytest

from twinreg.city import engine
from twinreg.city.cellfile import run_cell
from twinreg.city.resume import cell_key, cell_params
from twinreg.settings import DEFAULT

def _recording(params, seen: set):
    """``params`` whose groups record each value read, as ``group.name``, in ``seen`` (and the run's own values by
    name)."""
    def recorder(group_name, group):
        names = {f.name for f in dataclasses.fields(group)}

        class Recording(type(group)):
            def __getattribute__(self, name):
                if name in names:
                    seen.add(f"{group_name}.{name}")
                return object.__getattribute__(self, name)

        return Recording(**{n: getattr(group, n) for n in names})

    groups = {f.name: getattr(params, f.name) for f in dataclasses.fields(params)}
    wrapped = {n: recorder(n, g) if dataclasses.is_dataclass(g) else g for n, g in groups.items()}
    own = {n for n, g in groups.items() if not dataclasses.is_dataclass(g)}

    class RecordingSettings(type(params)):
        def __getattribute__(self, name):
            if name in own:
                seen.add(name)
            return object.__getattribute__(self, name)

    return RecordingSettings(**wrapped)


@pytest.fixture()
def cells_here(monkeypatch):
    """The city engine's cells run in this process, one after the other, with recording parameters; what they
    read and which cells ran."""
    seen, ran = set(), []
    run = engine.Engine.run

    def local(self, fn, jobs, names, on_result=None, window=None, deps=None):
        if fn is not run_cell:
            return run(self, fn, jobs, names, on_result, window, deps)
        for name, job in zip(names, jobs):
            for f in (deps or {}).get(name, ()):
                f.result()
            result = fn(dataclasses.replace(job, params=_recording(job.params, seen)))
            ran.append(name)
            if on_result is not None:
                on_result(name, result)
        return []

    monkeypatch.setattr(engine.Engine, "run", local)
    return seen, ran


def test_cells_read_only_what_their_key_hashes_and_a_new_floor_reuses_them(tmp_path, parametric_catalogue,
                                                                         cells_here):
    from twinreg.city.build import build_city_twin
    from twinreg.sim.city import simulate_city

    cat = parametric_catalogue
    rows = sorted(cat.list(), key=lambda r: r.name)
    tiles = simulate_city(tmp_path / "street", [cat.ge_mesh(r) for r in rows], [r.name for r in rows], km2=0.003,
                          density=60.0, tile=40.0, seed=5, crs="EPSG:28992")
    seen, ran = cells_here
    out = tmp_path / "out"
    street = DEFAULT.with_(segment={"targets": "all"})  # the street's segmentation: every object, not cars
    first = build_city_twin([tmp_path / "street"], cat, None, out, workers=1, params=street)
    assert ran and first["objects"]
    assert seen <= set(cell_params(DEFAULT)), sorted(seen - set(cell_params(DEFAULT)))
    n_cells = len(ran)
    ran.clear()
    other = street.with_(matching={"size_tol": 0.35}, kinds={"k": 3})
    again = build_city_twin([tmp_path / "street"], cat, None, out, workers=1, params=other, min_confidence=0.9)
    assert ran == [] and len(again["objects"]) == len(first["objects"]) and n_cells >= 1  # every cell reused
    assert tiles


def test_a_segmentation_change_changes_the_key_a_floor_does_not():
    from twinreg.city.grid import Grid

    grid = Grid(50.0, 5.0)
    key = lambda p: cell_key("c0_0", [], grid, p, "1")  # noqa: E731
    assert key(DEFAULT) == key(DEFAULT.with_(min_confidence=0.9, matching={"size_tol": 0.4}))
    assert key(DEFAULT) != key(DEFAULT.with_(segment={"gap": DEFAULT.segment.gap * 2}))
