"""Packed int64 sorts give exactly what numpy's stable argsort and an exact median per group give."""

from __future__ import annotations

import numpy as np

from cosco.sorting import group_by_key, group_medians, stable_argsort


def test_stable_argsort_equals_numpys_stable_argsort_and_falls_back_for_wide_keys():
    rng = np.random.default_rng(1)
    for keys in (rng.integers(0, 50, 10_000), rng.integers(0, 2**40, 5_000), np.zeros(7, dtype=np.int64),
                 rng.integers(0, 2**62, 1000), rng.integers(-5, 5, 100)):  # the last two: the fallback
        assert np.array_equal(stable_argsort(keys), np.argsort(keys, kind="stable"))
    assert stable_argsort(np.zeros(0, dtype=np.int64)).tolist() == []


def test_groups_and_medians_per_key():
    rng = np.random.default_rng(2)
    keys = rng.integers(0, 300, 20_000)
    values = rng.normal(10.0, 3.0, len(keys))
    order, distinct, starts = group_by_key(keys)
    assert np.array_equal(distinct, np.unique(keys))
    bounds = np.r_[starts, len(keys)]
    for k in (0, 17, len(distinct) - 1):
        assert set(keys[order[bounds[k]:bounds[k + 1]]].tolist()) == {distinct[k]}
    got_keys, medians = group_medians(keys, values)
    exact = np.array([np.median(values[keys == k]) for k in got_keys])
    assert np.array_equal(got_keys, distinct)
    assert np.abs(medians - exact).max() <= 1e-6
    # a range too wide to pack: the two-key sort gives the exact medians
    wide = values * 1e12
    _, m = group_medians(keys, wide)
    assert np.allclose(m, exact * 1e12, rtol=0, atol=1e-3 * 1e12 * 1e-9)


def test_compiled_group_medians_are_the_packed_sorts(kernel_path):
    """The ground filter's medians per cell (keys with gaps, single points, even and odd counts, repeated heights):
    the counting kernel gives the packed sort's keys and medians to the bit; keys too sparse for a count and
    negative keys take the numpy paths on both."""
    from cosco import kernels

    rng = np.random.default_rng(4)
    keys = np.r_[rng.integers(0, 900, 30_000) * 7, 50_000, 6301]
    values = np.r_[np.round(rng.normal(3.0, 0.4, 30_000), 3), -1.5, 2.0]
    for k, v in ((keys, values), (np.r_[keys, 2**40], np.r_[values, 1.0]), (keys - 5, values)):
        got = group_medians(k, v)
        with kernels.reference_only():
            want = group_medians(k, v)
        assert np.array_equal(got[0], want[0]) and np.array_equal(got[1], want[1])
    distinct, medians = group_medians(keys, values)
    exact = np.array([np.median(values[keys == g]) for g in distinct[:50]])
    assert np.abs(medians[:50] - exact).max() <= 1e-6
