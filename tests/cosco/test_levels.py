"""cosco/levels: the level of symmetry of simple solids, of the shared street furniture and cars (sampled as the
catalogue samples them), and of a scan-like partial view."""

from __future__ import annotations

import numpy as np
import pytest

from cosco.levels import LEVELS, symmetry_level


def _cylinder(rng, r=0.2, h=3.0, n=4000):
    a = rng.uniform(0, 2 * np.pi, n)
    return np.c_[r * np.cos(a), r * np.sin(a), rng.uniform(0, h, n)]


def _box(rng, size=(4.0, 1.0, 1.0), n=5000):
    return rng.uniform(np.zeros(3), size, (n, 3))


def test_solids_get_their_levels():
    rng = np.random.default_rng(0)
    assert symmetry_level(_cylinder(rng)).level == "rotational"
    assert symmetry_level(_box(rng)).level == "two_mirrors"
    # a wedge along x (a car's profile, crudely): one mirror plane (across its width)
    p = _box(rng, (4.0, 1.8, 1.5), 8000)
    wedge = p[p[:, 2] <= 0.6 + 0.9 * p[:, 0] / 4.0]
    lv = symmetry_level(wedge)
    assert lv.level == "mirror" and abs(np.sin(lv.phi)) > 0.99  # the plane's normal across the width (y)
    # an L in plan with arms of unequal length (equal ones mirror across the diagonal): no plane and no axis
    ell = np.vstack([_box(rng, (3.0, 0.6, 1.0)), _box(rng, (0.6, 1.2, 1.0)) + [0, 0.6, 0]])
    assert symmetry_level(ell).level == "none"


def test_a_pole_with_an_arm_is_rotational_and_has_no_heading():
    rng = np.random.default_rng(1)
    column = _cylinder(rng, 0.12, 8.0, 6000)
    arm = np.c_[rng.uniform(0, 1.5, 500), rng.normal(0, 0.03, 500), rng.uniform(7.8, 8.0, 500)]
    lv = symmetry_level(np.vstack([column, arm]) + [100.0, 200.0, 3.0])
    assert lv.level == "rotational" and not lv.heading_defined
    assert np.allclose(lv.axis, [100.0, 200.0], atol=0.05)  # the axis through the column, not the arm


def test_the_level_does_not_depend_on_where_the_object_stands_or_faces():
    rng = np.random.default_rng(2)
    box = _box(rng, (2.0, 0.8, 1.2))
    for turn in (0.3, 1.1):
        c, s = np.cos(turn), np.sin(turn)
        moved = box @ np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]]).T + [5e5, 6e6, 40.0]
        assert symmetry_level(moved).level == "two_mirrors"


@pytest.mark.parametrize("slug, level", [
    ("fire_hydrant", "rotational"), ("construction_cone", "rotational"), ("first_2015_trash_can", "rotational"),
    ("lamp_post", "rotational"), ("jersey_barrier", "two_mirrors"), ("bus_stop", "two_mirrors"),
    ("oak_tree", "none")])
def test_the_shared_furniture_models(slug, level, furniture):
    """Each model at its life size (its file's unit, model.sdf's scale), as the SOURCE.md describes it."""
    from twinreg.catalogue.prepare import prepare_model

    row = furniture[slug]
    prep = prepare_model(row["path"], category=row["category"], factor=row["scale"])
    assert prep.level.level == level and prep.level.level in LEVELS


def test_most_shared_cars_have_one_mirror_plane(cars):
    """A car has one plane (across its width); a boxy van may show two at the catalogue's sampling. Measured on
    the 16 shared cars: 12 mirror, 2 two_mirrors (the VW and UAZ vans), 2 none (uaz_469 and the Gazebo hatchback,
    whose sampled surfaces are 71-72 % mirror-symmetric)."""
    from twinreg.catalogue.prepare import prepare_model

    levels = [prepare_model(r["path"], unit=r["unit"], up=r["up"]).level.level for r in cars[:6]]
    assert levels.count("mirror") >= 5 and "rotational" not in levels
