"""Candidates alone (twinreg/matching/prefilter.py): the density-aware window, the ranking inside it and the
nearest models outside it."""

import numpy as np

from twinreg.settings import DEFAULT
from twinreg.matching.prefilter import SizeIndex


class _Cat:
    """A catalogue's descriptors (id, L, W, H, profile_mid, profile_end) without a database."""

    def __init__(self, rows):
        t = np.array(rows, dtype=np.float64)
        self.table = (t[:, 0].astype(np.int64), t[:, 1:])

    def descriptors(self):
        return self.table


class _Shape:
    def __init__(self, size):
        from cosco.sections import Sections, Size

        self.size = Size(*size)
        lon = np.column_stack([np.linspace(-size[0] / 2, size[0] / 2, 50), np.full(50, size[2])])
        self.sections = Sections(lon, lon[:, :2], 0.05)


def test_the_window_grows_with_the_spacing_for_length_and_width_only():
    index = SizeIndex(_Cat([[1, 4.5, 1.8, 1.5, 1.2, 1.0]]))
    lo, hi = index.window(np.array([4.0, 1.7, 1.4]), spacing=0.2)
    assert np.allclose(lo, [3.8, 1.5, 1.2]) and np.allclose(hi, [4.5, 2.2, 1.6])
    exact = DEFAULT.with_(matching={"size_spacing_k": 0.0})
    lo, hi = index.window(np.array([4.0, 1.7, 1.4]), spacing=0.2, params=exact)
    assert np.allclose(hi, [4.2, 1.9, 1.6])


def test_candidates_are_ranked_inside_the_window_and_the_nearest_outside_are_kept():
    rows = [[1, 4.50, 1.80, 1.50, 1.4, 1.1], [2, 4.30, 1.75, 1.45, 1.4, 1.1], [3, 5.20, 1.95, 1.90, 1.8, 1.5],
            [4, 3.60, 1.60, 1.50, 1.4, 1.1], [5, 4.25, 1.78, 1.46, 1.4, 1.1]]
    index = SizeIndex(_Cat(rows))
    found = index.candidates(_Shape((4.25, 1.76, 1.45)), spacing=0.06)
    assert set(found.ids) == {1, 2, 5} and found.ids[0] == 5 and not found.outside
    assert found.nearest == [4, 3] and found.all == list(found.ids) + [4, 3]
    none = index.candidates(_Shape((2.5, 1.2, 1.0)), spacing=0.06)
    assert none.ids == [] and none.outside and none.nearest[0] == 4
    model, gap = index.nearest_gap(np.array([2.5, 1.2, 1.0]), 0.06)
    assert model == 4 and np.allclose(gap, [1.1, 0.4, 0.5])


def test_a_model_drawn_along_its_width_is_a_candidate_either_way_round():
    """A bus shelter's model drawn facing its own x axis (L 1.74 m, W 3.46 m) is in the window of a shelter measured
    3.45 x 1.71 m (its length along the kerb): the registration turns it a quarter. A car's window stays a car's."""
    rows = [[1, 1.74, 3.46, 3.26, 0.0, 2.6], [2, 4.50, 1.80, 1.50, 1.4, 1.1], [3, 1.80, 4.50, 3.26, 0.0, 2.6]]
    index = SizeIndex(_Cat(rows))
    found = index.candidates(_Shape((3.45, 1.71, 3.21)), spacing=0.05)
    assert found.ids == [1] and not found.outside
    assert index.candidates(_Shape((4.40, 1.78, 1.48)), spacing=0.05).ids == [2]
    model, gap = index.nearest_gap(np.array([3.0, 1.7, 3.2]), 0.05)
    assert model == 1 and np.allclose(gap, [0.46, 0.04, 0.06])  # measured against the quarter-turned plan
