"""The processing grid: every point owned by exactly one cell; every cell whose read square holds a point gets it."""

from __future__ import annotations

import numpy as np
import pytest

from twinreg.city.grid import Grid, cell_size_for


def test_each_point_is_owned_once_and_read_by_every_cell_within_reach():
    rng = np.random.default_rng(0)
    grid = Grid(50.0, 10.0, 32.0)
    xy = rng.uniform([120900.0, 486900.0], [121100.0, 487100.0], (20000, 2))
    xy[:50, 0] = 121000.0  # exactly on a seam: the cell to the east owns it (half-open cores)
    cells = grid.cells_over(xy.min(0), xy.max(0))
    owners = np.sum([c.owns(xy) for c in cells], axis=0)
    assert (owners == 1).all()
    assert all(grid.index(xy[:50])[:, 0] == 121000 // 50)
    members = grid.membership(xy)
    for c in cells:
        expected = np.flatnonzero(((xy >= c.read_lo) & (xy <= c.read_hi)).all(1))
        got = members.get((c.ix, c.iy), np.zeros(0, int))
        assert np.array_equal(np.sort(got), expected), c.name


def test_searched_square_is_the_buffer_and_read_square_the_larger_margin():
    c = Grid(100.0, 10.0, 32.0).cell(3, 4)
    assert c.name == "c3_4"
    assert np.allclose(c.read_lo, [268.0, 368.0]) and np.allclose(c.read_hi, [432.0, 532.0])
    assert c.searches(np.array([[290.0, 395.0], [289.0, 450.0]])).tolist() == [True, False]


def test_bad_grids_are_refused():
    with pytest.raises(ValueError, match="twice its buffer"):
        Grid(15.0, 10.0)
    with pytest.raises(ValueError, match="as wide as it reads"):
        Grid(30.0, 10.0, 32.0)


def test_default_cell_size_holds_about_six_million_points():
    for density in (8.0, 17.0, 150.0, 300.0, 600.0):
        side = cell_size_for(int(density * 1e6), 1e6)
        assert side % 10 == 0
        assert 4.5e6 <= density * side ** 2 <= 6.0e6 or side == 40.0, (density, side)
    assert cell_size_for(100, 1e6) > 1000  # a sparse scan: one big cell, not thousands of empty ones
