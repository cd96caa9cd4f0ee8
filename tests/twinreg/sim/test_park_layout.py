"""The dense car-park city layout (simulate-city --layout parks): 10-16 cars a park in bays that do not overlap,
each park with its kerb, wall, tree, kiosk and lamp post; the same seed gives the same city."""

from __future__ import annotations

from collections import Counter

import numpy as np
from typer.testing import CliRunner

from twinreg.cli import app
from twinreg.sim.city import PARK, city_models, park_layout


def test_parks_hold_10_to_16_cars_and_their_furniture():
    models = city_models(None)[0]
    placed = park_layout(models, 3 * PARK, 2 * PARK, seed=5)
    parks = Counter((int(p.x // PARK), int(p.y // PARK)) for p in placed if p.kind == "car")
    assert len(parks) == 6 and all(10 <= n <= 16 for n in parks.values()), parks
    kinds = Counter(p.kind for p in placed if p.kind not in ("car", "slot"))
    assert kinds == {k: 6 for k in ("kerb", "wall", "tree", "kiosk", "pole")}
    cars = [p for p in placed if p.kind == "car"]
    xy = np.array([[p.x, p.y] for p in cars])
    gaps = np.linalg.norm(xy[:, None] - xy[None], axis=2) + np.eye(len(xy)) * 99
    assert gaps.min() > 2.2  # bays 2.6 m apart: no two cars on one spot
    for p in cars:  # perpendicular bays: each car's long side across the row
        assert abs(np.cos(p.heading)) < 0.1
    again = park_layout(models, 3 * PARK, 2 * PARK, seed=5)
    assert [(p.kind, p.x, p.y) for p in again] == [(p.kind, p.x, p.y) for p in placed]


def test_an_unknown_layout_is_one_line(tmp_path):
    r = CliRunner().invoke(app, ["simulate-city", str(tmp_path / "c"), "--layout", "mall"])
    assert r.exit_code == 2 and "--layout must be streets or parks" in r.output  # a usage error
    assert not (tmp_path / "c").exists()
