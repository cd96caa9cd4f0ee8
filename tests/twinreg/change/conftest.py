"""Two simulated surveys of one car park (twinreg/sim/epochs.py), built once for the change tests: the earlier at
150 pts/m2, the later flown along other lines and offset by (0.10, -0.08, 0.10) m with a strip of no returns, at
150 and at 20 pts/m2; the twins are built with the parametric catalogue."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import pytest

SEED = 4  # its strip of no returns hides a car that left, one that stayed and two arrivals
DATES = ("2026-03-02", "2026-06-02", "2026-09-01")


@dataclass
class Surveys:
    pairs: dict
    twins: dict
    folder: Path


@pytest.fixture(scope="session")
def surveys(tmp_path_factory, parametric_catalogue) -> Surveys:
    from twinreg.geo.georef import georef_from_options
    from twinreg.io.ply import write_ply
    from twinreg.pipeline import build_twin
    from twinreg.sim.epochs import survey_pair

    folder = tmp_path_factory.mktemp("surveys")
    cat = parametric_catalogue
    rows = sorted(cat.list(), key=lambda r: r.id)
    models, sizes = cat.scan_meshes(rows), [(r.length, r.width, r.height) for r in rows]
    pairs = {d: survey_pair(models, seed=SEED, densities=(150.0, d), sizes=sizes) for d in (150.0, 20.0)}
    scans = {"before": pairs[150.0].before, "after150": pairs[150.0].after, "after20": pairs[20.0].after}
    twins = {}
    for (name, pts), date in zip(scans.items(), DATES):
        write_ply(folder / f"{name}.ply", pts)
        build_twin(folder / f"{name}.ply", cat, georef_from_options(53.35, -6.26), folder / name, date=date)
        twins[name] = folder / name
    return Surveys(pairs, twins, folder)
