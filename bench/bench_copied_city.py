"""Issue 37's city, made with our own code: one furnished car park (12 of the 16 shared cars, kerb, 2.4 m wall, a
tree with a 2.2 m crown, a 6 m lamp post, a 2 m kiosk) scanned at 150 pts/m2 and copied G x G times, each copy
turned by a multiple of 90 degrees and stepped 1.5-2 cm in height from its neighbours, in LAZ tiles of 7 x 7 copies
(EPSG:2157 in their headers); then build-twin on the tiles, timed from outside with the whole process tree's peak
memory (``peak_gib``: its resident sets summed, a page shared with a forked child counted in each;
``peak_pss_gib``: its proportional sets summed, each page once), and the twin checked against the truth (every car
found once, its model) and, with ``--against``, against another run's twin.json (model, pose within 1 cm,
confidence within 0.01).

    python bench/bench_copied_city.py make DIR [--copies 28]         # 28: 784 copies, about 100M points, 16 tiles
    python bench/bench_copied_city.py run DIR OUT [--against OTHER/twin.json] [--tiles N]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

SIDE = 29.0  # one copy's square (m), centred on the park
CENTRE = np.array([-3.0, 0.0])
ORIGIN = np.array([700_000.0, 730_000.0, 50.0])  # Irish Transverse Mercator (EPSG:2157)
PER_TILE = 7


def one_park(cat, seed: int = 7, density: float = 150.0):
    """(points (n, 3) in the copy's frame, centred, cars [(x, y, heading, model name)])."""
    from twinreg.sim.accuracy import density_passes
    from twinreg.sim.scan import car_park

    rows = sorted(cat.list(), key=lambda r: r.name)
    models = cat.scan_meshes(rows)
    h = SIDE / 2
    ground = (CENTRE[0] - h, CENTRE[0] + h, CENTRE[1] - h, CENTRE[1] + h)
    park = car_park(models, n_cars=12, seed=seed, passes=density_passes(density), kiosk=True, ground=ground)
    p = park.points.copy()
    keep = (np.abs(p[:, 0] - CENTRE[0]) < h) & (np.abs(p[:, 1] - CENTRE[1]) < h)
    p = p[keep]
    p[:, :2] -= CENTRE
    cars = [(c.x - CENTRE[0], c.y - CENTRE[1], c.heading, rows[c.model].name) for c in park.cars]
    return p, cars


def make(folder: Path, copies: int, seed: int) -> dict:
    from bench_twin import _catalogue

    from twinreg.sim.city import write_laz

    (folder / "tiles").mkdir(parents=True, exist_ok=True)
    cat = _catalogue(folder / "cat16")
    pts, cars = one_park(cat, seed)
    rng = np.random.default_rng(seed)
    turns = rng.integers(0, 4, (copies, copies))
    step_x = np.r_[0.0, np.cumsum(rng.uniform(0.015, 0.02, copies - 1))]
    step_y = np.r_[0.0, np.cumsum(rng.uniform(0.015, 0.02, copies - 1))]
    truth = []
    n_tiles = int(np.ceil(copies / PER_TILE))
    total = 0
    for tx in range(n_tiles):
        for ty in range(n_tiles):
            chunk = []
            for i in range(tx * PER_TILE, min((tx + 1) * PER_TILE, copies)):
                for j in range(ty * PER_TILE, min((ty + 1) * PER_TILE, copies)):
                    a = turns[i, j] * np.pi / 2
                    c, s = np.cos(a), np.sin(a)
                    off = np.array([(i + 0.5) * SIDE, (j + 0.5) * SIDE, step_x[i] + step_y[j]])
                    q = np.c_[c * pts[:, 0] - s * pts[:, 1], s * pts[:, 0] + c * pts[:, 1], pts[:, 2]] + off
                    chunk.append(q)
                    for x, y, hd, name in cars:
                        truth.append({"x": float(c * x - s * y + off[0]), "y": float(s * x + c * y + off[1]),
                                      "heading": float(np.mod(hd + a, 2 * np.pi)), "model": name})
            tile = np.vstack(chunk) + ORIGIN
            total += len(tile)
            write_laz(folder / "tiles" / f"tile_{tx}_{ty}.laz", tile, "EPSG:2157")
            print(f"tile {tx},{ty}: {len(tile):,} points", file=sys.stderr)
    doc = {"copies": copies * copies, "points_per_copy": len(pts), "points": total, "cars": len(truth),
           "origin": ORIGIN.tolist(), "truth": truth}
    (folder / "truth.json").write_text(json.dumps(doc))
    return {k: v for k, v in doc.items() if k != "truth"}


def score(twin: dict, truth: dict, tiles: list[str] | None = None) -> dict:
    """Every car found once (an object within 1 m of it, none other), its model right."""
    from scipy.spatial import cKDTree

    cars = truth["truth"]
    xy = np.array([[c["x"], c["y"]] for c in cars]) + np.asarray(truth["origin"][:2])
    objs = twin["objects"]
    pos = np.array([o["position_crs"][:2] for o in objs]).reshape(-1, 2)
    if tiles is not None:  # only the cars of the tiles built
        lo, hi = pos.min(0) - 5, pos.max(0) + 5
        inside = ((xy >= lo) & (xy <= hi)).all(1)
        xy, cars = xy[inside], [c for c, k in zip(cars, inside) if k]
    near = cKDTree(pos).query_ball_point(xy, 1.0)
    once = sum(len(n) == 1 for n in near)
    right = sum(len(n) >= 1 and any((objs[k]["match"] or {}).get("name") == c["model"] for k in n)
                for n, c in zip(near, cars))
    return {"cars": len(cars), "found_once": once, "missed": sum(len(n) == 0 for n in near),
            "twice": sum(len(n) > 1 for n in near), "model_right": right, "objects": len(objs)}


def against(twin: dict, other: dict) -> dict:
    """Objects of two runs paired by position (within 0.5 m): the model, the pose (1 cm) and the confidence (0.01)."""
    from scipy.spatial import cKDTree

    a, b = twin["objects"], other["objects"]
    pa = np.array([o["position_crs"] for o in a])
    pb = np.array([o["position_crs"] for o in b])
    d, k = cKDTree(pb).query(pa)
    out = {"objects": [len(a), len(b)], "unpaired": int((d > 0.5).sum()), "model_differs": 0, "pose_over_1cm": 0,
           "confidence_over_0.01": 0, "max_pose_m": 0.0, "max_confidence": 0.0}
    for o, dd, j in zip(a, d, k):
        if dd > 0.5:
            continue
        q = b[j]
        ma, mb = o["match"], q["match"]
        if (ma or {}).get("name") != (mb or {}).get("name"):
            out["model_differs"] += 1
            continue
        out["max_pose_m"] = max(out["max_pose_m"], float(dd))
        out["pose_over_1cm"] += int(dd > 0.01)
        if ma and mb and ma.get("confidence") is not None and mb.get("confidence") is not None:
            dc = abs(ma["confidence"] - mb["confidence"])
            out["max_confidence"] = max(out["max_confidence"], dc)
            out["confidence_over_0.01"] += int(dc > 0.01)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="cmd", required=True)
    m = sub.add_parser("make")
    m.add_argument("folder", type=Path)
    m.add_argument("--copies", type=int, default=28)
    m.add_argument("--seed", type=int, default=7)
    r = sub.add_parser("run")
    r.add_argument("folder", type=Path)
    r.add_argument("out", type=Path)
    r.add_argument("--against", type=Path)
    r.add_argument("--tiles", type=int, help="only the first N tiles")
    args = ap.parse_args()
    if args.cmd == "make":
        print(json.dumps(make(args.folder, args.copies, args.seed), indent=1))
        return
    from bench_city import PSS_PEAK, build

    tiles = sorted(str(p) for p in (args.folder / "tiles").glob("*.laz"))
    if args.tiles:
        tiles = tiles[:args.tiles]
    t0 = time.perf_counter()
    secs, peak, doc = build(args.folder / "cat16", tiles, args.out)
    twin = json.loads((args.out / "twin.json").read_text())
    res = {"tiles": len(tiles), "wall_s": round(secs, 1), "peak_gib": round(peak / 2**30, 2),
           "peak_pss_gib": round(PSS_PEAK[0] / 2**30, 2),
           "timing_s": {k: round(v, 1) for k, v in twin.get("timing_s", {}).items() if isinstance(v, (int, float))},
           **score(twin, json.loads((args.folder / "truth.json").read_text()), tiles if args.tiles else None)}
    if args.against:
        res["against"] = against(twin, json.loads(args.against.read_text()))
    res["bench_s"] = round(time.perf_counter() - t0, 1)
    print(json.dumps(res, indent=1))


if __name__ == "__main__":
    main()
