"""Ground removal + object detection speed, and its growth with the number of points (0.1M-10M).

Scenes of any size are tiled from one simulated car park (12 shared cars, distractors, 3 airborne passes): each
tile is the same scan shifted by 40 m, so the density and the object mix stay those of a real car park.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
from common import REPO, SHARED, Row


def _tile_source():
    from twinreg.catalogue.prepare import prepare_model
    from twinreg.sim.scan import car_park

    names = ["toyota_prius/Hybrid.obj", "nissan_patrol/suv_chassis.obj", "audi_unidentified/audi_chassis.obj",
             "jeep_cherokee_xj_1997/JeepCherokee.obj", "uaz_469/uaz469_chassis.obj",
             "vw_type2_microbus/van_chassis.obj", "generic_sedan_chrono/sedan_chassis_vis.obj",
             "generic_hatchback_gazebo/hatchback.obj"]
    models = []
    for n in names:
        p = prepare_model(SHARED / "cars" / n)
        models.append((p.mesh.vertices, p.mesh.faces))
    return car_park(models, n_cars=12, seed=3)


def tiled(points: np.ndarray, n_target: int) -> np.ndarray:
    per = len(points)
    k = int(np.ceil(n_target / per))
    side = int(np.ceil(np.sqrt(k)))
    tiles = [points + [40.0 * (i % side), 40.0 * (i // side), 0.0] for i in range(k)]
    return np.vstack(tiles)[:n_target] + [650_000.0, 5_800_000.0, 0.0]


def run(plot: Path | None = REPO / "docs" / "detect_scaling.png") -> list[Row]:
    from cosco.ground import remove_ground
    from cosco.segment import segment_objects

    src = _tile_source()
    rows, curve = [], []
    for n in (100_000, 250_000, 1_000_000, 3_000_000, 10_000_000):
        pts = tiled(src.points, n)
        local = pts - pts.min(0)
        t = time.perf_counter()
        g, hag, _ = remove_ground(local)
        t_ground = time.perf_counter() - t
        t = time.perf_counter()
        seg = segment_objects(local, hag, is_ground=g)
        t_seg = time.perf_counter() - t
        cars = sum(o.target for o in seg.objects)
        curve.append((n, t_ground, t_seg))
        target = {250_000: "< 1 s", 10_000_000: "< 60 s"}.get(n, "")
        rows.append(Row(f"ground + detection, {n / 1e6:g}M points", f"tiled simulated car park ({cars} cars found)",
                        f"{t_ground + t_seg:.2f} s (ground {t_ground:.2f} + objects {t_seg:.2f})", target))
    if plot:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        c = np.array(curve)
        fig, ax = plt.subplots(figsize=(5, 3.5))
        ax.loglog(c[:, 0], c[:, 1] + c[:, 2], "o-", label="ground + objects")
        ax.loglog(c[:, 0], c[:, 1], "s--", label="ground")
        ax.loglog(c[:, 0], c[:, 2], "^--", label="objects")
        ax.axhline(60, color="grey", lw=0.8, ls=":")
        ax.set_xlabel("points")
        ax.set_ylabel("seconds")
        ax.set_title("detection time vs points (2-core machine)")
        ax.legend(fontsize=8)
        ax.grid(alpha=0.3, which="both")
        fig.tight_layout()
        fig.savefig(plot, dpi=100)
    return rows


if __name__ == "__main__":
    for r in run():
        print(r)
