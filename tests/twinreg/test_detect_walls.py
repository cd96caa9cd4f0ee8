"""Detection from the ground and from the air: a street's walls give back what hangs on them only where a wall is
seen standing (cosco.segment.street.off_walls)."""

from __future__ import annotations

import numpy as np

from tests.cosco.test_all_objects import _low_crown_at_a_facade
from twinreg.detect import detect_points
from twinreg.io.points import PointSet
from twinreg.settings import DEFAULT


def test_detection_takes_the_walls_pass_only_from_the_ground():
    """``detect_points`` takes the pass for a scan with its scanners' positions (a van's survey) or a sweep, not for
    the same points from the air (no positions): the tree is an object in the one and not in the other."""
    pts, _, labels, names = _low_crown_at_a_facade()
    params = DEFAULT.with_(segment={"targets": "all"})
    origins = np.c_[np.zeros(len(pts)), pts[:, 1], np.full(len(pts), 2.4)]  # a van driving along x = 0
    found = {}
    for name, scene in {"van": PointSet(path=None, points=pts, offset=np.zeros(3), unit="m", origins=origins),
                        "air": PointSet(path=None, points=pts, offset=np.zeros(3), unit="m")}.items():
        det = detect_points(scene, params)
        found[name] = any((labels[o.indices] == names.index("tree")).mean() > 0.9 and o.n_points > 5000
                          for o in det.objects)
    assert found == {"van": True, "air": False}
