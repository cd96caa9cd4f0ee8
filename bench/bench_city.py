"""City scale: build-twin on simulated cities of LAZ tiles (the 16 shared cars, about 160 points per m2, streets of
parked cars, walls, trees, poles, slopes), timed from outside with the peak memory of the whole process tree (the
command, the Dask scheduler and its workers), sampled every 0.1 s; and the 9.2M-point case of issue 9 (a car park
repeated 6 x 6 in one LAS file).

    python bench/bench_city.py [--points 10,30,100] [--cars 12,100,400] [--parks 10,100] [--no-park6x6] [--keep DIR]

``--parks`` adds dense car-park cities (simulate-city --layout parks: 10-16 cars a park with a kerb, wall, tree,
kiosk and lamp post) at 150 and 300 pts/m2 beside a street city of the same size, with the cell stage per million
points and the matching per object of each and their ratios.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from common import Row, machine, tree_memory  # noqa: E402

#: streets every 36 m; points per km2 and cars per km2 of that city at --density 150 (measured on 0.56 km2)
STREETS = 36.0
POINTS_PER_KM2 = 150e6
CARS_PER_KM2 = 7_500


def run_tree(cmd: list[str]) -> tuple[float, int, str]:
    """Wall time (s), peak summed RSS (bytes) of the process and all its descendants (every 0.1 s), and stdout; the
    peak summed PSS (once a second: what the tree really holds, a page its forked children share with it counted
    once) is kept in :data:`PSS_PEAK`."""
    import psutil

    t = time.perf_counter()
    sink = tempfile.TemporaryFile(mode="w+")  # a pipe would fill up and stall the command
    p = subprocess.Popen(cmd, stdout=sink, stderr=subprocess.DEVNULL, text=True)
    proc = psutil.Process(p.pid)
    peak, pss_peak, last = 0, 0, -1.0
    while p.poll() is None:
        try:
            tree = [proc, *proc.children(recursive=True)]
            if time.perf_counter() - last >= 1.0:
                last = time.perf_counter()
                rss, pss, _ = tree_memory(tree)
                pss_peak = max(pss_peak, pss)
            else:
                rss = sum(c.memory_info().rss for c in tree)
            peak = max(peak, rss)
        except psutil.Error:
            pass
        time.sleep(0.1)
    secs = time.perf_counter() - t
    PSS_PEAK[0] = pss_peak
    sink.seek(0)
    out = sink.read()
    if p.returncode:
        raise RuntimeError(f"{' '.join(cmd)} failed ({p.returncode})")
    return secs, peak, out


#: the last :func:`run_tree`'s peak summed PSS (bytes)
PSS_PEAK = [0]


def catalogue16(folder: Path):
    from bench_twin import _catalogue

    if (folder / "catalogue.sqlite").exists():
        from twinreg.catalogue.repository import Catalogue

        return Catalogue(folder, create=False)
    cat = _catalogue(folder)
    for r in cat.list():  # the twin meshes, cached once (as after a first build-twin)
        cat.ge_mesh(r)
    return cat


def city(cat, folder: Path, km2: float, seed: int = 0, tile: float = 250.0, density: float = 150.0,
         layout: str = "streets") -> dict:
    from twinreg.sim.city import simulate_city

    if (folder / "truth.json").exists():
        return json.loads((folder / "truth.json").read_text())
    rows = sorted(cat.list(), key=lambda r: r.name)
    return simulate_city(folder, [cat.ge_mesh(r) for r in rows], [r.name for r in rows], km2=km2, density=density,
                         tile=tile, seed=seed, street_spacing=STREETS, kind=layout)


def _tiles_for(km2: float) -> float:
    """The tile side (m, at most 250, a multiple of 5) whose tiles make up a city of ``km2``."""
    side = np.sqrt(km2) * 1000.0
    n = int(np.ceil(side / 250.0))
    return float(np.ceil(side / n / 5.0) * 5.0)


def _per(twin: dict) -> tuple[float, float]:
    """(cell stage seconds per million points, taxonomy + matching ms per object) of a city run."""
    t = twin["timing_s"]
    return (t["cells"] / (twin["n_points"] / 1e6),
            1000 * (t.get("matrix", 0) + t.get("matching", 0)) / max(len(twin["objects"]), 1))


def main_alone(twin: dict) -> float:
    """Seconds of twin.json's ``total`` outside its timed stages: what the main process does alone while the
    workers wait (loading the finished cells, the output folder's checks, twin.json)."""
    t = twin["timing_s"]
    return t["total"] - sum(v for k, v in t.items() if k != "total")


def compare_layouts(cat, lib: Path, root: Path, size: int, densities=(150.0, 300.0)) -> list[Row]:
    """Streets and dense car parks (simulate-city --layout parks) of ``size`` million points each: time, memory,
    the cell stage per million points and the matching per object, and the ratios parks / streets."""
    rows, per = [], {}
    for layout, density in [("streets", 150.0)] + [("parks", d) for d in densities]:
        km2 = size * 1e6 / (density * 1e6)  # every ray returns: about density x 1e6 points a km2
        folder = root / f"city_{layout}_{size}_{density:g}"
        truth = city(cat, folder, km2, seed=21, tile=_tiles_for(km2), density=density, layout=layout)
        secs, peak, twin = build(lib, [str(folder)], root / f"out_{layout}_{size}_{density:g}")
        right, found, pos = score(truth, twin)
        per[(layout, density)] = _per(twin)
        cells, match = per[(layout, density)]
        others = sum(1 for o in truth.get("others", []) if o["kind"] in ("kiosk", "wall", "tree"))
        data = (f"simulated {layout} city at {density:g} pts/m2, {twin['n_points']:,} points, {len(truth['cars'])} "
                f"cars, {others} kiosks, walls and trees")
        rows.append(Row(f"build-twin on {layout}, process start to files written", data,
                        f"{secs:.1f} s, peak {peak / 2**30:.2f} GiB; {found}/{len(truth['cars'])} found once, "
                        f"{right} own model; cells {cells:.2f} s per M points, taxonomy + matching {match:.1f} ms "
                        f"an object; stages " + ", ".join(f"{k} {v:.1f}" for k, v in twin["timing_s"].items()
                                                          if k in ("cells", "matrix", "matching", "formats"))
                        + f", the main process alone {main_alone(twin):.1f}"))
        stages: dict = {}
        for c in twin["cells"]:
            for k, v in c["timing_s"].items():
                stages[k] = stages.get(k, 0.0) + v
        rows.append(Row(f"cell time by stage on {layout} ({density:g} pts/m2), summed over cells", data,
                        ", ".join(f"{k} {1000 * v / (twin['n_points'] / 1e6):.0f} ms" for k, v in stages.items())
                        + " per million points"))
    base = per[("streets", 150.0)]
    for (layout, density), (cells, match) in per.items():
        if layout == "parks":
            rows.append(Row("parks / streets", f"{size}M points, parks at {density:g} pts/m2",
                            f"cells per M points x{cells / base[0]:.2f}, matching per object x{match / base[1]:.2f}",
                            "within 1.5x"))
    return rows


def score(truth: dict, twin: dict) -> tuple[int, int, float]:
    """(cars with their own model, cars found once, max position error m)."""
    from scipy.spatial import cKDTree

    cars = truth["cars"]
    xy = np.array([[c["x"], c["y"]] for c in cars])
    objs = twin["objects"]
    d, idx = cKDTree(xy).query(np.array([o["centroid"][:2] for o in objs]))
    near = d < 1.0
    right = sum(1 for o, i, ok in zip(objs, idx, near) if ok and o["match"] and o["match"]["name"] == cars[i]["model"])
    return right, len(set(idx[near])), float(d[near].max()) if near.any() else float("nan")


def build(lib: Path, inputs: list[str], out: Path, extra=()) -> tuple[float, int, dict]:
    """One build-twin from scratch (an earlier run's OUT, whose finished cells a rerun would reuse, is removed)."""
    import shutil

    shutil.rmtree(out, ignore_errors=True)
    cmd = [sys.executable, "-m", "twinreg", "--library", str(lib), "build-twin", *inputs, "--out", str(out),
           "--json", *extra]
    secs, peak, stdout = run_tree(cmd)
    return secs, peak, json.loads(stdout)


def viewer_open(out: Path) -> dict:
    """Serve a twin with `twinreg view` and open it in the system's headless Chromium (tests/js/shoot_viewer.mjs):
    the time from loading the page to the viewer's ready flag, and what it drew."""
    root = Path(__file__).resolve().parents[1]
    p = subprocess.Popen([sys.executable, "-m", "twinreg", "view", str(out), "--port", "0", "--no-open"],
                         stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    try:
        url = p.stdout.readline().strip()
        shot = Path(tempfile.mkdtemp()) / "viewer.png"
        got = subprocess.run(["node", str(root / "tests" / "js" / "shoot_viewer.mjs"), url, str(shot)],
                             capture_output=True, text=True, check=True, cwd=root)
        return json.loads(got.stdout.strip().splitlines()[-1]) | {"screenshot": str(shot)}
    finally:
        p.terminate()
        p.wait()


def car_park_6x6(cat, path: Path) -> int:
    """The bench_twin car park (seed 5, 12 cars) repeated 6 x 6 in one LAS file (EPSG:28992)."""
    from bench_twin import _scene

    from twinreg.sim.city import write_laz

    park, _ = _scene(cat, path.with_suffix(".ply"))
    pts = park.points
    span = np.ptp(pts[:, :2], axis=0) + 6.0
    allp = np.vstack([pts + [121000 + i * span[0], 487000 + j * span[1], 0] for i in range(6) for j in range(6)])
    write_laz(path, allp, "EPSG:28992")
    return len(allp)


def run(points=(10, 30, 100), cars=(12, 100, 400), keep: Path | None = None, parks=(), park6x6: bool = True,
        densities=(150.0, 300.0)) -> list[Row]:
    rows = []
    root = keep or Path(tempfile.mkdtemp(prefix="twinreg-city-bench-"))
    root.mkdir(parents=True, exist_ok=True)
    lib = root / "lib16"
    cat = catalogue16(lib)
    for size in parks:
        rows += compare_layouts(cat, lib, root, size, densities)
    if park6x6:
        rows += _park6x6(cat, lib, root)
    return rows + _cities(cat, lib, root, points, cars)


def _park6x6(cat, lib: Path, root: Path) -> list[Row]:
    rows = []
    # the 9.2M-point case of issue 9
    park = root / "park6x6.las"
    n = car_park_6x6(cat, park) if not park.exists() else None
    secs, peak, twin = build(lib, [str(park)], root / "out_park")
    n = n or twin["n_points"]
    matched = sum(1 for o in twin["objects"] if o["match"])
    rows.append(Row("build-twin, one LAS file, process start to files written", f"car park repeated 6 x 6, "
                    f"{twin['n_points']:,} points, {len(twin['objects'])} objects, 16-model catalogue",
                    f"{secs:.1f} s, peak {peak / 2**30:.2f} GiB (all processes), {matched} matched, "
                    f"{twin['grid']['n_cells']} cells", "< 30 s (was 335 s and 15 GB)"))
    return rows


def _cities(cat, lib: Path, root: Path, points, cars) -> list[Row]:
    rows, per_object, curve = [], [], []
    for kind, sizes in (("cars", cars), ("points", points)):
        for size in sizes:
            km2 = size / CARS_PER_KM2 if kind == "cars" else size * 1e6 / POINTS_PER_KM2
            folder = root / f"city_{kind}_{size}"
            truth = city(cat, folder, km2, tile=_tiles_for(km2))
            secs, peak, twin = build(lib, [str(folder)], root / f"out_{kind}_{size}")
            right, found, pos = score(truth, twin)
            t = twin["timing_s"]
            n_obj = len(twin["objects"])
            per_object.append((n_obj, (t.get("matrix", 0) + t.get("matching", 0)) / max(n_obj, 1)))
            data = (f"simulated city {truth['side_m']:.0f} m square, {len(truth['tiles'])} LAZ tiles, "
                    f"{twin['n_points']:,} points, {len(truth['cars'])} cars")
            rows.append(Row("build-twin on tiles, process start to files written", data,
                            f"{secs:.1f} s, peak {peak / 2**30:.2f} GiB, {twin['grid']['n_cells']} cells of "
                            f"{twin['grid']['cell_m']:g} m; {found}/{len(truth['cars'])} cars found once, {right} "
                            f"with their own model, max position error {pos * 100:.1f} cm",
                            "100M points: < 300 s, < 4 GB" if kind == "points" else ""))
            rows.append(Row("build-twin on tiles, stages (wall s)", data,
                            ", ".join(f"{k} {v:.1f}" for k, v in t.items() if k not in ("prefilter", "model_prep",
                                                                                           "registration",
                                                                                           "verification"))))
            if kind == "points":
                curve.append((twin["n_points"], secs, peak))
            if n_obj >= 4000:
                v = viewer_open(root / f"out_{kind}_{size}")
                rows.append(Row("the twin's formats (3D Tiles with the scan, twin.glb, CityJSON, GeoJSON) and the "
                                "viewer", data, f"written in {t['formats']:.1f} s ({twin['tiles']['n_tiles']} model "
                                f"tiles, {twin['tiles']['n_scan_points']:,} scan points); opens in headless Chromium "
                                f"in {v['ms'] / 1000:.1f} s ({v['stats']['instances']:,} instances, "
                                f"{v['stats']['points']:,} points, {len(v['errors'])} console errors)",
                                "tiles of 4,000 cars < 10 s; open < 30 s"))
    if len(per_object) < 2:
        return rows
    n_obj = np.array([n for n, _ in per_object], dtype=float)
    secs_obj = np.array([n * c for n, c in per_object])
    fixed, slope = np.polynomial.polynomial.polyfit(n_obj, secs_obj, 1)
    rows.append(Row("taxonomy + matching (wall, 2 workers): fixed cost and cost per object", "the cities above",
                    f"fixed {fixed:.1f} s (worker start, catalogue models loaded once per worker), then "
                    f"{1000 * slope:.1f} ms an object (least squares); per object beyond the fixed cost: " +
                    ", ".join(f"{int(n):,} objects {1000 * (t - fixed) / n:.1f} ms"
                              for n, t in sorted(zip(n_obj, secs_obj))), "flat from 12 to 4,000 objects"))
    if len(curve) >= 2:
        pts, secs, peak = (np.array(v, dtype=float) for v in zip(*curve))
        rows.append(Row("growth with points (time, memory)", "the cities of 10M, 30M, 100M points",
                        "; ".join(f"{p / 1e6:.0f}M: {s:.0f} s, {m / 2**30:.2f} GiB" for p, s, m in curve) +
                        f"; seconds per million points {', '.join(f'{s / p * 1e6:.2f}' for p, s in zip(pts, secs))}",
                        "linear"))
        _plot(curve, per_object, Path(__file__).resolve().parents[1] / "docs" / "city_scaling.png")
    return rows


def _plot(curve, per_object, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    pts, secs, peak = (np.array(v, dtype=float) for v in zip(*curve))
    fig, ax = plt.subplots(1, 3, figsize=(13, 3.6))
    ax[0].plot(pts / 1e6, secs, "o-")
    ax[0].plot([0, pts.max() / 1e6], [0, secs[-1] / pts[-1] * pts.max()], ":", color="0.5", label="linear")
    ax[0].set_xlabel("points (millions)")
    ax[0].set_ylabel("build-twin (s)")
    ax[0].legend()
    ax[1].plot(pts / 1e6, peak / 2**30, "o-", color="tab:red")
    ax[1].axhline(4.0, color="0.5", ls=":")
    ax[1].set_xlabel("points (millions)")
    ax[1].set_ylabel("peak memory, all processes (GiB)")
    n, c = (np.array(v, dtype=float) for v in zip(*sorted(per_object)))
    ax[2].semilogx(n, c * 1000, "o-", color="tab:green")
    ax[2].set_ylim(0, max(c * 1000) * 1.3)
    ax[2].set_xlabel("objects")
    ax[2].set_ylabel("taxonomy + matching per object (ms)")
    fig.suptitle("twinreg build-twin on simulated cities (2-core VM)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def main():
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--points", default="10,30,100", help="city sizes in millions of points")
    ap.add_argument("--cars", default="12,100,400", help="small cities by number of cars")
    ap.add_argument("--keep", type=Path, default=None, help="keep the cities and outputs here (reused)")
    ap.add_argument("--parks", default="", help="dense car-park cities (150 and 300 pts/m2) beside a street city "
                                                "of the same size, in millions of points (e.g. 10,100)")
    ap.add_argument("--densities", default="150,300", help="the car-park cities' densities (pts/m2)")
    ap.add_argument("--no-park6x6", action="store_true", help="leave out issue 9's car park repeated 6 x 6")
    args = ap.parse_args()
    pts = [int(v) for v in args.points.split(",") if v]
    cars = [int(v) for v in args.cars.split(",") if v]
    parks = [int(v) for v in args.parks.split(",") if v]
    rows = run(pts, cars, args.keep, parks, not args.no_park6x6,
               tuple(float(v) for v in args.densities.split(",") if v))
    print(f"machine: {machine()}")
    for r in rows:
        print(f"| {r['what']} | {r['data']} | {r['figure']} | {r['target']} |")


if __name__ == "__main__":
    main()
