"""open3d loaded without its plotly drawing: the same open3d, the drawing imported when it is called. Run in a
fresh process (the test process has loaded open3d long before); the child reports what it saw as JSON and the
assertions are made here, where pytest shows them."""

import json
import subprocess
import sys
from pathlib import Path

_CHILD = """
import json, sys
import numpy as np
from twinreg.o3d import load

o3d = load()
seen = {"drawing_loaded_with_open3d": "dash" in sys.modules or "plotly" in sys.modules}
from twinreg.raycast import cast
pts, faces, rays = cast(np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float), np.array([[0, 1, 2]]),
                        np.array([[0.2, 0.2, 1.0], [2.0, 2.0, 1.0]]), np.array([[0, 0, -1.0], [0, 0, -1.0]]))
seen.update(rays=np.asarray(rays).tolist(), points=np.asarray(pts).tolist(), same_module=load() is o3d)
cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(np.random.default_rng(0).random((20, 3))))
figure = o3d.visualization.get_plotly_fig([cloud])
seen.update(figure=type(figure).__name__, plotly_after_drawing="plotly" in sys.modules,
            stand_in_left=bool(getattr(sys.modules["open3d.visualization.draw_plotly"], "twinreg_stand_in", False)))
print(json.dumps(seen))
"""


def test_open3d_without_plotly_until_drawn():
    import numpy as np

    root = Path(__file__).resolve().parents[2]
    done = subprocess.run([sys.executable, "-c", _CHILD], capture_output=True, text=True, cwd=root, timeout=120)
    assert done.returncode == 0, done.stderr[-2000:]
    seen = json.loads(done.stdout.strip().splitlines()[-1])
    assert seen["drawing_loaded_with_open3d"] is False
    assert seen["rays"] == [0] and np.allclose(seen["points"], [[0.2, 0.2, 0.0]], atol=1e-6)
    assert seen["same_module"] is True
    assert seen["figure"] == "Figure" and seen["plotly_after_drawing"] is True
    assert seen["stand_in_left"] is False


_FORK_CHILD = """
import json
import numpy as np
import trimesh
from twinreg.o3d import fork_safe, load
from twinreg.raycast import CentredScene

seen = {"before": fork_safe()}
load()
seen["imported"] = fork_safe()
sphere = trimesh.creation.icosphere(5)
scene = CentredScene(np.asarray(sphere.vertices, float), np.asarray(sphere.faces))
for _ in range(5):
    scene.distances(np.random.default_rng(0).random((300000, 3)))
seen["queried"] = fork_safe()
print(json.dumps(seen))
"""


def test_a_child_is_forked_with_open3d_only_before_its_thread_pools_start():
    """The matching forks a child to share a sweep's clusters only where open3d's pools have not started here (a
    forked child inherits none of their workers): imported is fine, queried is not."""
    res = subprocess.run([sys.executable, "-c", _FORK_CHILD], capture_output=True, text=True, timeout=300,
                         cwd=Path(__file__).resolve().parents[2])
    assert res.returncode == 0, res.stderr[-2000:]
    assert json.loads(res.stdout.strip().splitlines()[-1]) == {"before": True, "imported": True, "queried": False}
