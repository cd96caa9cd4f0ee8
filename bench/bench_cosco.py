"""COSCO speed: symmetry + sections per object, the dissimilarity matrix, clustering."""

from __future__ import annotations

import numpy as np
from common import SHARED, Row, timed

import cosco


def _scanned_cars(n: int):
    from twinreg.catalogue.normalise import normalise
    from twinreg.io.meshes import load_mesh
    from twinreg.sim.scan import pose_matrix, scan_meshes, transform

    names = ["toyota_prius/Hybrid.obj", "nissan_patrol/suv_chassis.obj", "audi_unidentified/audi_chassis.obj",
             "jeep_cherokee_xj_1997/JeepCherokee.obj", "uaz_469/uaz469_chassis.obj",
             "vw_type2_microbus/van_chassis.obj", "generic_sedan_chrono/sedan_chassis_vis.obj",
             "uaz_452_bukhanka/uazbus_chassis.obj", "generic_hatchback_gazebo/hatchback.obj",
             "mercedes_g_class_gd250/gd250_Chassis.obj", "vw_beetle_type1/Beetle.glb",
             "generic_pickup_gazebo/pickup.dae"]
    rng = np.random.default_rng(0)
    out = []
    for k in range(n):
        m = normalise(load_mesh(SHARED / "cars" / names[k % len(names)]))
        local = transform(m.vertices, pose_matrix(0, 0, rng.uniform(0, 2 * np.pi)))
        out.append(scan_meshes([(local, m.faces)], noise=0.02, seed=k).points)
    return out


def run() -> list[Row]:
    rows = []
    objs = _scanned_cars(12)
    sizes = [len(o) for o in objs]
    # symmetry + sections for objects of about 2,000 points
    idx = int(np.argmin([abs(s - 2000) for s in sizes]))
    t_sym, _ = timed(lambda: cosco.detect_symmetry(objs[idx]), repeat=7)
    t_all, _ = timed(lambda: cosco.describe_object(objs[idx]), repeat=7)
    rows.append(Row("symmetry / symmetry + sections + size, one object", f"simulated airborne car, {sizes[idx]} points",
                    f"{t_sym * 1000:.0f} / {t_all * 1000:.0f} ms", "< 50 ms (paper: 450 ms per object)"))
    t_each = [timed(lambda o=o: cosco.describe_object(o), repeat=3)[0] for o in objs]
    rows.append(Row("symmetry + sections + size, mean of 12 objects",
                    f"simulated airborne cars, {min(sizes)}-{max(sizes)} points",
                    f"{np.mean(t_each) * 1000:.0f} ms"))
    dales = sorted((SHARED / "dales_objects" / "car").glob("*.xyz"))
    if dales:
        pts = [np.loadtxt(f) for f in dales]
        t, _ = timed(lambda: [cosco.describe_object(p) for p in pts], repeat=3)
        rows.append(Row("symmetry + sections + size, per object", "DALES cars (50 objects, 101-553 points)",
                        f"{t / len(pts) * 1000:.0f} ms"))
    shapes = [cosco.describe_object(o) for o in objs]
    t_mat, m = timed(lambda: cosco.dissimilarity_matrix([s.sections for s in shapes]), repeat=5)
    rows.append(Row("dissimilarity matrix 12 x 12 (66 pairs, 4 rz x tz x du each)", "the 12 simulated cars",
                    f"{t_mat:.3f} s ({t_mat / 66 * 1000:.1f} ms per pair)", "< 0.5 s (paper: 4.96 s)"))
    t_cl, _ = timed(lambda: cosco.cluster(m), repeat=20)
    rows.append(Row("hierarchical clustering 12 x 12", "the matrix above", f"{t_cl * 1000:.2f} ms",
                    "(paper: 50 ms)"))
    return rows


if __name__ == "__main__":
    for r in run():
        print(r)
