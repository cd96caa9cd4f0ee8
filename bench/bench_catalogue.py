"""add-model speed: the whole command (process start to catalogue written) on the largest shared DAEs."""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import time

from common import SHARED, Row


def run() -> list[Row]:
    rows = []
    files = [("ford_mondeo_2015/body.dae", "Ford Mondeo DAE, 173,418 faces"),
             ("lincoln_mkz_2017/body.dae", "Lincoln MKZ DAE, 142,354 faces")]
    for rel, label in files:
        path = SHARED / "cars" / rel
        if not path.exists():
            continue
        times = []
        for _ in range(3):
            with tempfile.TemporaryDirectory() as lib:
                t = time.perf_counter()
                subprocess.run([sys.executable, "-m", "twinreg", "add-model", str(path), "--library", lib],
                               check=True, capture_output=True, env={**os.environ})
                times.append(time.perf_counter() - t)
        rows.append(Row("add-model, process start to catalogue written", label, f"{min(times):.2f} s",
                        "< 5 s"))
    # the same work in-process, by stage, on the largest file
    import cosco
    from twinreg.catalogue.normalise import normalise
    from twinreg.catalogue.prepare import SAMPLE_SPACING
    from twinreg.io.meshes import load_mesh
    from twinreg.raycast import visible_surface

    path = SHARED / "cars" / files[0][0]
    if path.exists():
        t = time.perf_counter(); m = load_mesh(path); t_load = time.perf_counter() - t
        t = time.perf_counter(); n = normalise(m); t_norm = time.perf_counter() - t
        t = time.perf_counter(); pts = visible_surface(n.vertices, n.faces, SAMPLE_SPACING, drop_faces=n.glass)
        pts = cosco.voxel_downsample(pts, SAMPLE_SPACING)[0]; t_ray = time.perf_counter() - t
        t = time.perf_counter(); cosco.describe_object(pts, ground_z=0.0, front_hint=0.0); t_cos = time.perf_counter() - t
        rows.append(Row("add-model stages: load / normalise / ray-cast sampling / COSCO", files[0][1],
                        f"{t_load:.2f} / {t_norm:.2f} / {t_ray:.2f} / {t_cos:.3f} s ({len(pts)} points)"))
    return rows


if __name__ == "__main__":
    for r in run():
        print(r)
