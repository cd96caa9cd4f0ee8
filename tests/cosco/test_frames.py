"""The one yaw rotation: a turn about +Z, counter-clockwise seen from above, orthonormal, composing by adding."""

import numpy as np
import pytest

from cosco.frames import yaw, yaw_pose


@pytest.mark.parametrize("a", [0.0, 0.3, np.pi / 2, -2.0, 7.0])
def test_yaw_turns_counter_clockwise_and_composes(a):
    r = yaw(a)
    assert np.allclose(r @ r.T, np.eye(3)) and np.isclose(np.linalg.det(r), 1.0)
    assert np.allclose(r @ [1.0, 0.0, 0.0], [np.cos(a), np.sin(a), 0.0])
    assert np.allclose(r @ [0.0, 0.0, 1.0], [0.0, 0.0, 1.0])
    assert np.allclose(yaw(a) @ yaw(0.4), yaw(a + 0.4))


def test_yaw_pose_turns_then_moves():
    m = yaw_pose(np.pi / 2, (10.0, 20.0, 1.0))
    p = m @ [1.0, 0.0, 0.0, 1.0]
    assert np.allclose(p, [10.0, 21.0, 1.0, 1.0])
