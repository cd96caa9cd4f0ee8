"""The decision alone (twinreg/matching/decision.py): the lowest acceptable score wins, a model that sinks or
floats is not acceptable, the confidence falls with the margin and with a poor fit, near scores are ambiguous."""

import numpy as np
from scipy.spatial import cKDTree

from twinreg.settings import DEFAULT
from twinreg.matching.acceptance import verdict
from twinreg.matching.decision import Evidence, decide, evidence, fit_factor, top_surface

NOISE = 0.02


def _ev(model_id, score, outliers=0.0, unseen=0.0, sink=0.0):
    v = verdict(np.r_[np.zeros(int(100 * (1 - outliers))), np.ones(int(100 * outliers))], NOISE, 0.05)
    return Evidence(model_id, 0.02, 0.01, 0.02, 0.0, score, v, unseen, sink, 2 * NOISE + 0.03, 0.25)


def test_the_lowest_acceptable_score_wins_with_a_margin_confidence():
    d = decide([_ev(1, 0.10), _ev(2, 0.05), _ev(3, 0.20)], NOISE)
    assert d.best.model_id == 2 and np.isclose(d.margin_sigma, 2.5)
    assert np.isclose(d.confidence, 1 - np.exp(-2.5)) and d.ambiguous_with == []
    close = decide([_ev(1, 0.050), _ev(2, 0.054)], NOISE)
    assert close.best.model_id == 1 and close.ambiguous_with == [2] and close.confidence < 0.2


def test_a_sunk_or_floating_model_is_not_acceptable():
    d = decide([_ev(1, 0.01, sink=0.15), _ev(2, 0.05)], NOISE)
    assert d.best.model_id == 2
    assert "sunk into the ground" in _ev(1, 0.01, sink=0.15).reason("van")
    assert "above the ground" in _ev(1, 0.01, sink=-0.4).reason("van")
    assert decide([_ev(1, 0.01, sink=-0.4)], NOISE).best is None
    assert decide([_ev(1, 0.01, outliers=0.2)], NOISE).best is None
    assert decide([_ev(1, 0.01, unseen=0.6)], NOISE).best is None


def test_a_poor_fit_is_never_above_one_half():
    far_behind = _ev(2, 1.0)
    good = decide([_ev(1, 0.01), far_behind], NOISE)
    poor = decide([_ev(1, 0.01, outliers=0.08), far_behind], NOISE)  # 80 % of the outlier limit
    assert good.confidence > 0.99
    assert poor.best.model_id == 1 and poor.confidence <= 0.5
    assert [fit_factor(r) for r in (0.0, 0.5, 0.75, 1.0, 2.0)] == [1.0, 1.0, 0.5, 0.25, 0.25]


def test_evidence_parts_and_the_top_surface():
    rng = np.random.default_rng(0)
    cloud = rng.uniform([-2, -1, 0], [2, 1, 1.5], (3000, 3))
    top = top_surface(cloud, 0.1)
    cells = {}
    for x, y, z in cloud:  # the highest point of each 10 cm cell, the slow way
        key = (int(np.floor(x / 0.1)), int(np.floor(y / 0.1)))
        cells[key] = max(cells.get(key, -1.0), z)
    assert sorted(top[:, 2]) == sorted(cells.values())
    e = evidence(7, 0.03, np.full(500, 0.01), top, cKDTree(cloud), np.array([4.0, 2.0, 1.5]),
                 np.array([4.1, 2.0, 1.5]), NOISE, 0.05, DEFAULT, sink=0.01)
    assert e.model_id == 7 and e.unseen_share == 0.0 and e.stands()
    assert np.isclose(e.size, 0.1 - 2 * NOISE)  # the object is 10 cm longer than the model, beyond the noise
    assert np.isclose(e.score, e.scan_fit + e.model_fit + 0.5 * 0.03 + 0.5 * e.size)
