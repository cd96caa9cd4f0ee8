"""The scan's quadtree: each point in the tile of its level that holds it, found by one sort."""

from __future__ import annotations

import numpy as np
import pytest

from twinreg.export.scan_tiles import _tile_order, levels


@pytest.mark.parametrize("n, seed", [(1, 0), (5000, 1), (400_000, 2)])
def test_tiles_by_one_sort_are_the_tiles_level_by_level(n, seed, monkeypatch):
    from twinreg.export import scan_tiles

    monkeypatch.setattr(scan_tiles, "NODE_POINTS", 500)  # a deep tree from few points
    rng = np.random.default_rng(seed)
    enu = rng.uniform([0, 0, 0], [190, 120, 3], (n, 3))
    enu[:10, 0] = (190.0 * np.arange(10) / 9)[:n]  # points on the tiles' edges and on the far side
    lo = enu.min(0)
    side = float(max(np.ptp(enu[:, 0]), np.ptp(enu[:, 1]), 1.0)) * (1 + 1e-9)
    level, depth = levels(n, seed)
    rows, tiles = _tile_order(enu, lo, side, level, depth)
    # the reference: at each level, the tile of each point from that level's own tile size
    want = []
    for d in range(depth + 1):
        sel = np.flatnonzero(level == d)
        size = side / 2 ** d
        i = np.clip(np.floor((enu[sel, 0] - lo[0]) / size).astype(np.int64), 0, 2 ** d - 1)
        j = np.clip(np.floor((enu[sel, 1] - lo[1]) / size).astype(np.int64), 0, 2 ** d - 1)
        for ti, tj in sorted(set(zip(i.tolist(), j.tolist()))):
            want.append(((d, ti, tj), sel[(i == ti) & (j == tj)]))
    # deep enough that every level is exercised: about 500 points a tile at the deepest level (4^depth tiles)
    assert depth == {1: 0, 5000: 2, 400_000: 5}[n]
    counts = np.bincount(level, minlength=depth + 1)
    assert (counts > 0).all() or n == 1
    if n >= 5000:  # level d holds a share of the points proportional to 4^d
        share = 4.0 ** np.arange(depth + 1) / (4.0 ** np.arange(depth + 1)).sum()
        assert np.allclose(counts / n, share, atol=0.02), (counts / n, share)
    assert tiles == [t for t, _ in want]
    assert all(np.array_equal(r, w) for r, (_, w) in zip(rows, want))
