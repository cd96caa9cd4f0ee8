"""open3d loaded without its plotly drawing: the same open3d, the drawing imported when it is called."""

import subprocess
import sys
from pathlib import Path

_BODY = """
import sys
import numpy as np
from twinreg.o3d import load

o3d = load()
assert "dash" not in sys.modules and "plotly" not in sys.modules, "dash or plotly imported with open3d"
from twinreg.raycast import cast
pts, faces, rays = cast(np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float), np.array([[0, 1, 2]]),
                        np.array([[0.2, 0.2, 1.0], [2.0, 2.0, 1.0]]), np.array([[0, 0, -1.0], [0, 0, -1.0]]))
assert rays.tolist() == [0] and np.allclose(pts, [[0.2, 0.2, 0.0]], atol=1e-6), (pts, rays)
assert load() is o3d
cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(np.random.default_rng(0).random((20, 3))))
figure = o3d.visualization.get_plotly_fig([cloud])
assert type(figure).__name__ == "Figure" and "plotly" in sys.modules
assert not getattr(sys.modules["open3d.visualization.draw_plotly"], "twinreg_stand_in", False)
print("ok")
"""


def test_open3d_without_plotly_until_drawn():
    root = Path(__file__).resolve().parents[2]
    done = subprocess.run([sys.executable, "-c", _BODY], capture_output=True, text=True, cwd=root, timeout=120)
    assert done.returncode == 0 and done.stdout.strip() == "ok", done.stderr[-2000:]
