"""What a heading and a size say between two surveys of street furniture (issue 50, seen from a van): a box whose
length runs across the object in one survey is the same object; a shelter's measured box along its back wall and
its model facing the road are one footprint; a mailbox's turn is weighed by how far its ends move; a squat blob
with no mirror plane has no heading. Two-object epochs built in memory, no scans."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from cosco.sections import Sections

from twinreg.change.epochs import Epoch
from twinreg.change.pairs import pair_objects
from twinreg.change.status import tolerances, turn_tolerance
from twinreg.io.observed import Record

LON = np.array([[u, 1.0] for u in np.linspace(-0.4, 0.4, 9)])
TRA = np.array([[v, 1.0] for v in np.linspace(-0.3, 0.3, 7)])


def _epoch(heading, size, model=None, level="mirror", n_points=2000, measured=None, at=(0.0, 0.0)) -> Epoch:
    size = np.array([size], dtype=np.float64)
    return Epoch(Path("."), None, None, ["obj1"], np.array([[*at, 0.5]]), np.array([heading]), size,
                 np.array([measured], dtype=np.float64) if measured is not None else size.copy(), [model],
                 np.array([1.0 if model else np.nan]), np.array([n_points]), np.zeros((1, 2)), 0.01, 0.02,
                 Record([], [Sections(LON, TRA, 0.1)]), kinds=["unknown"], levels=[level])


def test_a_box_whose_length_runs_across_the_object_is_the_same_object():
    """A jersey barrier measured 0.44 x 4.1 m in one survey and 4.1 x 0.46 m (its box turned a quarter) in the
    next: the same long and short sides, the same axis: the same object, not turned."""
    a = _epoch(3.09, [0.438, 4.112, 1.097], level="none")
    b = _epoch(1.54, [4.096, 0.46, 1.094], level="mirror")
    p = pair_objects(a, b, np.zeros(3))
    assert len(p.i) == 1 and p.p_same[0] > 0.5 and p.turn[0] < np.radians(3)


def test_a_shelter_s_measured_box_and_its_model_make_one_footprint():
    """A bus shelter whose measured box took the axis across it (heading 2.93 rad, 1.68 m along it, 3.49 m
    across) and its model placed facing the road (front 1.36 rad, 3.46 m along it as twin.json states a model's
    size): their long axes agree, so no quarter turn is read."""
    a = _epoch(2.931, [1.678, 3.49, 3.227], level="two_mirrors")
    b = _epoch(1.361, [3.46, 1.737, 3.256], model="bus_stop", level="two_mirrors")
    p = pair_objects(a, b, np.zeros(3))
    assert p.turn[0] < np.radians(3)


def test_a_squat_object_with_no_mirror_plane_has_no_heading():
    """A mailbox's 61 points with no mirror plane give a 0.32 x 0.21 m box of any axis: against its model placed
    74 degrees away, no turn is read; with a mirror plane found (or an elongated box) the turn counts."""
    b = _epoch(2.533, [0.336, 0.128, 1.05], model="mailbox", level="two_mirrors")
    squat = _epoch(0.678, [0.318, 0.208, 1.051], level="none", n_points=61)
    assert pair_objects(squat, b, np.zeros(3)).turn[0] == 0.0
    mirrored = _epoch(0.678, [0.318, 0.208, 1.051], level="mirror", n_points=61)
    assert pair_objects(mirrored, b, np.zeros(3)).turn[0] > np.radians(60)


def test_a_short_object_s_turn_tolerance_moves_its_ends_as_far_as_a_car_s():
    car_a, car_b = _epoch(0.0, [4.5, 1.8, 1.5]), _epoch(0.0, [4.5, 1.8, 1.5])
    box_a, box_b = _epoch(0.0, [0.4, 0.3, 1.0]), _epoch(0.0, [0.4, 0.3, 1.0])
    _, t_tol = tolerances(car_a, car_b)
    ij = np.array([0])
    assert turn_tolerance(t_tol, car_a, car_b, ij, ij)[0] == t_tol  # a car's own tolerance unchanged
    small = turn_tolerance(t_tol, box_a, box_b, ij, ij)[0]
    assert np.isclose(small * 0.4, t_tol * 4.0)  # its ends (0.4 m apart) move as far as a 4 m car's


def test_a_placed_model_s_size_runs_along_its_heading():
    """twin.json's ``size`` of a placed model is its footprint along and across its heading: a shelter measured by
    the catalogue across its front (its symmetry frame a quarter turn from +X) has length and width swapped; a car
    (frame along +X, or a full turn) keeps them."""
    from types import SimpleNamespace

    from twinreg.export.objects import placed_size

    shelter = SimpleNamespace(length=1.737, width=3.46, height=3.26, frame_heading=1.5708)
    assert placed_size(shelter) == {"length": 3.46, "width": 1.737, "height": 3.26}
    for heading in (0.0, 6.283, 3.1416, None):
        car = SimpleNamespace(length=4.6, width=1.8, height=1.5, frame_heading=heading)
        assert placed_size(car) == {"length": 4.6, "width": 1.8, "height": 1.5}


def _status(a: Epoch, b: Epoch) -> dict:
    from twinreg.change.align import Alignment
    from twinreg.change.status import classify

    return classify(a, b, 0, Alignment(np.zeros(3), None, 0, 0), pair_objects(a, b, np.zeros(3)))[0]


def test_a_tree_s_box_fit_along_another_axis_is_no_move():
    """Van seed 10's oak, in place, as its two twins state it: a crown with no mirror plane, its 8.4 x 6.6 m
    box fit 3.8 degrees apart in the two surveys, centres 25 cm apart: the same tree (it was called moved at 0.98).
    The same boxes 60 cm apart, or the same axes 25 cm apart, moved; so is an elongated box (its axis a measurement)
    25 cm apart however its heading turned."""
    tree_a = _epoch(1.7617, [8.444, 6.625, 6.147], level="none", n_points=24459)
    tree_b = _epoch(1.6952, [8.352, 6.549, 6.155], level="none", n_points=24475, at=(-0.203, 0.139))
    same = _status(tree_a, tree_b)
    assert same["status"] == "same" and "another axis" in same["reason"], same
    far = _epoch(1.6952, [8.352, 6.549, 6.155], level="none", n_points=24475, at=(-0.5, 0.35))
    assert _status(tree_a, far)["status"] == "moved"
    one_axis = _epoch(1.7617, [8.352, 6.549, 6.155], level="none", n_points=24475, at=(-0.203, 0.139))
    assert _status(tree_a, one_axis)["status"] == "moved"
    car_a = _epoch(1.7617, [4.5, 1.8, 1.5], level="none")
    car_b = _epoch(1.7137, [4.5, 1.8, 1.5], level="none", at=(-0.203, 0.139))
    assert _status(car_a, car_b)["status"] == "moved"
