"""cosco/arrays: the point checks every stage relies on, and the fast column and voxel helpers against numpy's
plain forms."""

from __future__ import annotations

import numpy as np
import pytest

from cosco.arrays import as_points, cell_keys, check_object, column_max, column_min, voxel_downsample


@pytest.mark.parametrize("bad, words", [(np.zeros((4, 2)), "(n, 3)"), (np.zeros(3), "(n, 3)"),
                                        ([[0, 0, np.nan]], "NaN"), ([[0, 0, np.inf]], "infinite")])
def test_as_points_refuses_what_is_not_points(bad, words):
    with pytest.raises(ValueError, match=words.replace("(", r"\(").replace(")", r"\)")):
        as_points(bad)


def test_check_object_names_each_degenerate_case():
    rng = np.random.default_rng(0)
    with pytest.raises(ValueError, match="only 5 points"):
        check_object(rng.normal(size=(5, 3)))
    with pytest.raises(ValueError, match="one vertical line"):
        check_object(np.c_[np.zeros(50), np.zeros(50), np.linspace(0, 2, 50)])
    with pytest.raises(ValueError, match="collinear in plan"):
        t = np.linspace(0, 4, 200)
        check_object(np.c_[t, 0.5 * t, rng.uniform(0, 1.5, 200)])
    car = rng.uniform([0, 0, 0], [4.5, 1.8, 1.5], size=(500, 3))
    assert check_object(car).shape == (500, 3)


def test_column_extremes_and_cell_keys_agree_with_numpy():
    rng = np.random.default_rng(1)
    a = rng.integers(-50, 50, size=(1000, 3))
    assert np.array_equal(column_min(a), a.min(0)) and np.array_equal(column_max(a), a.max(0))
    keys = cell_keys(a)
    # the same rows share a key, different rows differ, and the keys sort the rows lexicographically
    _, by_rows = np.unique(a, axis=0, return_inverse=True)
    _, by_keys = np.unique(keys, return_inverse=True)
    assert np.array_equal(by_rows.reshape(-1), by_keys.reshape(-1))
    assert len(cell_keys(np.zeros((0, 3), dtype=int))) == 0


def test_voxel_downsample_keeps_the_mass_and_the_centroid():
    rng = np.random.default_rng(2)
    pts = rng.uniform(0, 3, size=(5000, 3))
    centroids, counts = voxel_downsample(pts, 0.5)
    assert counts.sum() == len(pts) and len(centroids) == 6 ** 3
    assert np.allclose((centroids * counts[:, None]).sum(0) / counts.sum(), pts.mean(0))
    assert np.all(np.floor(centroids / 0.5).max(0) <= 5)
