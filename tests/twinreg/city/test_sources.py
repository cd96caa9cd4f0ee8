"""Tiles as inputs: paths, folders and globs; headers that disagree are refused; reading by chunks and splitting a
tile into cells lose and duplicate nothing."""

from __future__ import annotations

import numpy as np
import pytest

from tests.conftest import write_las
from twinreg.city import sources
from twinreg.city.grid import Grid
from twinreg.city.sources import expand_paths, open_sources, read_box, read_splits, split_tile
from twinreg.errors import CityError, SceneReadError


def _tiles(folder, crs="EPSG:28992", n=3000, seed=0):
    rng = np.random.default_rng(seed)
    folder.mkdir(exist_ok=True)
    out = []
    for k, (x0, y0) in enumerate([(121000, 487000), (121050, 487000)]):
        pts = rng.uniform([x0, y0, 0], [x0 + 50, y0 + 50, 3], (n, 3))
        out.append(write_las(folder / f"t{k}.laz", pts, crs=crs))
    return out


def test_paths_folders_and_globs(tmp_path):
    a, b = _tiles(tmp_path / "tiles")
    assert expand_paths([tmp_path / "tiles"]) == [a, b]
    assert expand_paths([str(tmp_path / "tiles" / "*.laz"), a]) == [a, b]
    with pytest.raises(SceneReadError, match="matches no file"):
        expand_paths([str(tmp_path / "none" / "*.laz")])
    with pytest.raises(SceneReadError, match="no .las or .laz"):
        (tmp_path / "empty").mkdir()
        expand_paths([tmp_path / "empty"])
    srcs = open_sources([tmp_path / "tiles"])
    assert [s.crs for s in srcs] == ["EPSG:28992", "EPSG:28992"] and sum(s.n_points for s in srcs) == 6000


def test_tiles_whose_crs_or_unit_disagree_are_refused(tmp_path):
    a, _ = _tiles(tmp_path / "rd")
    b = write_las(tmp_path / "utm.laz", np.random.default_rng(1).uniform([5e5, 5e6, 0], [5e5 + 9, 5e6 + 9, 1],
                                                                         (200, 3)), crs="EPSG:32631")
    with pytest.raises(SceneReadError, match=r"utm\.laz: its CRS .*differs from that of .*t0\.laz"):
        open_sources([a, b])
    c = write_las(tmp_path / "feet.laz", np.random.default_rng(2).uniform(0, 9, (200, 3)), crs="EPSG:2994")
    with pytest.raises(SceneReadError, match="feet.laz"):
        open_sources([a, c])
    none = write_las(tmp_path / "nocrs.laz", np.random.default_rng(3).uniform(0, 9, (200, 3)))
    with pytest.raises(SceneReadError, match="none stated"):
        open_sources([a, none])
    ply = tmp_path / "scene.ply"
    ply.write_text("ply\n")
    with pytest.raises(SceneReadError, match="scene.ply: a tiled run reads LAS, LAZ or COPC"):
        open_sources([a, ply])


def test_reading_by_chunks_and_splitting_keep_every_point_once(tmp_path, monkeypatch):
    monkeypatch.setattr(sources, "CHUNK_POINTS", 700)  # several chunks per tile
    tiles = _tiles(tmp_path / "tiles", n=5000)
    srcs = open_sources(tiles)
    grid = Grid(30.0, 5.0, 12.0)
    every = np.vstack([read_box(s, [-1e9, -1e9], [1e9, 1e9]) for s in srcs])
    assert len(every) == 10000
    cells = {}
    for k, s in enumerate(srcs):
        counts = split_tile(s, grid, tmp_path / "split" / str(k))
        assert (tmp_path / "split" / str(k) / "split.json").is_file()
        for name in counts:
            cells.setdefault(name, []).append(tmp_path / "split" / str(k))
    owned = []
    for (ix, iy) in {tuple(map(int, n[1:].split("_"))) for n in cells}:
        c = grid.cell(ix, iy)
        pts = read_splits(cells[c.name], c.name, [every[:0]])
        # what a cell reads is exactly the points in its read square, from both tiles
        inside = ((every[:, :2] >= c.read_lo) & (every[:, :2] <= c.read_hi)).all(1)
        assert len(pts) == inside.sum()
        assert np.array_equal(np.unique(pts, axis=0), np.unique(every[inside], axis=0))
        owned.append(pts[c.owns(pts[:, :2])])
    owned = np.vstack(owned)
    assert len(owned) == len(every)
    assert np.array_equal(np.unique(owned, axis=0), np.unique(every, axis=0))
    # a second split of the same tile reuses the finished folder
    assert split_tile(srcs[0], grid, tmp_path / "split" / "0") == split_tile(srcs[0], grid, tmp_path / "split" / "0")


def test_a_split_gives_the_metres_of_the_tile_bit_for_bit_in_feet_too(tmp_path):
    # the split keeps the file's integers; the cell scales them back with the header's scale and offset and the
    # unit (international feet here): the same float64 metres as reading the tile, each with its ASPRS class
    rng = np.random.default_rng(3)
    codes = rng.choice(np.array([1, 2, 5, 6], dtype=np.uint8), 4000)
    tile = write_las(tmp_path / "feet.laz", rng.uniform([4_000_000, 800_000, 300], [4_000_150, 800_150, 330],
                                                       (4000, 3)), crs="EPSG:2994", classes=codes)
    (src,) = open_sources([tile])
    assert src.scale != 1.0
    direct, direct_codes = read_box(src, [-1e12, -1e12], [1e12, 1e12], classes=True)
    assert np.array_equal(direct_codes, codes)
    grid = Grid(20.0, 2.0, 5.0)
    counts = split_tile(src, grid, tmp_path / "split")
    assert sorted(p.suffix for p in (tmp_path / "split").iterdir()) == \
        [".cls"] * len(counts) + [".i32"] * len(counts) + [".json"]
    for name, n in counts.items():
        ix, iy = map(int, name[1:].split("_"))
        c = grid.cell(ix, iy)
        got, got_codes = read_splits([tmp_path / "split"], name, classes=True)
        inside = ((direct[:, :2] >= c.read_lo) & (direct[:, :2] <= c.read_hi)).all(1)
        assert len(got) == n and np.array_equal(got, direct[inside])  # the same points in the same order, bit for bit
        assert np.array_equal(got_codes, codes[inside])  # each with its class
        assert np.array_equal(read_splits([tmp_path / "split"], name), got)  # the points alone, as before


def test_a_damaged_or_planted_split_is_made_again_and_names_no_path(tmp_path):
    """A split folder in OUT may come from a killed run or from someone else: a document that does not check
    (another format, a count its file does not hold, a cell name that is a path, a scale that is not a number) is
    removed with its folder and the tile split again; a cell never reads what it names."""
    import json

    rng = np.random.default_rng(5)
    tile = write_las(tmp_path / "t.laz", rng.uniform([1000, 2000, 10], [1060, 2060, 12], (3000, 3)), crs="EPSG:2157")
    (src,) = open_sources([tile])
    grid = Grid(20.0, 2.0, 5.0)
    folder = tmp_path / "split"
    counts = split_tile(src, grid, folder)
    want = {name: read_splits([folder], name) for name in counts}
    outside = tmp_path / "elsewhere.i32"
    outside.write_bytes(b"\0" * 12)
    good = json.loads((folder / "split.json").read_text())
    name = sorted(counts)[0]
    # "i32": a split of the format before the classes were kept
    for bad in ({**good, "format": "f64"}, {**good, "format": "i32"},
                {**good, "cells": {**counts, name: counts[name] + 1}},
                {**good, "cells": {**counts, "../elsewhere": 1}}, {**good, "scales": ["1e-3", 1, 1]}, [1, 2]):
        (folder / "split.json").write_text(json.dumps(bad))
        with pytest.raises(CityError):
            read_splits([folder], name)
        assert split_tile(src, grid, folder) == counts  # split again, whole
        assert json.loads((folder / "split.json").read_text()) == good
        for n in counts:
            assert np.array_equal(read_splits([folder], n), want[n])
    # a classes file cut short (a killed copy): split again
    (folder / f"{name}.cls").write_bytes(b"\2")
    with pytest.raises(CityError):
        read_splits([folder], name)
    assert split_tile(src, grid, folder) == counts and np.array_equal(read_splits([folder], name), want[name])
    assert outside.read_bytes() == b"\0" * 12
