"""The verification's distances answered by a helper process (twinreg/matching/prober.py) are open3d's, as
in-process; a helper that dies or is stuck is replaced by this process, with the same answers; the helper leaves
with the run; no helper starts where open3d is loaded already."""

from __future__ import annotations

import numpy as np
import psutil

from twinreg.matching.acceptance import SurfaceIndex
from twinreg.matching.prober import Prober, warm_up
from twinreg.report.painter import Painter


def _mesh():
    import trimesh

    m = trimesh.creation.box([4.5, 1.8, 1.4])
    m.apply_translation([0.0, 0.0, 0.7])
    return np.asarray(m.vertices), np.asarray(m.faces)


def test_helper_distances_are_open3ds_and_a_dead_helper_is_replaced():
    v, f = _mesh()
    pts = np.random.default_rng(0).uniform([-3, -2, -0.5], [3, 2, 2.5], (2000, 3))
    want = SurfaceIndex(v, f).distances(pts)
    assert Prober.start() is None  # open3d is loaded here now: a helper would only load it again
    prober = Prober(Painter.start(warm=warm_up))
    assert prober.helper is not None
    pid = prober.helper.pid
    try:
        surface = prober.surface(7, lambda: (v, f))
        np.testing.assert_array_equal(surface.distances(pts), want)
        np.testing.assert_array_equal(surface.distances(pts[:10]), want[:10])  # the mesh kept in the helper
        psutil.Process(pid).kill()
        psutil.Process(pid).wait(10)
        np.testing.assert_array_equal(surface.distances(pts), want)  # answered here
        assert prober.helper is None
    finally:
        prober.stop()
    assert not psutil.pid_exists(pid) or psutil.Process(pid).status() == psutil.STATUS_ZOMBIE
