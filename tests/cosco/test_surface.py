"""An object's roughness against its scan's ground (cosco/surface.py): a shell's scan lines stand out of their
chords no more than the road's, a hedge's leaves do; told in units of the scan's own smooth surface, so that a
simulated scan's isotropic noise and a rotating scanner's millimetres give the same answer."""

from __future__ import annotations

import numpy as np
import pytest

from cosco.surface import scan_smoothness, surface_of


def _lines(rng, along: np.ndarray, across: np.ndarray, surface, noise: float, depth: float = 0.0) -> np.ndarray:
    """Scan lines: at each ``across`` value a line of points ``along`` a surface (``surface(u, v)`` -> (n, 3) points and
    (n, 3) unit normals), each point moved ``noise`` (sd, m, every way) and, for foliage, up to ``depth`` m into
    the surface along its normal (the leaf a beam met)."""
    u, v = (a.ravel() for a in np.meshgrid(along, across))
    p, n = surface(u, v)
    return p + rng.normal(0, noise, p.shape) - n * rng.uniform(0, depth, (len(p), 1))


def _road(u, v):
    return np.c_[u, v, np.zeros_like(u)], np.tile([0.0, 0.0, 1.0], (len(u), 1))


def _side(u, v):  # a car's side, bulging 10 cm over its height, seen from +y
    return np.c_[u, 1.0 + 0.1 * np.sin(np.pi * v / 1.2), v], np.tile([0.0, 1.0, 0.0], (len(u), 1))


@pytest.mark.parametrize("noise, step, lines", [(0.003, 0.03, 0.17), (0.003, 0.03, 0.1), (0.01, 0.05, 0.1),
                                                (0.02, 0.1, 0.2), (0.02, 0.04, 0.1)])
def test_a_shell_is_as_smooth_as_its_scans_ground_whatever_the_noise(noise, step, lines):
    """Scan lines ``lines`` m apart, their points ``step`` m apart along: a car's side reads as rough as the road
    beside it (its units), whatever the noise, so no car is refused for it; a hedge seen as a rotating scanner sees
    one at 25 m (lines 17 cm apart, 3 cm along, leaves up to 30 cm deep, millimetres of range noise) several times
    rougher. (Where the lines lie closer than the leaves' depth, a point's nearest neighbours are leaves of its own
    depth on the next line, and a hedge reads less rough: the test cannot find every hedge.)"""
    rng = np.random.default_rng(int(noise * 1000) + int(step * 100))
    road = _lines(rng, np.arange(0, 20, step), np.arange(0, 20, 0.5), _road, noise)
    smooth = scan_smoothness(road)
    assert smooth is not None and smooth > 0
    shell = _lines(rng, np.arange(0, 4.5, step), np.arange(0.05, 1.2, lines), _side, noise)
    s_shell = surface_of(shell, smooth=smooth)
    assert s_shell.rough < 1.5, s_shell
    if lines >= 0.15 and noise <= step / 10:  # (a simulated scan's centimetres of noise: every neighbour is noise)
        hedge = _lines(rng, np.arange(0, 4.5, step), np.arange(0.05, 1.8, lines), _side, noise, depth=0.3)
        s_hedge = surface_of(hedge, smooth=smooth)
        assert s_hedge.rough > 2.5, s_hedge
    # without the scan's ground the roughness is measured and told against nothing
    assert surface_of(shell).roughness == s_shell.roughness and surface_of(shell).rough is None


def test_too_few_chords_measure_no_roughness():
    rng = np.random.default_rng(0)
    few = rng.normal(0, 0.3, (12, 3))
    assert surface_of(few, smooth=0.005).roughness is None and surface_of(few, smooth=0.005).rough is None
    assert scan_smoothness(few) is None
