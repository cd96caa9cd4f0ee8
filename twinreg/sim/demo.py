"""twinreg demo: parametric car library -> add-model -> simulated airborne scan -> build-twin, with the truth.

Everything is made here, offline: eight parametric cars (supermini to van, real-world sizes) are written as OBJ
files and catalogued through the real add-model path; a car park of 14 of them with distractors (wall, kerb, pole,
a tree over a car) on a sloped ground is scanned by three oblique airborne passes; build-twin places the models at
the Dublin car park of the paper (53.351160, -6.261601).
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from ..catalogue.repository import Catalogue
from ..geo.georef import georef_from_options
from ..io.outdir import staged_folder
from ..io.ply import write_ply
from ..pipeline import build_twin
from ..progress import say as report_progress
from .parametric import LIBRARY, car_mesh, write_obj
from .scan import car_park

DUBLIN = (53.351160, -6.261601)


def run_demo(out, seed: int = 0, n_cars: int = 14, progress=None) -> dict:
    """Run the demo into ``out`` (library/, models/, scan.ply and twin/), which is replaced as a whole and only if
    it is missing, empty or an earlier demo (see :func:`~twinreg.io.outdir.staged_folder`). Returns a summary."""
    t0 = time.perf_counter()
    out = Path(out)
    with staged_folder(out, kind="demo") as stage:
        summary = _run(stage, seed, n_cars, progress)
    summary["files"] = {k: str(out / v) for k, v in summary["files"].items()}
    summary["timing_s"]["total"] = round(time.perf_counter() - t0, 2)
    return summary


def _run(out: Path, seed: int, n_cars: int, progress) -> dict:
    t0 = time.perf_counter()
    models_dir, lib_dir = out / "models", out / "library"
    models_dir.mkdir()

    def say(msg):
        report_progress(progress, msg)

    def build_progress(stage, done=None, total=None):  # build-twin's stages as the demo's lines
        if done is None:
            say(f"build-twin: {stage}")

    say("building the parametric car library")
    cat = Catalogue(lib_dir)
    for spec in LIBRARY:
        v, f = car_mesh(spec)
        path = models_dir / f"{spec.name}.obj"
        write_obj(path, v, f, comment=f"twinreg parametric {spec.body_class}: {spec.make_model}")
        say(f"add-model {path.name}")
        cat.add(path, name=spec.name, make="twinreg parametric", model=spec.make_model, body_class=spec.body_class)
    rows = sorted(cat.list(), key=lambda r: r.id)
    names = [r.name for r in rows]
    meshes = cat.scan_meshes(rows)

    say("simulating an airborne scan of the car park")
    park = car_park(meshes, n_cars=n_cars, seed=seed, gaps=(0.4, 1.0))
    scan = out / "scan.ply"
    write_ply(scan, park.points, comments=[f"twinreg demo scan, seed {seed}", "local metres, origin at the anchor"])

    say("building the twin")
    twin = build_twin(scan, cat, georef_from_options(*DUBLIN), out / "twin",
                      progress=build_progress)
    cat.close()
    rows_out = []
    for o in twin["objects"]:
        c = np.array(o["centroid"][:2])
        d = [np.hypot(*(c - [car.x, car.y])) for car in park.cars]
        car = park.cars[int(np.argmin(d))]
        truth = names[car.model]
        m = o["match"]
        rows_out.append({
            "object": o["id"], "matched": m["name"] if m else None, "truth": truth,
            "correct": bool(m and m["name"] == truth), "bearing_deg": o["bearing_deg"],
            "size": o["measured_size"], "position_error_m": float(min(d)),
            "heading_error_deg": float(abs(np.degrees(np.angle(np.exp(1j * (o["heading_rad"] - car.heading)))))),
            "rmse_m": m["rmse_m"] if m else None,
        })
    return {"seed": seed, "n_cars": n_cars, "n_points": twin["n_points"], "objects": rows_out,
            "n_correct": sum(r["correct"] for r in rows_out), "files": {
                "scan": "scan.ply", "library": "library", "twin_json": "twin/twin.json", "twin_ply": "twin/twin.ply",
                "twin_kmz": "twin/twin.kmz", "report": "twin/report.html", "tiles": "twin/tiles/tileset.json",
                "twin_glb": "twin/twin.glb", "cityjson": "twin/twin.city.json", "geojson": "twin/twin.geojson"},
            "timing_s": {"total": round(time.perf_counter() - t0, 2), "build_twin": twin["timing_s"]["total"]}}
